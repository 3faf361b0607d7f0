"""The identification driver: a Problem for the data (constant speed, several measurements
jointly, or a transient), its parameters checked for identifiability before and after the fit,
one Optimiser, one IdentificationResult."""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass

import numpy as np

from ..blas import small_solves
from ..config import PumpConfig
from ..data import Dataset
from ..signals import residual_report
from ..errors import ConfigError, StartError
from .adequacy import VERDICTS, assess
from .identifiability import to_fix
from .joint import JointProblem
from .optimiser import FitOutcome, Optimiser
from .problem import ConstantSpeedProblem, Problem, base_name, interval_geometric
from .result import Estimate, IdentificationResult, bounds_reached, fit_estimates, provenance
from .transient import TransientProblem


def make_problem(cfg, data, names, initial=None, extra=None, ripple_order=1, transient=False,
                 reversals=None, interval=False, speed_in_band=False) -> Problem:
    """One measurement: ConstantSpeedProblem; several (a list of Datasets): JointProblem; a run-up
    or coast-down (transient=True): TransientProblem. `extra`: values held for special names.
    `reversals`: None, or the noise sigma (0: estimated at each x) of the reversal-aware cost (reversals.py).
    `interval`: the geometric defects' Jacobian columns from the sample-interval average (problem.py).
    `speed_in_band`: a fitted speed stays in the measurement's tolerance band (problem.speed_band) --
    for refining a known operating point; otherwise its start is searched over a wide band."""
    datasets = list(data) if isinstance(data, (list, tuple)) else [data]
    if transient:
        if len(datasets) > 1:
            raise ConfigError("transient identification fits one measurement")
        return TransientProblem(cfg, datasets[0], names, initial, extra)
    if len(datasets) > 1:
        prob = JointProblem(cfg, datasets, names, initial, extra, ripple_order, speed_in_band)
        for s in prob.subs:  # each measurement its own noise sigma
            s.reversal_sigma, s.interval_geometry = reversals, interval
        return prob
    prob = ConstantSpeedProblem(cfg, datasets[0], names, initial, extra, ripple_order, speed_in_band)
    prob.reversal_sigma, prob.interval_geometry = reversals, interval
    return prob


@small_solves
def identify(cfg: PumpConfig, data: Dataset, params=("mu", "theta0"), method="gauss-newton",
             relaxation=1.0, initial=None, max_iter=50, log=None, multistart=True,
             ripple_order=1, extra=None, transient=False, reversals=None,
             interval=False, speed_in_band=False, adequacy=True, at=None, polish=True,
             final_jacobian=True) -> IdentificationResult:
    """Fit `params` to one measurement (a Dataset) or several (a list, fitted jointly) at constant
    speed, or to a run-up/coast-down's speed under its measured torque (transient=True). The
    engine behind `pumpsim.identify`, which also takes paths and arrays; see there. `at`: (x,
    model, Jacobian) the caller already has, used if x is this fit's start. `polish=False`: an
    interval fit without its exact polish (a scout that only chooses a start). `final_jacobian=False`:
    a fit that ends by max_iter is not checked for identifiability at its end and its estimates
    have values only (a scout compared by its RMS; optimiser.gauss_newton)."""
    optimiser = Optimiser(method, relaxation, max_iter, log, final_jacobian)
    datasets = data if isinstance(data, (list, tuple)) else [data]
    if method == "ipopt" and len(datasets) > 1:
        raise ConfigError("method 'ipopt' fits one measurement; use gauss-newton or levenberg-marquardt")
    if method == "ipopt" and transient:  # CVODES adjoints inside IPOPT: minutes, and they fail
        raise ConfigError("method 'ipopt' fits constant-speed data; a transient fit uses gauss-newton or "
                          "levenberg-marquardt")
    if not transient and cfg.mode != "speed" and "speed" not in params and any(d.speed is None for d in datasets):
        raise ConfigError("identification needs a constant speed: operation.speed in the config, a "
                          "speed column in the data, or 'speed' in params")
    wall0 = _time.perf_counter()
    prob = make_problem(cfg, data, params, initial, extra, ripple_order, transient, reversals, interval, speed_in_band)

    def reduced(active, fixed, unident):  # the identifiable names, the others held where they were
        held = {n: fixed[n] for n in unident if base_name(n) in prob.SPECIAL}
        return make_problem(cfg, data, active, {n: fixed[n] for n in active}, {**(extra or {}), **held},
                            ripple_order, transient, reversals, interval, speed_in_band)

    start = prob.start(prob.x0) if multistart and prob.moves_phase() else prob.x0.copy()
    at_start = None
    if isinstance(prob, ConstantSpeedProblem) and np.array_equal(start, prob.x0):
        # its model is the model at the start, to the bit: one model run fewer per fit
        at_start = at[1:] if at is not None and np.array_equal(at[0], start) else prob.model_and_jacobian(start)
        initial_model = at_start[0]
    else:
        initial_model = prob.model(prob.x0)
    fit = fit_identifiable(prob, start, optimiser, reduced, at_start)
    res = _result(prob, fit, multistart, adequacy)
    res.initial_model, res.method = initial_model, method + prob.METHOD_TAG
    res.provenance, res.wall_time = provenance(cfg, data, prob.kern), _time.perf_counter() - wall0
    if polish and interval and fit.outcome is not None and any(interval_geometric(n) for n in prob.names):
        # the interval columns lead into the valley; the exact ones polish inside it (their
        # difference quotients resolve a reversal's motion to 1/8 interval only: noisy near the
        # minimum), the better of the two kept
        values = {n: e.value for n, e in res.estimates.items() if e.value is not None}
        exact = fit.prob.exact_at(fit.outcome.x) if fit.prob.names == prob.names else None
        polished = identify(cfg, data, params, method, relaxation, {**(initial or {}), **values}, max_iter, log,
                            False, ripple_order, extra, transient, reversals, speed_in_band=speed_in_band,
                            adequacy=adequacy, at=None if exact is None else (fit.outcome.x, *exact))
        if polished.rms <= res.rms:
            polished.wall_time = _time.perf_counter() - wall0
            return polished
    return res


def identify_transient(cfg: PumpConfig, data: Dataset, params=("mu", "speed0"), initial=None,
                       max_iter=30, method="gauss-newton") -> IdentificationResult:
    """Fit `params` (mu, mu_slot, speed0, theta0 or config paths) to a run-up or coast-down: the
    measured torque drives the model, its speed is compared with the measured speed."""
    return identify(cfg, data, params, method=method, initial=initial, max_iter=max_iter, transient=True)


@dataclass
class _Fit:
    """The identifiable part of a fit: the problem finally fitted (its names the identifiable
    ones), the optimiser's outcome (None when nothing is identifiable), the names fixed on the way."""

    prob: Problem
    outcome: FitOutcome | None
    start: np.ndarray
    model_at_start: np.ndarray
    unident: list
    no_effect: list
    evaluations: int  # model evaluations of the problems fitted and dropped on the way


def fit_identifiable(prob, start, optimiser, reduced, at_start=None) -> _Fit:
    """Identifiability at the start and again at the fit: a parameter without effect, or in a
    near-null direction of J'J (over-parameterised: COF and offset on a concentric rig), gets no
    number; it is fixed and the others are fitted again. `at_start`: the model and Jacobian at
    `start` when the caller has them."""
    at_start = prob.model_and_jacobian(start) if at_start is None else at_start
    if not (np.all(np.isfinite(at_start[0])) and np.all(np.isfinite(at_start[1]))):
        raise StartError(not_finite_at(prob.names, start))
    m_start = at_start[0]
    fixed = dict(zip(prob.names, start))
    active, unident, no_effect = list(prob.names), [], []
    prob_fit, start_fit, evaluations = prob, start, 0
    while True:
        dead, flat = to_fix(active, at_start[1], start_fit, at_start[0]) if at_start else ([], [])
        if dead or flat:
            fixed.update(zip(active, start_fit))
            fixed.update({n: prob.x0[prob.names.index(n)] for n in flat if base_name(n) == "speed"})  # nominal
            unident = sorted(unident + dead + flat, key=prob.names.index)
            no_effect = no_effect + dead
            active = [n for n in active if n not in dead + flat]
            if not active:  # nothing can be fitted: say so, with no numbers for the parameters
                return _Fit(prob, None, start, m_start, unident, no_effect, evaluations)
            evaluations += prob_fit.n_eval if prob_fit is not prob else 0
            prob_fit, start_fit, at_start = reduced(active, fixed, unident), np.array([fixed[n] for n in active]), None
        out = optimiser.fit(prob_fit, start_fit, start=at_start)
        at_start = (prob_fit.y - out.residual, out.jacobian)
        if out.jacobian is None or not any(to_fix(active, out.jacobian, out.x, prob_fit.y - out.residual)):
            return _Fit(prob_fit, out, start, m_start, unident, no_effect, evaluations)
        start_fit = out.x  # flat at the fit: the loop's head fixes those parameters and refits


def not_finite_at(names, start) -> str:
    """The message of a start where the model (or its slope) is not finite."""
    values = ", ".join(f"{n} = {v:.6g}" for n, v in zip(names, start))
    return (f"the model is not finite at the fit's start ({values}): a start outside the pump's geometry "
            "or physics (a housing centre or lobe beyond the clearance, a negative size); start nearer the "
            "configured values (--start NAME=VALUE) or check the config")


def _result(prob, fit: _Fit, wrap_phase: bool, adequacy: bool = True) -> IdentificationResult:
    """The result in the names asked for (`prob`): estimates of the identifiable ones, no number
    for the others; residual diagnostics at the fit (or at the start when nothing was fitted)."""
    x0 = dict(zip(prob.names, prob.x0))
    if fit.outcome is None:
        r, w, x = prob.y - fit.model_at_start, prob.speed_of(fit.start), fit.start
        est, corr, k, history = {}, None, 0, [{"params": dict(zip(prob.names, map(float, x))),
                                                "rms": float(np.sqrt(np.mean(r**2)))}]
        converged, message, on_bound, fitted_prob, intervals = False, "", [], prob, None
    else:
        out, fitted_prob = fit.outcome, fit.prob
        x, r, history = np.array(out.x, dtype=float), out.residual, out.history
        for i, nm in enumerate(fitted_prob.names):  # theta0 is periodic: report it in [0, 2 pi)
            if wrap_phase and base_name(nm) == "theta0":
                x[i] = float(np.mod(x[i], 2 * math.pi))
                x[i] = 0.0 if x[i] > 2 * math.pi - 1e-12 else x[i]
        k, w = len(fitted_prob.names), fitted_prob.speed_of(x)
        kept = slice(None) if out.keep is None else out.keep  # the reversal-aware cost's samples
        if out.jacobian is None:  # a scout's end (final_jacobian=False): values only
            est, corr, intervals = {n: Estimate(n, float(v), None, initial=x0[n]) for n, v in
                                    zip(fitted_prob.names, x)}, None, None
        else:
            est, corr, intervals = fit_estimates(fitted_prob.names, x, [x0[n] for n in fitted_prob.names], r[kept],
                                                 out.jacobian[kept], fitted_prob.y[kept],
                                                 _channels(fitted_prob, out.keep))
        converged, message, on_bound = out.converged, out.message + prob.NOTE, bounds_reached(fitted_prob, x)
    for name in fit.unident:
        est[name] = Estimate(name, None, None, None, None, x0[name], identifiable=False)
    if fit.unident:
        message += ("; " if message else "") + f"not identifiable from this data: {', '.join(fit.unident)}"
    n_eval = prob.n_eval + fit.evaluations + (fitted_prob.n_eval if fitted_prob is not prob else 0)
    keep = None if fit.outcome is None else fit.outcome.keep
    rk = r if keep is None else r[keep]
    adequacy = adequacy_at(fitted_prob, x, fitted_prob.y - r) if adequacy else None
    return IdentificationResult(
        estimates={nm: est[nm] for nm in prob.names}, iterations=history, rms=float(np.sqrt(np.mean(rk**2))),
        converged=converged, message=message, correlation=corr,
        diagnostics=residual_report(rk, prob.dt, w, fitted=k), method="", wall_time=0.0,
        unidentifiable=fit.unident, time=prob.time_axis(), measured=prob.y, fitted=fitted_prob.y - r,
        speed=w, angle=fitted_prob.angle(x), n_evaluations=n_eval, on_bound=on_bound, no_effect=fit.no_effect,
        keep=keep, adequacy=adequacy, intervals=intervals, residual_unit=prob.RESIDUAL_UNIT,
        points_to=None if fit.outcome is None or fit.outcome.points_to is None else
        dict(zip(fitted_prob.names, map(float, fit.outcome.points_to))),
        left_chi2=None if fit.outcome is None else fit.outcome.left_chi2)


def _channels(prob, keep) -> list:
    """[(name, kept rows)] of the residual's own time axes: each measurement of a joint fit."""
    n = prob.y.size
    edges = list(prob.rows) if isinstance(prob, JointProblem) else [0, n]
    kept = np.ones(n, bool) if keep is None else np.asarray(keep, bool)
    names = [f"measurement {i + 1}" for i in range(len(edges) - 1)] if len(edges) > 2 else [
        "speed" if isinstance(prob, TransientProblem) else "torque"]
    return [(nm, int(kept[lo:hi].sum())) for nm, lo, hi in zip(names, edges[:-1], edges[1:])]


def adequacy_at(prob, x, fitted):
    """The fit's adequacy (adequacy.py): per measurement of a joint fit, the worst one kept; None
    for a transient fit (its residual is a speed, not a torque)."""
    if isinstance(prob, TransientProblem):
        return None
    if isinstance(prob, JointProblem):
        found = [_assess_measured(s, fitted[a:b], x[c], len(prob.names))
                 for s, c, a, b in zip(prob.subs, prob.cols, prob.rows[:-1], prob.rows[1:])]
        return max(found, key=lambda q: VERDICTS.index(q.verdict))
    return _assess_measured(prob, fitted, x, len(prob.names))


def _assess_measured(prob, fitted, x, k):
    """assess on the longest stretch of measured samples (all of them unless resampling bridged a
    gap): its tests need a uniform grid, and the samples inside a gap were not measured."""
    lo, hi = longest_run(prob.measured, prob.y.size)
    return assess(prob.y[lo:hi], fitted[lo:hi], prob.angle(x)[lo:hi], prob.dt, prob.speed_of(x), k)


def longest_run(mask, n) -> tuple:
    """(lo, hi) of the longest run of True in mask (all n samples when mask is None)."""
    if mask is None:
        return 0, n
    edges = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(mask, int), [0]])))
    starts, ends = edges[::2], edges[1::2]
    i = int(np.argmax(ends - starts))
    return int(starts[i]), int(ends[i])
