"""What a diagnosis found: `DiagnosisResult`, its JSON (spec section 7) and its step table."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..diagnostics import detectors
from ..identification import base_name
from ..presentation import OPTIMISTIC, PLUS_MINUS, parameter_text, step_parameters

from .effects import clearance
from .estimates import covariance


def _undetermined(name, value, se, cfg) -> bool:
    """An estimate whose standard error exceeds what would make it a result: larger than itself
    for a positive quantity (COF, speed, lag), than half the angular period for theta0, than the
    clearance for geometry and than its plausible size for the other effect parameters."""
    if value is None or se is None or not math.isfinite(se):
        return True
    b = base_name(name)
    if b == "theta0":
        return se > math.pi / max(cfg.vanes, 1)
    if b in ("mu", "mu_slot", "speed", "lag", "effects.viscous_tip_friction") or b.startswith("effects.vane"):
        return se > abs(value)
    if b.startswith("housing."):
        return se > clearance(cfg)
    if b in ("ripple_cos", "ripple_sin"):
        return se > 0.05
    return False


def params_json(res, names, cfg):
    out = {}
    for n in names:
        e = res.estimates.get(n)
        if e is None:
            continue
        if e.value is not None and not _undetermined(n, e.value, e.stderr, cfg):
            out[n] = {"value": e.value, "stderr": e.stderr}
        else:  # never a number with a standard error larger than itself as a result
            out[n] = {"value": None, "stderr": None, "not_determined": {"estimate": e.value, "stderr": e.stderr}}
    return out


def effect_params(cand, res, new_names, cfg):
    """The step's parameters as an engineer reads them."""
    out = params_json(res, new_names, cfg)
    if cand.order:
        out["order"] = cand.order
    if cand.kind.describe is not None:  # amplitude and phase of a harmonic pair
        out.update(cand.kind.describe(res, new_names, cand.order))
    return out


def vane_cofs(res, cfg) -> tuple:
    """Each vane's effective dynamic COF (tip and slot: mu x its factor, vane 0 the reference) and
    the reported mu, their mean over the vanes, with standard errors by the delta method."""
    N = cfg.vanes
    names = ["mu"] + [f"effects.vane_friction_factor.{i}" for i in range(1, N)]
    fitted = [n for n in names if n in res.estimates and res.estimates[n].value is not None]
    val = {n: (res.estimates[n].value if n in fitted else
               (cfg.values["friction.housing.dynamic"] if n == "mu" else cfg.values[n])) for n in names}
    S = covariance(res, fitted)
    mu = val["mu"]
    facs = [1.0] + [val[n] for n in names[1:]]
    per = []
    for i in range(N):
        g = np.array([facs[i] if n == "mu" else (mu if n == names[i] and i > 0 else 0.0) for n in fitted])
        per.append({"value": mu * facs[i], "stderr": float(math.sqrt(max(g @ S @ g, 0.0)))})
    g = np.array([sum(facs) / N if n == "mu" else mu / N for n in fitted])
    mean = {"value": mu * sum(facs) / N, "stderr": float(math.sqrt(max(g @ S @ g, 0.0)))}
    return per, mean


MU_DEFINITION = ("mu: the mean over the vanes of each vane's dynamic COF (vane-housing tip, slot tied "
                 "unless mu_slot is fitted); vane_mu: each vane's COF = mu_vane0 x its factor")


@dataclass
class DiagnosisResult:
    """What `diagnose` found. The JSON names (spec §7) are the fields; `str()` is the step table."""

    baseline: dict
    steps: list
    effects: list
    final: dict
    unexplained: bool
    confounded: list
    unexplained_where: list
    verdict: str
    notes: list
    detectors: dict
    speed: dict
    ranking: list
    screens: list  # per search step: after, alpha, candidates (by score p), chosen
    rejected: list
    method: str
    wall_time: float
    history: list = field(default_factory=list, repr=False)  # per step: label, IdentificationResult
    drift: list = field(default_factory=list)  # identification.drift.Drift.to_json() per drifting parameter
    budget: dict = field(default_factory=dict)  # {"seconds", "bound", "cut"}: what the time budget cut

    JSON = ("baseline", "steps", "effects", "final", "unexplained", "confounded", "unexplained_where",
            "verdict", "notes", "detectors", "speed", "ranking", "screens", "rejected", "method", "wall_time",
            "drift", "budget")

    def to_json(self) -> dict:
        return {k: getattr(self, k) for k in self.JSON}

    def __getitem__(self, key):  # read like the JSON
        if key not in self.JSON:
            raise KeyError(key)
        return getattr(self, key)

    def __contains__(self, key):
        return key in self.JSON

    def __str__(self):
        return step_table(self)


def _fmt_param(k, v):
    if not isinstance(v, dict):
        return f"{k} {v:.4g}"
    if v["value"] is None:
        return f"{k} not determined"
    return f"{k} {v['value']:.4g} ± {v['stderr']:.2g}"


def step_table(result) -> str:
    lines = [f"{'step':<28}{'RMS before':>13}{'RMS after':>13}{'p-value':>11}  parameters"]
    lines.append(f"{'baseline':<28}{'':>13}{result['baseline']['rms']:>13.5g}{'':>11}  " + ", ".join(
        parameter_text(k, v["value"], v["stderr"]) for k, v in result["baseline"]["params"].items()))
    for s in result["steps"]:
        ps = ", ".join(step_parameters(s))  # amplitude/phase with units; (a, b) in the JSON only
        lines.append(f"{s['effect']:<28}{s['rms_before']:>13.5g}{s['rms_after']:>13.5g}{s['p_value']:>11.2g}  {ps}")
    f = result["final"]
    lines.append(f"final: RMS {f['rms']:.5g}, mu (mean over vanes) {_fmt_param('', f['params'].get('mu', {'value': None})).strip()}; "
                 f"detectors p: runs {f['runs_p_value']:.2g}, Ljung-Box {f['ljung_box_p_value']:.2g}, "
                 f"synchronous F {f['synchronous_f_p_value']:.2g}, noise level {f['noise_level_p_value']:.2g}")
    if "effects.vane_friction_factor.1" in f["params"]:
        lines.append("vane COFs: " + ", ".join(f"{i}: {v['value']:.4g}" for i, v in enumerate(f["vane_mu"])))
    where = ", ".join((f"order {w['order']}" if "order" in w else f"{w['angle_deg']} deg")
                      for w in result["unexplained_where"]) or "broadband"
    lines.append(f"verdict: {result['verdict'].upper()}" + (f" (at {where})" if result["unexplained"] else ""))
    for a, b in result["confounded"]:
        lines.append(f"confounded: {a} ~ {b}")
    for n in result["notes"]:
        lines.append(f"note: {n}")
    lines.append(PLUS_MINUS)
    if not f["residual_white"]:
        lines.append(OPTIMISTIC)
    return "\n".join(lines)
