"""The identification result: estimates with standard errors and 95 % intervals, the fit's history
and residual diagnostics, and what it was computed from (config, data files and hashes, kernel)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..distributions import t_ppf
from ..presentation import OPTIMISTIC, PLUS_MINUS, UNIT_TEXT, describe, samples_sha256, sha256
from .adequacy import Adequacy
from .optimiser import scaled_svd
from .uncertainty import Intervals, fixed_b_quantile, residual_aware


@dataclass
class Estimate:
    name: str
    value: float | None
    stderr: float | None
    lower95: float | None = None
    upper95: float | None = None
    initial: float | None = None
    identifiable: bool = True
    stderr_white: float | None = None  # sigma^2 (J'J)^-1: independent errors of one size
    stderr_residual_aware: float | None = None  # Newey-West sandwich (uncertainty.py)


def provenance(cfg, data, kern) -> dict:
    """What a result was computed from: the config, the data files (name and SHA-256 of the file,
    or of the samples when there is no file) and the compiled kernel's key."""
    files = []
    for d in (data if isinstance(data, (list, tuple)) else [data]):
        path = Path(d.source) if d.source else None
        digest = sha256(path) if path is not None and path.is_file() else samples_sha256(d)
        files.append({"name": path.name if path else "(in memory)", "sha256": digest})
    return {"config": cfg.path or cfg.name, "data": files, "kernel_key": kern.key}


@dataclass(kw_only=True)
class IdentificationResult:
    estimates: dict
    iterations: list  # [{"params": {...}, "rms": ...}]
    rms: float
    converged: bool
    message: str
    correlation: np.ndarray | None
    diagnostics: dict
    method: str
    wall_time: float
    unidentifiable: list = field(default_factory=list)
    time: np.ndarray | None = None
    measured: np.ndarray | None = None
    fitted: np.ndarray | None = None
    initial_model: np.ndarray | None = None
    speed: float = 0.0
    angle: np.ndarray | None = None
    n_evaluations: int = 0
    provenance: dict = field(default_factory=dict)  # config, data files and hashes, kernel key
    on_bound: list = field(default_factory=list)  # [(name, bound value)] where the fit stopped
    no_effect: list = field(default_factory=list)  # unidentifiable because they do not act at all
    warnings: list = field(default_factory=list)  # plausibility warnings accepted under force
    keep: np.ndarray | None = None  # samples kept by the reversal-aware cost (None: all); rms over them
    adequacy: Adequacy | None = None  # how well the model describes the data (adequacy.py)
    intervals: Intervals | None = None  # white or residual-aware intervals, the residual's structure
    notes: list = field(default_factory=list)  # what the estimates rest on beyond the data (sentences)
    residual_unit: str = "N m"  # the measured channel's (a transient fit compares speeds: rad/s)
    # a fit that stalled at a start which is NOT a minimum (optimiser.start_test): {name: value} where
    # the Gauss-Newton step from that start points -- a start to fit again from; None otherwise
    points_to: dict | None = None
    # a fit that did not converge: what its remaining Gauss-Newton step would still take off the
    # cost, in noise variances (optimiser.FitOutcome.left_chi2); None otherwise
    left_chi2: float | None = None

    @property
    def residual(self):
        """Measured minus fitted per sample: torque [N m] (a transient fit's speed [rad/s])."""
        return self.measured - self.fitted

    def value(self, name):
        """The estimate of `name` (None when it is not identifiable from the data)."""
        return self.estimates[name].value

    def interval_notes(self) -> list[str]:
        """What the intervals mean when the residual is not white (empty when it is)."""
        note = None if self.intervals is None else self.intervals.note()
        return [f"intervals: {note}"] if note else []

    def problems(self) -> list[str]:
        """Why this fit is not a usable estimate (empty when it is): not converged, a parameter on
        its bound, parameters not identifiable. The command line exits 1 when there are any."""
        out = []
        if not self.converged:
            out.append(f"NOT converged ({self.message})")
        for name, bound in self.on_bound:
            out.append(f"{name} ended on its bound {bound:g} (a unit mistake, a wrong configuration or "
                       "an effect the model lacks; the interval is not valid)")
        if self.adequacy is not None and self.adequacy.problem():
            out.append(self.adequacy.problem())
        apart = [n for n in self.unidentifiable if n not in self.no_effect]
        if apart:  # parameters without any effect are reported, but leave the others' fit usable
            out.append(f"not identifiable from this data: {', '.join(apart)} (their effects on the torque "
                       "cannot be told apart: fit fewer parameters, or add a measurement at another speed)")
        return out

    def __repr__(self):
        vals = ", ".join(f"{n}={e.value:.6g}" if e.value is not None else f"{n}=None"
                         for n, e in self.estimates.items())
        state = "converged" if self.converged and not self.problems() else "NOT usable"
        return f"<IdentificationResult {self.method}: {vals}; RMS {self.rms:.4g} {self.residual_unit}; {state}>"

    def to_json(self) -> dict:
        """The spec §7 JSON document: params {name: value, stderr, ci95, initial, identifiable},
        iterations, rms [residual_unit: N m, a transient fit's rad/s], converged, and message, problems, on_bound, correlation, diagnostics.

        Example::

            json.dumps(pumpsim.identify(cfg, "run.csv").to_json())
        """
        names = list(self.estimates)
        return {
            "params": {n: {"value": e.value, "stderr": e.stderr, "ci95": [e.lower95, e.upper95],
                           "initial": e.initial, "identifiable": e.identifiable, "stderr_white": e.stderr_white,
                           "stderr_residual_aware": e.stderr_residual_aware}
                       for n, e in self.estimates.items()},
            "iterations": self.iterations, "rms": self.rms, "rms_unit": self.residual_unit, "converged": self.converged,
            "message": self.message, "method": self.method, "unidentifiable": self.unidentifiable,
            "correlation": {"names": [n for n in names if self.estimates[n].identifiable],
                            "matrix": None if self.correlation is None else self.correlation.tolist()},
            "diagnostics": self.diagnostics, "wall_time": self.wall_time, "provenance": self.provenance,
            "on_bound": [{"name": n, "bound": b} for n, b in self.on_bound], "no_effect": self.no_effect,
            "problems": self.problems(), "warnings": self.warnings,
            "adequacy": None if self.adequacy is None else self.adequacy.to_json(),
            "intervals": None if self.intervals is None else self.intervals.to_json(), "notes": self.notes,
        }

    def __str__(self):
        its = self.iterations[-1].get("iteration", len(self.iterations) - 1) if self.iterations else 0
        usable = "" if not self.converged or not self.problems() else " but NOT a usable estimate (see below)"
        lines = [f"identification ({self.method}): {'converged' if self.converged else 'NOT converged'} "
                 f"after {its} iterations{usable}, residual RMS {self.rms:.6g} {self.residual_unit}"
                 + (f" -- {self.message}" if its == 0 and self.message else "")]
        if self.provenance:
            pv = self.provenance
            lines.append(f"  from {pv['config']} and " + ", ".join(
                f"{d['name']} (sha256 {d['sha256'][:12]})" for d in pv["data"]) + f", kernel {pv['kernel_key']}")
        lines += [self._estimate_line(e) for e in self.estimates.values()]
        for name, bound in self.on_bound:
            lines.append(f"  {name} is ON ITS BOUND {bound:g}: the estimate and interval are not valid")
        d = self.diagnostics
        lines.append(f"  residual: runs test p = {d['runs_test']['p_value']:.3g}, Ljung-Box p = "
                     f"{d['ljung_box']['p_value']:.3g} -> {'white' if d['white_at_5pct'] else 'not white'} at 5%")
        if d["spectrum_peaks"]:
            lines.append("  residual peaks at shaft orders: " + ", ".join(
                f"{p['order']:.2f}" for p in d["spectrum_peaks"][:5]))
        if self.adequacy is not None:
            lines.append("  " + self.adequacy.summary().replace("\n", "\n  "))
        lines.append(f"  {PLUS_MINUS}")
        notes = self.interval_notes()
        lines += [f"  {n}" for n in notes + [f"note: {n}" for n in self.notes]]
        if not notes and not d["white_at_5pct"]:
            lines.append(f"  {OPTIMISTIC}")
        return "\n".join(lines)

    def _estimate_line(self, e: Estimate) -> str:
        if e.identifiable and e.value is not None:
            unit = UNIT_TEXT.get(describe(e.name)[1], describe(e.name)[1])
            unit = "" if unit in ("–", "?") else f" {unit}"
            white = ("" if e.stderr_white is None or e.stderr == e.stderr_white
                     else f"; white-noise ± {e.stderr_white:.3g}")
            return (f"  {e.name:<22} {e.value:.8g} ± {e.stderr:.3g}{unit}  (95%: {e.lower95:.6g} .. "
                    f"{e.upper95:.6g}; start {e.initial:.6g}{white})")
        if e.name in self.no_effect:
            return f"  {e.name:<22} not identifiable: no effect on the torque in this data"
        return f"  {e.name:<22} not identifiable from this data"


def bounds_reached(prob, x) -> list:
    """[(name, bound)] for fitted values that ended on a finite bound of the fit."""
    out = []
    for i, nm in enumerate(prob.names):
        for b in (prob.lower[i], prob.upper[i]):
            if np.isfinite(b) and abs(x[i] - b) <= 1e-9 * max(1.0, abs(b)):
                out.append((nm, float(b)))
    return out


def fit_estimates(names, x, initial, r, J, y=None, channels=None):
    """Estimates with standard errors, 95 % intervals and their correlation from the residual r
    and Jacobian J at the fit x, and how the intervals were made (uncertainty.Intervals): the
    white-noise covariance sigma^2 (J'J)^-1 (through the column-scaled SVD; t quantile) and the
    residual-aware Newey-West sandwich over `channels` [(name, rows)] (fixed-b quantile); each
    interval is the wider of the two and `stderr` the standard error it uses. y: the measured
    values in r's units (the channels' spread, for the note). The correlation is the white one."""
    n, k = r.size, len(names)
    sigma2 = float(r @ r) / max(n - k, 1)
    scale, U, s, Vt = scaled_svd(J)
    del U  # n x k: not held while the residual-aware covariance's n x k arrays are built
    bread = (Vt.T / s**2) @ Vt / np.outer(scale, scale)
    cov = bread * sigma2
    se = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):  # a noise-free fit has se = 0
        corr = np.where(np.outer(se, se) > 0, cov / np.outer(se, se), np.eye(k))
    cov_ra, structure, b = residual_aware(J, r, r if y is None else y, bread, channels)
    se_ra = np.sqrt(np.maximum(np.diag(cov_ra), 0.0))
    tq = t_ppf(0.975, max(n - k, 1))
    q_ra = np.maximum(tq, [fixed_b_quantile(bi) for bi in b])
    wide = q_ra * se_ra > tq * se
    use_se, use_q = np.where(wide, se_ra, se), np.where(wide, q_ra, tq)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(se > 0, q_ra * se_ra / (tq * se), 1.0)
    intervals = Intervals("residual-aware" if np.any(wide) else "white", float(max(1.0, np.max(ratio, initial=1.0))),
                          structure, {nm: float(q) for nm, q in zip(names, use_q)})
    est = {nm: Estimate(nm, float(x[i]), float(use_se[i]), float(x[i] - use_q[i] * use_se[i]),
                        float(x[i] + use_q[i] * use_se[i]), float(initial[i]), stderr_white=float(se[i]),
                        stderr_residual_aware=float(se_ra[i])) for i, nm in enumerate(names)}
    return est, corr, intervals
