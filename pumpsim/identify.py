"""Identification (report §12-14): fit the vane-housing COF (and phase, speed, offsets, any numeric
config value) to a measured drive-torque signal at constant speed.

Dataset -> Problem (model torque and its exact Jacobian through the compiled kernel, CasADi AD) ->
solver (the report's Gauss-Newton with relaxation factor, Levenberg-Marquardt, or IPOPT through
nlpsol with bounds) -> Result (estimates, standard errors, 95% intervals, correlation, history,
residual diagnostics).
"""
from __future__ import annotations

import difflib
import math
import time as _time
from dataclasses import dataclass, field
from typing import NamedTuple
from pathlib import Path

import casadi as ca
import numpy as np
from scipy import stats

from .config import PumpConfig, as_array
from .data import Dataset
from .diagnostics import residual_report, synchronous_speed_scan
from .errors import ConfigError
from .kernels import load_kernels, map_samples
from .model_spec.parameters import (ANGLE_ACTING, COF_ALIASES, DERIVED, KERNEL_GRAPH_INPUTS,
                                    MEASUREMENT, alias_targets, derive, fit_bounds, layout)
from .presentation import OPTIMISTIC, PLUS_MINUS, UNIT_TEXT, describe, samples_sha256, sha256
from .sensor import first_order_lag
from .simulate import ripple_motion

# fit names beyond the parameter paths: the COF aliases and the measurement parameters (registry)
SPECIAL = COF_ALIASES + tuple(m.name for m in MEASUREMENT if not m.transient or m.in_kernel_graph)
METHODS = ("gauss-newton", "levenberg-marquardt", "ipopt")
SINGULAR_COND = 1e7  # condition number of the column-scaled Jacobian beyond which J'J is singular
Z_SPECIAL = KERNEL_GRAPH_INPUTS  # theta0, speed, delay, torque_offset, ripple_cos, ripple_sin


@dataclass
class Estimate:
    name: str
    value: float | None
    stderr: float | None
    lower95: float | None = None
    upper95: float | None = None
    initial: float | None = None
    identifiable: bool = True


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

    @property
    def residual(self):
        """Measured minus fitted torque [N m] per sample."""
        return self.measured - self.fitted

    def value(self, name):
        """The estimate of `name` (None when it is not identifiable from the data)."""
        return self.estimates[name].value

    def problems(self) -> list[str]:
        """Why this fit is not a usable estimate (empty when it is): not converged, a parameter on
        its bound, parameters not identifiable. The command line exits 1 when there are any."""
        out = []
        if not self.converged:
            out.append(f"NOT converged ({self.message})")
        for name, bound in self.on_bound:
            out.append(f"{name} ended on its bound {bound:g} (a unit mistake, a wrong configuration or "
                       "an effect the model lacks; the interval is not valid)")
        apart = [n for n in self.unidentifiable if n not in self.no_effect]
        if apart:  # parameters without any effect are reported, but leave the others' fit usable
            out.append(f"not identifiable from this data: {', '.join(apart)} (their effects on the torque "
                       "cannot be told apart: fit fewer parameters, or add a measurement at another speed)")
        return out

    def __repr__(self):
        vals = ", ".join(f"{n}={e.value:.6g}" if e.value is not None else f"{n}=None"
                         for n, e in self.estimates.items())
        state = "converged" if self.converged and not self.problems() else "NOT usable"
        return f"<IdentificationResult {self.method}: {vals}; RMS {self.rms:.4g} N m; {state}>"

    def to_json(self) -> dict:
        """The spec §7 JSON document: params {name: value, stderr, ci95, initial, identifiable},
        iterations, rms [N m], converged, and message, problems, on_bound, correlation, diagnostics.

        Example::

            json.dumps(pumpsim.identify(cfg, "run.csv").to_json())
        """
        names = list(self.estimates)
        return {
            "params": {n: {"value": e.value, "stderr": e.stderr, "ci95": [e.lower95, e.upper95],
                           "initial": e.initial, "identifiable": e.identifiable}
                       for n, e in self.estimates.items()},
            "iterations": self.iterations, "rms": self.rms, "converged": self.converged,
            "message": self.message, "method": self.method, "unidentifiable": self.unidentifiable,
            "correlation": {"names": [n for n in names if self.estimates[n].identifiable],
                            "matrix": None if self.correlation is None else self.correlation.tolist()},
            "diagnostics": self.diagnostics, "wall_time": self.wall_time, "provenance": self.provenance,
            "on_bound": [{"name": n, "bound": b} for n, b in self.on_bound], "no_effect": self.no_effect,
            "problems": self.problems(), "warnings": self.warnings,
        }

    def __str__(self):
        its = self.iterations[-1].get("iteration", len(self.iterations) - 1) if self.iterations else 0
        lines = [f"identification ({self.method}): {'converged' if self.converged else 'NOT converged'} "
                 f"after {its} iterations, residual RMS {self.rms:.6g} N m"]
        if self.provenance:
            pv = self.provenance
            lines.append(f"  from {pv['config']} and " + ", ".join(
                f"{d['name']} (sha256 {d['sha256'][:12]})" for d in pv["data"]) + f", kernel {pv['kernel_key']}")
        for e in self.estimates.values():
            if e.identifiable and e.value is not None:
                unit = UNIT_TEXT.get(describe(e.name)[1], describe(e.name)[1])
                unit = "" if unit in ("–", "?") else f" {unit}"
                lines.append(f"  {e.name:<22} {e.value:.8g} ± {e.stderr:.3g}{unit}  (95%: {e.lower95:.6g} .. "
                             f"{e.upper95:.6g}; start {e.initial:.6g})")
            elif e.name in self.no_effect:
                lines.append(f"  {e.name:<22} not identifiable: no effect on the torque in this data")
            else:
                lines.append(f"  {e.name:<22} not identifiable from this data")
        for name, bound in self.on_bound:
            lines.append(f"  {name} is ON ITS BOUND {bound:g}: the estimate and interval are not valid")
        d = self.diagnostics
        lines.append(f"  residual: runs test p = {d['runs_test']['p_value']:.3g}, Ljung-Box p = "
                     f"{d['ljung_box']['p_value']:.3g} -> {'white' if d['white_at_5pct'] else 'not white'} at 5%")
        if d["spectrum_peaks"]:
            lines.append("  residual peaks at shaft orders: " + ", ".join(
                f"{p['order']:.2f}" for p in d["spectrum_peaks"][:5]))
        lines.append(f"  {PLUS_MINUS}")
        if not d["white_at_5pct"]:
            lines.append(f"  {OPTIMISTIC}")
        return "\n".join(lines)


class Problem:
    """Model torque tau(t; phi) at constant speed and its Jacobian d tau / d phi, exact (CasADi
    forward AD through the compiled inverse-dynamics kernel).

    Every fitted name acts on the model through z = (runtime parameter vector, theta0, speed,
    delay, torque_offset, ripple_cos, ripple_sin), and z is affine in the fitted values: z(x) =
    z(x0) + S (x - x0), S a constant seed matrix. The compiled graph is one sample's torque and its
    derivatives along the columns of S, mapped over the samples: it depends only on the variant and
    the number of directions, never on the names or the sample count, so building it is cheap and
    every fit, candidate and joint measurement shares it."""

    def __init__(self, cfg: PumpConfig, data: Dataset, names, initial=None, extra=None,
                 ripple_order: int = 1):
        self.cfg, self.data = cfg, data
        self.pv = cfg.parameters("constrained")
        self.kern = load_kernels(self.pv.structure)
        self.p0 = as_array(self.pv)
        self.names = list(names)
        if not self.names:
            raise ConfigError("--params names no parameter to fit")
        self._index = {n: i for i, n in enumerate(self.pv.names)}
        for n in self.names:
            self._check_name(n)
        if len(set(self.names)) != len(self.names):
            raise ConfigError(f"--params names a parameter twice: {','.join(self.names)}")
        v = self.pv.values
        speed0 = float(np.mean(data.speed)) if data.speed is not None else cfg.speed
        theta0 = float(data.angle[0]) if data.angle is not None else cfg.angle
        self.fixed = {"mu": v["friction.housing.dynamic"], "mu_slot": v["friction.slot.dynamic"],
                      "theta0": theta0, "speed": speed0, "torque_offset": 0.0, "delay": 0.0,
                      "ripple_cos": 0.0, "ripple_sin": 0.0, "lag": 0.0}
        self.ripple_order = int(ripple_order)
        self.fixed.update(extra or {})
        self.x0, self.lower, self.upper = start_and_bounds(self.names, self.pv, self.fixed, initial)
        band = speed_band(cfg, data)
        if band is not None and "speed" in self.names:  # the nominal speed's tolerance band
            i = self.names.index("speed")
            self.lower[i], self.upper[i] = band
            self.x0[i] = min(max(self.x0[i], band[0]), band[1])
        self._follow = following(cfg)
        self.t = data.time - data.time[0]
        self.y = data.torque
        self._ratios = np.array([self._ratio("housing"), self._ratio("slot")])
        self._seeds = self._seed_matrix()
        self._half_step = 0.5 * (self.t[1] - self.t[0]) if self.t.size > 1 else 0.0
        self.n_eval = 0

    def _check_name(self, n):
        if n in SPECIAL or n in self._index or alias_targets(n):
            return
        close = difflib.get_close_matches(n, list(SPECIAL) + list(self._index), n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise ConfigError(f"--params: unknown parameter '{n}'{hint}")

    def _ratio(self, side):
        v = self.pv.values
        return v[f"friction.{side}.static"] / max(v[f"friction.{side}.dynamic"], 1e-300)

    def _values(self, x):
        """Every special value at x: the fitted ones from x, the others fixed."""
        d = dict(self.fixed)
        d.update(zip(self.names, x))
        return d

    def z(self, x):
        """The kernel-graph input z at the fitted values x."""
        d = self._values(x)
        p = parameter_map(self._index, self.p0, dict(zip(self.names, x)), d["mu_slot"], self._ratios,
                          self._follow)
        return np.concatenate([np.asarray(p, dtype=float).ravel(), [d[s] for s in Z_SPECIAL]])

    def _seed_matrix(self):
        """S = dz/dx at the start: the map from fitted values to z is affine (a derived default that
        follows a fitted input, vane inertia from the mass, is linear in it), so each column is the
        central difference of the map by a unit step ('lag' acts after the kernel: a zero column)."""
        S = np.zeros((self.p0.size + len(Z_SPECIAL), len(self.names)))
        for j, nm in enumerate(self.names):
            at = [{n: v + (n == nm) * sgn for n, v in zip(self.names, self.x0)} for sgn in (0.5, -0.5)]
            hi, lo = (np.asarray(parameter_map(self._index, self.p0, a, 0.0, self._ratios, self._follow),
                                 dtype=float).ravel() for a in at)
            S[:self.p0.size, j] = hi - lo
            if nm in Z_SPECIAL:
                S[self.p0.size + Z_SPECIAL.index(nm), j] = 1.0
        return S

    def angle_and_jacobian(self, x, lib=np):
        """Rotor angle per sample and its derivative by the fitted values (lib = ca for a symbolic
        x): the integral of omega = omega0 (1 + rc cos(k theta_n) - rs sin(k theta_n)) with the
        nominal angle theta_n = theta0 + omega0 (t - delay)."""
        d = self._values(x)
        th0, w0, dl, rc, rs, k = (d["theta0"], d["speed"], d["delay"], d["ripple_cos"], d["ripple_sin"],
                                  self.ripple_order)
        t = self.t if lib is np else ca.DM(self.t)
        thn = th0 + w0 * (t - dl)
        theta, g, _ = ripple_motion(thn, th0, 1.0, rc, rs, k, lib)  # g = omega / omega0
        if lib is not np:
            return theta, None
        cols = {"theta0": g - rc * math.cos(k * th0) + rs * math.sin(k * th0), "speed": (t - dl) * g,
                "delay": -w0 * g, "ripple_cos": (np.sin(k * thn) - math.sin(k * th0)) / k,
                "ripple_sin": (np.cos(k * thn) - math.cos(k * th0)) / k}
        J = np.zeros((t.size, len(self.names)))
        for j, nm in enumerate(self.names):
            if nm in cols:
                J[:, j] = cols[nm]
        return theta, J

    def angle(self, x):
        return self.angle_and_jacobian(x)[0]

    def _lag(self, x):
        return self._values(x)["lag"]

    def _torque(self, theta, z):
        f = sample_torque(self.kern, 0, theta.size)
        return np.asarray(f(theta, self.t, z, self.ripple_order)).ravel()

    def _filter(self, y, T):
        return first_order_lag(y, self.dt, T)

    def model(self, x):
        self.n_eval += 1
        return self._filter(self._torque(self.angle(x), self.z(x)), self._lag(x))

    def model_and_jacobian(self, x, cols=None):
        """Torque and its Jacobian (the columns `cols` only, default all). For the angle-acting
        parameters (theta0, speed, delay, ripple) the derivative is that of the sample-interval
        average of the model, [tau(theta + h) - tau(theta - h)] / (2 h) with 2 h = omega dt:
        Coulomb friction reversals change tau over ~1e-4 rad, far below a sample angle, so the
        pointwise d tau / d theta is a set of spikes that carries no phase information at the
        sampling scale."""
        self.n_eval += 1
        cols = list(range(len(self.names))) if cols is None else list(cols)
        names = [self.names[c] for c in cols]
        theta, dtheta = self.angle_and_jacobian(x)
        z = self.z(x)
        f = sample_torque(self.kern, len(cols), theta.size)
        tq, J = f(theta, self.t, z, self.ripple_order, self._seeds[:, cols])
        tq, J = np.asarray(tq).ravel(), np.asarray(J).reshape(theta.size, len(cols))
        T = self._lag(x)
        slope = None
        if any(n in ANGLE_ACTING for n in names) or ("lag" in names and T == 0):
            h = abs(self.speed_of(x)) * self._half_step
            slope = (self._torque(theta + h, z) - self._torque(theta - h, z)) / (2 * h)
            for i, c in enumerate(cols):
                if self.names[c] in ANGLE_ACTING:
                    J[:, i] += slope * dtheta[:, c]
        if T > 0:
            y = self._filter(tq, T)
            J = self._filter(J, T)
            if "lag" in names:  # d y / d T by finite steps of the exact filter (1-D)
                dT = 1e-6 * T
                J[:, names.index("lag")] = (self._filter(tq, T + dT) - self._filter(tq, T - dT)) / (2 * dT)
            return y, J
        if "lag" in names:  # at T = 0 the filter is y = tau - T dtau/dt to first order
            J[:, names.index("lag")] = -self.speed_of(x) * slope
        return tq, J

    def symbolic_model(self, phi):
        """The (unfiltered) model torque as a CasADi expression of symbolic fitted values phi."""
        theta, _ = self.angle_and_jacobian([phi[i] for i in range(len(self.names))], lib=ca)
        z = ca.DM(self.z(self.x0)) + ca.mtimes(ca.DM(self._seeds), phi - ca.DM(self.x0))
        f = sample_torque(self.kern, 0, self.t.size)
        return f(theta.T, ca.DM(self.t).T, z, self.ripple_order).T

    def residual(self, x):
        return self.y - self.model(x)

    @property
    def dt(self):
        return self.t[1] - self.t[0]

    def time_axis(self):
        return self.t + self.data.time[0]

    def speed_of(self, x):
        return self._values(x)["speed"]

    def start(self, x):
        return phase_and_speed_start(self, x)

    def parameter_vector(self, x):
        return self.z(x)[:self.p0.size]


_SAMPLE_FNS: dict = {}  # per (variant key, directions[, samples]): see sample_torque


def sample_torque(kern, directions: int, samples: int) -> ca.Function:
    """One sample's drive torque at angle theta and time t given z (runtime parameters, theta0,
    speed, delay, torque_offset, ripple_cos, ripple_sin) and the ripple order k -- the speed and
    acceleration come from the ripple at the nominal angle -- with, for directions m > 0, its
    derivatives along the m columns of a seed matrix S; mapped over `samples` samples."""
    key = (kern.key, directions)
    if key not in _SAMPLE_FNS:
        npar = len(layout(kern.structure))
        th, t, k = ca.MX.sym("theta"), ca.MX.sym("t"), ca.MX.sym("k")
        z = ca.MX.sym("z", npar + len(Z_SPECIAL))
        theta0, w0, delay, offset, rc, rs = (z[npar + i] for i in range(len(Z_SPECIAL)))
        _, w, wd = ripple_motion(theta0 + w0 * (t - delay), theta0, w0, rc, rs, k, ca)
        tq = kern["inverse_dynamics"](th, w, wd, z[:npar])[0] + offset
        if directions == 0:
            _SAMPLE_FNS[key] = ca.Function("torque", [th, t, z, k], [tq])
        else:
            S = ca.MX.sym("S", z.size1(), directions)
            _SAMPLE_FNS[key] = ca.Function("torque_dir", [th, t, z, k, S], [tq, ca.jtimes(tq, z, S)])
    mkey = key + (samples,)
    if mkey not in _SAMPLE_FNS:
        _SAMPLE_FNS[mkey] = map_samples(_SAMPLE_FNS[key], samples)
    return _SAMPLE_FNS[mkey]


def start_and_bounds(names, pv, starts, initial=None):
    """Start values and bounds of the fit names (constant-speed and transient problems): a start
    given by the caller, else the measurement's (theta0, speed, ...), else the config value (an
    alias: its first target's -- mu is the housing's dynamic COF); bounds from the registries."""
    initial = initial or {}

    def start(n):
        if n in initial:
            return float(initial[n])
        if n in starts:
            return float(starts[n])
        return float(pv.values[n if n in pv.values else alias_targets(n)[0]])

    lower, upper = zip(*[fit_bounds(n, pv.structure) for n in names]) if names else ((), ())
    return np.array([start(n) for n in names], dtype=float), np.array(lower), np.array(upper)


def following(cfg):
    """The derived defaults the config did not set: they follow their inputs when those are fitted."""
    return tuple(q for q in DERIVED if q.name not in cfg.given)


def parameter_map(index, p0, val, mu_slot_fixed, ratios, follow=()):
    """The runtime parameter vector with the fitted values `val` (name -> expression) put in:
    mu sets the housing COF (static scaled by the configured ratio) and, unless mu_slot is fitted,
    the slot COF; an alias sets its targets (housing.radius: both semi-axes); any other name is a
    parameter path; a derived default in `follow` is recomputed from its fitted inputs."""
    p = [p0[i] for i in range(p0.shape[0])]

    def setp(name, expr):
        p[index[name]] = expr

    mu_slot = mu_slot_fixed
    if "mu" in val:
        setp("friction.housing.dynamic", val["mu"])
        setp("friction.housing.static", val["mu"] * ratios[0])
        if "mu_slot" not in val:
            mu_slot = val["mu"]  # slot COF tied to the housing COF unless mu_slot is named
    if "mu_slot" in val:
        mu_slot = val["mu_slot"]
    if "mu" in val or "mu_slot" in val:
        setp("friction.slot.dynamic", mu_slot)
        setp("friction.slot.static", mu_slot * ratios[1])
    for nm, e in val.items():
        for target in alias_targets(nm) or ((nm,) if nm in index else ()):
            setp(target, e)
    for q in follow:
        if any(n in val for n in q.inputs):
            setp(q.name, derive(q.derived, {n: p[index[n]] for n in q.inputs}))
    return ca.vertcat(*p)


def _scaled_svd(J):
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    U, s, Vt = np.linalg.svd(J / scale, full_matrices=False)
    return scale, U, s, Vt


class FitOutcome(NamedTuple):
    """What every optimiser returns (Gauss-Newton, Levenberg-Marquardt, IPOPT); it unpacks as
    (x, residual, jacobian, history, converged, message)."""

    x: np.ndarray
    residual: np.ndarray
    jacobian: np.ndarray
    history: list
    converged: bool
    message: str


def gauss_newton(prob: Problem, x0, relaxation=1.0, max_iter=50, tol=1e-6, lm=False, log=None,
                 start=None):
    """The report's Gauss-Newton with relaxation factor f (report §12); with lm=True a
    Levenberg-Marquardt damping (Marquardt scaling) instead. Steps are computed by a column-scaled
    least-squares solve; bounds are enforced by projection. `start` = (model, Jacobian) at x0 when
    the caller has them already."""
    x = np.array(x0, dtype=float)
    m, J = start if start is not None else prob.model_and_jacobian(x)
    r = prob.y - m
    history = [{"params": dict(zip(prob.names, map(float, x))), "rms": float(np.sqrt(np.mean(r**2)))}]
    lam = 1e-3
    converged, message = False, "maximum iterations reached"
    for _ in range(max_iter):
        scale, U, s, Vt = _scaled_svd(J)
        if s[-1] < s[0] / SINGULAR_COND:
            message = "Jacobian became singular"
            break
        g = U.T @ r
        if lm:
            while True:
                step = (Vt.T @ (s * g / (s**2 + lam))) / scale
                xn = np.clip(x + step, prob.lower, prob.upper)
                rn = prob.y - prob.model(xn)
                if rn @ rn <= r @ r or lam > 1e12:
                    lam = max(lam / 3, 1e-12)
                    _, Jn = prob.model_and_jacobian(xn)
                    break
                lam *= 4
        else:
            step = relaxation * (Vt.T @ (g / s)) / scale
            for _ in range(10):  # safeguard: halve a step that would increase the residual
                xn = np.clip(x + step, prob.lower, prob.upper)
                rn = prob.y - prob.model(xn)  # trial: the model only, the Jacobian once accepted
                if rn @ rn <= r @ r:
                    _, Jn = prob.model_and_jacobian(xn)
                    break
                step = 0.5 * step
            else:  # no step along the Gauss-Newton direction lowers the residual: at the minimum
                converged, message = True, "no further decrease of the residual"
                break
        small = np.all(np.abs(xn - x) <= tol * (np.abs(x) + 1e-8 * scale.max() / scale))
        x, r, J = xn, rn, Jn
        history.append({"params": dict(zip(prob.names, map(float, x))), "rms": float(np.sqrt(np.mean(r**2)))})
        if log:
            log(history[-1])
        if small:
            converged, message = True, "step below tolerance"
            break
        if history[-2]["rms"] - history[-1]["rms"] <= 1e-6 * history[-1]["rms"]:
            converged, message = True, "residual no longer decreases (relative change < 1e-6)"
            break
    return FitOutcome(x, r, J, history, converged, message)


IPOPT_CONVERGED = ("Solve_Succeeded", "Solved_To_Acceptable_Level", "Search_Direction_Becomes_Too_Small")


def ipopt_fit(prob: Problem, x0, log=None):
    phi = ca.MX.sym("phi", len(prob.names))
    r = ca.DM(prob.y) - prob.symbolic_model(phi)
    nlp = {"x": phi, "f": 0.5 * ca.sumsqr(r)}
    # scale the unknowns by their initial magnitude so IPOPT's tolerances mean the same for all
    sol = ca.nlpsol("fit", "ipopt", nlp, {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
                                          "ipopt.hessian_approximation": "limited-memory",
                                          "ipopt.tol": 1e-12, "ipopt.max_iter": 200})
    res = sol(x0=x0, lbx=np.where(np.isfinite(prob.lower), prob.lower, -1e20),
              ubx=np.where(np.isfinite(prob.upper), prob.upper, 1e20))
    x = np.asarray(res["x"]).ravel()
    m, J = prob.model_and_jacobian(x)
    st = sol.stats()
    r0 = prob.residual(x0)
    history = [{"params": dict(zip(prob.names, map(float, x0))), "rms": float(np.sqrt(np.mean(r0**2))),
                "iteration": 0},
               {"params": dict(zip(prob.names, map(float, x))), "rms": float(np.sqrt(np.mean((prob.y - m) ** 2))),
                "iteration": int(st.get("iter_count", 0))}]
    status = str(st.get("return_status"))
    # IPOPT stops with a step below machine precision at a least-squares minimum whose gradient is
    # at rounding level but above its (strict) tol: that is convergence, not failure
    converged = bool(st.get("success")) or status in IPOPT_CONVERGED
    return FitOutcome(x, prob.y - m, J, history, converged, status)


def speed_band(cfg, data):
    """(lowest, highest) speed a fit may give a measurement without a speed column: the configured
    speed +- operation.speed_tolerance (the operating point is known; a spectral peak elsewhere
    is a disturbance, not the shaft). None when the data has a speed column or no speed is set."""
    if data.speed is not None or cfg.mode != "speed" or not cfg.speed:
        return None
    tol = getattr(cfg, "speed_tolerance", 0.02)
    return cfg.speed * (1 - tol), cfg.speed * (1 + tol)


def phase_and_speed_start(prob: Problem, x):
    """theta0 is periodic and speed moves the phase: start from the best phase (and, when fitted,
    the speed from the torque spectrum) so a wrong initial phase cannot trap the fit."""
    x = np.array(x, dtype=float)
    names = prob.names
    t, y = prob.t, prob.y
    d = dict(zip(names, x))
    w = d.get("speed", prob.fixed["speed"])
    # model over one revolution at the current parameters (theta grid)
    grid = np.linspace(0, 2 * math.pi, 720, endpoint=False)
    pvec = prob.parameter_vector(x)
    from .simulate import inverse_dynamics

    one_rev = inverse_dynamics(prob.kern, pvec, grid, w, 0.0)["torque"]
    banded = "speed" in names and np.isfinite(prob.upper[names.index("speed")])
    if banded:  # inside the tolerance band, from shaft-synchronous evidence only
        lo, hi = prob.lower[names.index("speed")], prob.upper[names.index("speed")]
        w = synchronous_speed_scan(t, y, lo, hi, w)["speed"]
        x[names.index("speed")] = w
        one_rev = inverse_dynamics(prob.kern, prob.parameter_vector(x), grid, w, 0.0)["torque"]
    elif "speed" in names and t.size > 64:
        spec_y = np.abs(np.fft.rfft((y - y.mean()) * np.hanning(y.size)))
        f = np.fft.rfftfreq(y.size, t[1] - t[0])
        k = int(np.argmax(spec_y[1:])) + 1
        if 1 <= k < spec_y.size - 1:  # parabolic peak interpolation
            a, b, c = np.log(spec_y[k - 1:k + 2] + 1e-300)
            k = k + 0.5 * (a - c) / (a - 2 * b + c)
        f_peak = k * (f[1] - f[0])
        orders = np.abs(np.fft.rfft(one_rev - one_rev.mean()))
        order = int(np.argmax(orders[1:])) + 1
        candidates = [2 * math.pi * f_peak / o for o in range(1, 4 * prob.kern.structure.vanes + 1)]
        w_new = min(candidates, key=lambda c: abs(c - w) + (1e9 if abs(c - w) > 0.5 * w else 0))
        if abs(2 * math.pi * f_peak / order - w) < 0.5 * w:
            w_new = 2 * math.pi * f_peak / order
        x[names.index("speed")] = w_new
        w = w_new
        one_rev = inverse_dynamics(prob.kern, prob.parameter_vector(x), grid, w, 0.0)["torque"]
    if "theta0" in names:
        delay = d.get("delay", prob.fixed["delay"])
        th_init = d["theta0"]
        costs = []
        for th0 in np.linspace(0, 2 * math.pi, 360, endpoint=False):
            ang = np.mod(th0 + w * (t - delay), 2 * math.pi)
            m = np.interp(ang, np.append(grid, 2 * math.pi), np.append(one_rev, one_rev[0]))
            A = np.column_stack([m, np.ones_like(m)])
            coef, res, *_ = np.linalg.lstsq(A, y, rcond=None)
            cost = float(res[0]) if res.size else float(np.sum((y - A @ coef) ** 2))
            if coef[0] > 0:
                costs.append((cost, th0))
        if costs:
            # phases the torque cannot tell apart (its angular period) cost the same: take the
            # one nearest the initial guess
            lowest = min(c for c, _ in costs)
            near = [th for c, th in costs if c <= lowest * (1 + 1e-6) + 1e-300]
            dist = lambda a: abs((a - th_init + math.pi) % (2 * math.pi) - math.pi)  # noqa: E731
            x[names.index("theta0")] = min(near, key=dist) if len(near) > 1 else \
                min(costs)[1]
    return x


def base_name(name):
    """'theta0@1' (a per-measurement parameter of a joint fit) -> 'theta0'."""
    return name.split("@", 1)[0]


def make_problem(cfg, data, names, initial=None, extra=None, ripple_order=1):
    """One measurement: Problem; several (a list of Datasets): JointProblem."""
    if isinstance(data, (list, tuple)):
        if len(data) > 1:
            from .joint import JointProblem

            return JointProblem(cfg, data, names, initial, extra, ripple_order)
        data = data[0]
    return Problem(cfg, data, names, initial, extra, ripple_order)


def identify(cfg: PumpConfig, data: Dataset, params=("mu", "theta0"), method="gauss-newton",
             relaxation=1.0, initial=None, max_iter=50, log=None, multistart=True,
             ripple_order=1, extra=None) -> IdentificationResult:
    """Fit `params` to one measurement (a Dataset) or several (a list, fitted jointly) at constant
    speed. The engine behind `pumpsim.identify`, which also takes paths and arrays; see there."""
    if method not in METHODS:
        raise ConfigError(f"--method must be one of {', '.join(METHODS)}, got '{method}'")
    if not 0 < relaxation <= 1:
        raise ConfigError(f"--relaxation must be in (0, 1], got {relaxation:g}")
    if method == "ipopt" and isinstance(data, (list, tuple)) and len(data) > 1:
        raise ConfigError("--method ipopt fits one measurement; use gauss-newton or levenberg-marquardt")
    datasets = data if isinstance(data, (list, tuple)) else [data]
    if cfg.mode != "speed" and "speed" not in params and any(d.speed is None for d in datasets):
        raise ConfigError("identification needs a constant speed: operation.speed in the config, a "
                          "speed column in the data, or 'speed' in --params")
    wall0 = _time.perf_counter()
    prob = make_problem(cfg, data, params, initial, extra, ripple_order=ripple_order)  # extra: held values
    x0 = prob.x0.copy()
    moves_phase = any(base_name(n) in ("theta0", "speed") for n in prob.names)
    start = prob.start(x0) if multistart and moves_phase else x0
    initial_model = prob.model(x0)
    # identifiability at the start and again at the fit: a parameter without effect, or in a
    # near-null direction of J'J (over-parameterised: COF and offset on a concentric rig), gets no
    # number; it is fixed and the others are fitted again
    m_start, J_start = prob.model_and_jacobian(start)
    fixed = dict(zip(prob.names, start))
    active, unident, no_effect = list(prob.names), [], []
    prob_fit, start_fit, at_start, evaluations = prob, start, (m_start, J_start), 0

    def reduced():
        return make_problem(cfg, data, active, {n: fixed[n] for n in active},
                            extra={**(extra or {}), **{n: fixed[n] for n in unident if base_name(n) in SPECIAL}},
                            ripple_order=ripple_order)

    while True:
        dead, flat = _to_fix(active, at_start[1], start_fit, at_start[0]) if at_start else ([], [])
        if dead or flat:
            fixed.update(zip(active, start_fit))
            fixed.update({n: x0[prob.names.index(n)] for n in flat if base_name(n) == "speed"})  # nominal
            unident = sorted(unident + dead + flat, key=prob.names.index)
            no_effect = no_effect + dead
            active = [n for n in active if n not in dead + flat]
            if not active:  # nothing can be fitted: say so, with no numbers for the parameters
                r, w = prob.y - m_start, prob.speed_of(start)
                est = {n: Estimate(n, None, None, None, None, v, identifiable=False)
                       for n, v in zip(prob.names, x0)}
                rms = float(np.sqrt(np.mean(r**2)))
                return IdentificationResult(
                    estimates=est, iterations=[{"params": dict(zip(prob.names, map(float, start))), "rms": rms}],
                    rms=rms, converged=False, message=f"not identifiable from this data: {', '.join(unident)}",
                    correlation=None, diagnostics=residual_report(r, prob.dt, w), method=method,
                    wall_time=_time.perf_counter() - wall0, unidentifiable=unident, time=prob.time_axis(),
                    measured=prob.y, fitted=m_start, initial_model=initial_model, speed=w,
                    angle=prob.angle(start), n_evaluations=prob.n_eval + evaluations,
                    provenance=provenance(cfg, data, prob.kern), no_effect=no_effect)
            evaluations += prob_fit.n_eval if prob_fit is not prob else 0
            prob_fit, start_fit, at_start = reduced(), np.array([fixed[n] for n in active]), None
        if method == "ipopt":
            x, r, J, history, converged, message = ipopt_fit(prob_fit, start_fit, log)
        else:
            x, r, J, history, converged, message = gauss_newton(
                prob_fit, start_fit, relaxation=relaxation, max_iter=max_iter,
                lm=method == "levenberg-marquardt", log=log, start=at_start)
        at_start = (prob_fit.y - r, J)
        if not any(_to_fix(active, J, x, prob_fit.y - r)):
            break
        start_fit = x  # flat at the fit: the loop's head fixes those parameters and refits
    for i, nm in enumerate(prob_fit.names):  # theta0 is periodic: report it in [0, 2 pi)
        if multistart and base_name(nm) == "theta0":
            x[i] = float(np.mod(x[i], 2 * math.pi))
            if x[i] > 2 * math.pi - 1e-12:
                x[i] = 0.0
    k = len(prob_fit.names)
    x0d = dict(zip(prob.names, x0))
    est, corr = fit_estimates(prob_fit.names, x, [x0d[n] for n in prob_fit.names], r, J)
    for name in unident:
        est[name] = Estimate(name, None, None, None, None, x0d[name], identifiable=False)
    est = {nm: est[nm] for nm in prob.names}
    fitted = prob_fit.y - r
    w = prob_fit.speed_of(x)
    diag = residual_report(r, prob.dt, w, fitted=k)
    if unident:
        message += f"; not identifiable from this data: {', '.join(unident)}"
    return IdentificationResult(
        estimates=est, iterations=history, rms=float(np.sqrt(np.mean(r**2))), converged=converged,
        message=message, correlation=corr, diagnostics=diag, method=method,
        wall_time=_time.perf_counter() - wall0, unidentifiable=unident, time=prob.time_axis(),
        measured=prob.y, fitted=fitted, initial_model=initial_model, speed=w, angle=prob_fit.angle(x),
        n_evaluations=prob.n_eval + evaluations + (prob_fit.n_eval if prob_fit is not prob else 0),
        provenance=provenance(cfg, data, prob.kern), on_bound=bounds_reached(prob_fit, x), no_effect=no_effect)


def bounds_reached(prob, x) -> list:
    """[(name, bound)] for fitted values that ended on a finite bound of the fit."""
    out = []
    for i, nm in enumerate(prob.names):
        for b in (prob.lower[i], prob.upper[i]):
            if np.isfinite(b) and abs(x[i] - b) <= 1e-9 * max(1.0, abs(b)):
                out.append((nm, float(b)))
    return out


def fit_estimates(names, x, initial, r, J):
    """Estimates with standard errors, 95 % t-intervals and their correlation from the residual r
    and Jacobian J at the fit x: covariance sigma^2 (J'J)^-1 through the column-scaled SVD."""
    n, k = r.size, len(names)
    sigma2 = float(r @ r) / max(n - k, 1)
    scale, _, s, Vt = _scaled_svd(J)
    cov = (Vt.T / s**2) @ Vt / np.outer(scale, scale) * sigma2
    se = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):  # a noise-free fit has se = 0
        corr = np.where(np.outer(se, se) > 0, cov / np.outer(se, se), np.eye(k))
    tq = stats.t.ppf(0.975, max(n - k, 1))
    est = {nm: Estimate(nm, float(x[i]), float(se[i]), float(x[i] - tq * se[i]), float(x[i] + tq * se[i]),
                        float(initial[i])) for i, nm in enumerate(names)}
    return est, corr


def _unidentifiable(names, J, x, model) -> list:
    """Parameters the data cannot determine: those whose effect on the model is negligible (a
    change by their own size, or by 1 for angles and offsets, moves the model by < 1e-8 of its
    norm), and those in a near-null direction of the column-scaled Jacobian (J'J near-singular)."""
    return sorted(set(_no_effect(names, J, x, model) + _collinear(names, J, x, model)), key=list(names).index)


def _to_fix(names, J, x, model):
    """(parameters without effect, parameters in a flat direction) to fix before fitting. A flat
    direction that involves the speed and others fixes the speed alone: its nominal value (config
    or speed column) is known, and the others (e.g. the COF) are what the fit is for."""
    dead = _no_effect(names, J, x, model)
    flat = _collinear(names, J, x, model)
    speeds = [n for n in flat if base_name(n) == "speed"]
    if speeds and len(flat) > len(speeds):
        flat = speeds
    return dead, flat


def _no_effect(names, J, x, model) -> list:
    """The parameters of `_unidentifiable` that do not act on the model at all."""
    col = np.linalg.norm(J, axis=0)
    size = np.maximum(np.abs(x), 1.0)
    return [n for n, c, sz in zip(names, col, size) if c * sz <= 1e-8 * max(np.linalg.norm(model), 1e-300)]


def _collinear(names, J, x, model) -> list:
    """The parameters of `_unidentifiable` that act, but only in combinations the data cannot
    tell apart."""
    col = np.linalg.norm(J, axis=0)
    size = np.maximum(np.abs(x), 1.0)
    dead = [n for n, c, sz in zip(names, col, size) if c * sz <= 1e-8 * max(np.linalg.norm(model), 1e-300)]
    live = [i for i, n in enumerate(names) if n not in dead]
    bad = []
    if len(live) > 1:  # near-null directions among the parameters that do act
        scale, U, s, Vt = _scaled_svd(J[:, live])
        for j in range(len(s)):
            if s[j] < s[0] / SINGULAR_COND:
                v = np.abs(Vt[j])
                bad += [names[live[i]] for i in np.nonzero(v > 0.3 * v.max())[0]]
    return sorted(set(bad), key=names.index)
