"""One optimiser interface for every identification problem: the report's Gauss-Newton with
relaxation factor (report §12), Levenberg-Marquardt, or IPOPT through CasADi's nlpsol with bounds.
Each returns a FitOutcome."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import casadi as ca
import numpy as np

from .. import interrupt
from ..distributions import f_sf
from ..errors import ConfigError
from ..tolerances import SINGULAR_COND, STEP_SE

METHODS = ("gauss-newton", "levenberg-marquardt", "ipopt")
# IPOPT stops with a step below machine precision at a least-squares minimum whose gradient is at
# rounding level but above its (strict) tol: that is convergence, not failure
IPOPT_CONVERGED = ("Solve_Succeeded", "Solved_To_Acceptable_Level", "Search_Direction_Becomes_Too_Small")


@dataclass(frozen=True)
class FitOutcome:
    """What every optimiser returns: the fitted values x, the residual (measured - model) and the
    Jacobian at x, the history [{"params", "rms"[, "iteration"]}], whether it converged and why."""

    x: np.ndarray
    residual: np.ndarray
    jacobian: np.ndarray
    history: list
    converged: bool
    message: str
    keep: np.ndarray | None = None  # the samples the reversal-aware cost kept at x (None: all)
    # a fit no step left from its start, which is NOT a minimum (start_test): where the Gauss-Newton
    # step from it points (clipped to the bounds), the start to fit again from; None otherwise
    points_to: np.ndarray | None = None
    # a fit that did not converge: what the linear model says its remaining step would still take
    # off the cost, in noise variances (the step's squared length in standard errors); None otherwise
    left_chi2: float | None = None

    def __iter__(self):  # unpacks as (x, residual, jacobian, history, converged, message)
        return iter((self.x, self.residual, self.jacobian, self.history, self.converged, self.message))


@dataclass(frozen=True)
class Optimiser:
    """The method and its settings, checked once; `fit(problem, x0)` -> FitOutcome for any Problem."""

    method: str = "gauss-newton"
    relaxation: float = 1.0  # Gauss-Newton's relaxation factor f in (0, 1]
    max_iter: int = 50
    log: Callable | None = None  # called with each history entry
    final_jacobian: bool = True  # False: a fit that ends by max_iter has no Jacobian there (see gauss_newton)

    def __post_init__(self):
        if self.method not in METHODS:
            raise ConfigError(f"method must be one of {', '.join(METHODS)}, got '{self.method}'")
        if not 0 < self.relaxation <= 1:
            raise ConfigError(f"relaxation must be in (0, 1], got {self.relaxation:g}")

    def fit(self, prob, x0, start=None) -> FitOutcome:
        """Fit prob from x0; `start` = (model, Jacobian) at x0 when the caller has them already."""
        if self.method == "ipopt":
            return ipopt_fit(prob, x0, self.log, self.max_iter)
        return gauss_newton(prob, x0, relaxation=self.relaxation, max_iter=self.max_iter,
                            lm=self.method == "levenberg-marquardt", log=self.log, start=start,
                            final_jacobian=self.final_jacobian)


def scaled_svd(J):
    """SVD of J with unit-norm columns: (column norms, U, s, Vt); a zero column keeps scale 1."""
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    U, s, Vt = np.linalg.svd(J / scale, full_matrices=False)
    return scale, U, s, Vt


def _sumsq(v) -> float:
    return float(v @ v)


def _rms(r) -> float:
    return float(np.sqrt(np.mean(r**2)))


def _weights(prob, x):
    """1 per sample, 0 where the reversal-aware cost drops the sample at x (Problem.keep_at)."""
    keep = prob.keep_at(x)
    return None if keep is None else keep.astype(float)


def _wrms(r, w) -> float:
    return _rms(r) if w is None else float(np.sqrt((w * r) @ (w * r) / max(w.sum(), 1.0)))


NO_DECREASE = "no further decrease of the residual"
# A fit its iteration limit stops is converged when the Gauss-Newton step left is below STEP_SE
# standard errors in every parameter (_remaining_step); the message says how long it is
MAX_ITER = "maximum iterations reached"
STEP_BELOW_SE = MAX_ITER + "; the remaining Gauss-Newton step is below {lim:g} standard errors (at most {se:.2g}, in {name})"
STEP_ABOVE_SE = MAX_ITER + "; the remaining Gauss-Newton step is {se:.3g} standard errors in {name}"
ALL_ON_BOUNDS = MAX_ITER + "; every parameter is on a bound the remaining Gauss-Newton step points past"
# A start no step leaves counts as a minimum when the data cannot tell it from the one the
# Gauss-Newton step points to: the F test of "the parameters are the start's" (the linear model's
# reduction of the residual against the residual left) does not reject at this level, i.e. the start
# lies inside the fit's own 95 % confidence region. Started at the truth this holds 95 % of the time;
# a start the slope leads many standard errors away (a step of a staircase cost) fails it.
START_TEST_LEVEL = 0.05
NO_STEP_FROM_START = "no step from the start lowered the residual"
START_IS_MINIMUM = (NO_STEP_FROM_START + ", and the data cannot tell the start from a minimum: the "
                    "Gauss-Newton step from it is {se} standard errors long (F test p = {p:.2g}); the "
                    "estimates are the start values")
START_NOT_MINIMUM = (NO_STEP_FROM_START + ", yet the start is NOT a minimum: the model's slope there points "
                     "{se} standard errors away (to {to}; F test p = {p:.2g}); the start may sit on a step "
                     "of the cost (friction reversals make it a staircase) -- fit again from another start "
                     "(--start NAME=VALUE, e.g. the values the slope points to)")


def _free_of_bounds(x, step, lower, upper) -> np.ndarray:
    """The parameters a step may move: not those on a bound it points past (held there, the
    minimum on that face is what counts)."""
    return ~(((x <= lower) & (step < 0)) | ((x >= upper) & (step > 0)))


def start_test(x, full, rw, Jw, lower, upper, n) -> tuple[float, float]:
    """(length, p): the Gauss-Newton step from x in standard errors, and the F test's p-value of
    "x is the minimum". The linear model's reduction of the residual's sum of squares, d, against
    what it leaves, |rw|^2 - d, over n - k degrees of freedom: length = sqrt(d / sigma^2) (the step
    in the estimate's covariance sigma^2 (J'J)^-1), F = d / k / sigma^2. rw, Jw: the weighted
    residual and Jacobian; n: the samples weighed (the reversal-aware cost's kept ones). A parameter
    on a bound the step points past is held there (the minimum on that face is what counts)."""
    free = _free_of_bounds(x, full, lower, upper)
    if not free.any():  # every parameter is held by its bound: the start is the minimum on them
        return 0.0, 1.0
    U = scaled_svd(Jw[:, free])[1]
    d, k = _sumsq(U.T @ rw), int(free.sum())
    left = max(_sumsq(rw) - d, 0.0)
    if d == 0.0:
        return 0.0, 1.0
    if left == 0.0:  # the step would fit the data exactly: no noise to hide it in
        return float("inf"), 0.0
    sigma2 = left / max(n - k, 1)
    return float(np.sqrt(d / sigma2)), float(f_sf(d / k / sigma2, k, max(n - k, 1)))


def gauss_newton(prob, x0, relaxation=1.0, max_iter=50, tol=1e-6, lm=False, log=None,
                 start=None, final_jacobian=True) -> FitOutcome:
    """The report's Gauss-Newton with relaxation factor f (report §12); with lm=True a
    Levenberg-Marquardt damping (Marquardt scaling) instead. Steps are computed by a column-scaled
    least-squares solve; bounds are enforced by projection. `start` = (model, Jacobian) at x0 when
    the caller has them already. With a reversal-aware problem the samples it drops weigh 0; that
    mask is fixed during a step (trial points compared on it) and recomputed between steps.
    final_jacobian=False: the point the last of max_iter steps reaches gets its model only (the
    trial's, remembered: no model run) and the outcome's `jacobian` is None -- for a scout that
    only compares where a few steps lead (a Jacobian with interval columns costs ~10 model runs).
    A fit that reaches max_iter with its Jacobian is converged when the Gauss-Newton step left is
    below STEP_SE standard errors in every parameter (_remaining_step): the flag and message only."""
    x = np.array(x0, dtype=float)
    m, J = start if start is not None else prob.model_and_jacobian(x)
    r, w = prob.y - m, _weights(prob, x)
    wt = (lambda v: v) if w is None else (lambda v: (w * v.T).T)  # noqa: E731
    history = [{"params": dict(zip(prob.names, map(float, x))), "rms": _wrms(r, w)}]
    lam = 1e-3
    converged, message, points_to, left = False, MAX_ITER, None, None
    for it in range(max_iter):
        rw = wt(r)
        scale, U, s, Vt = scaled_svd(wt(J))
        if s[-1] < s[0] / SINGULAR_COND:
            message = "Jacobian became singular"
            break
        g = U.T @ rw
        del U  # n x k: not held while the next point's model and Jacobian are evaluated
        if lm:
            xn, lam = _damped_step(prob, x, rw, wt, (g, s, Vt, scale), lam)
        else:
            xn = _halved_step(prob, x, rw, wt, relaxation * (Vt.T @ (g / s)) / scale)
        if xn is None:  # no step along the Gauss-Newton direction lowers the residual: at the minimum
            converged, message = True, NO_DECREASE
            if not it:  # ... unless it never moved: a minimum only if the slope there is noise
                converged, message, points_to, left = _stalled_start(prob, x, (Vt.T @ (g / s)) / scale, rw, wt(J),
                                                                     w, scale, tol)
            break
        J = r = rw = None  # replaced below: not held while the next ones are evaluated (memory)
        mn, Jn = (prob.model(xn), None) if not final_jacobian and it == max_iter - 1 else prob.model_and_jacobian(xn)
        small = np.all(np.abs(xn - x) <= tol * (np.abs(x) + 1e-8 * scale.max() / scale))
        x, r, J, w = xn, prob.y - mn, Jn, _weights(prob, xn)
        history.append({"params": dict(zip(prob.names, map(float, x))), "rms": _wrms(r, w)})
        interrupt.progress(f"in a fit of {', '.join(prob.names)} after {len(history) - 1} iterations "
                           f"(residual RMS {history[-1]['rms']:.4g} {getattr(prob, 'RESIDUAL_UNIT', 'N m')})")
        if log:
            log(history[-1])
        if small:
            converged, message = True, "step below tolerance"
            break
        if history[-2]["rms"] - history[-1]["rms"] <= 1e-6 * history[-1]["rms"]:
            converged, message = True, "residual no longer decreases (relative change < 1e-6)"
            break
    else:  # the iteration limit: still creeping, or there (a scout's end has no Jacobian to tell)
        if J is not None:
            converged, message, left = _remaining_step(prob, x, wt(r), wt(J), r.size if w is None else float(w.sum()))
    return FitOutcome(x, r, J, history, converged, message, None if w is None else w > 0, points_to,
                      None if converged else left)


def _remaining_step(prob, x, rw, Jw, n) -> tuple[bool, str, float | None]:
    """(converged, message, left_chi2) of a fit its iteration limit stopped at x: converged when the
    Gauss-Newton step from x (to the linear model's minimum, rw and Jw weighted as in the fit) is
    below STEP_SE standard errors in every parameter -- a fit still creeping by a few 1e-6 of its
    RMS per step whose estimates would move by less than that is at its minimum as far as the
    data can tell. Standard errors: sigma^2 (J'J)^-1, sigma^2 = rss / (n - k). A parameter on a
    bound the step points past is held there (start_test's rule); a singular Jacobian tells nothing.
    left_chi2 (not converged): the whole remaining step's squared length in standard errors."""
    scale, U, s, Vt = scaled_svd(Jw)
    if s[-1] < s[0] / SINGULAR_COND:
        return False, MAX_ITER, None
    full = (Vt.T @ ((U.T @ rw) / s)) / scale
    free = _free_of_bounds(x, full, prob.lower, prob.upper)
    if not free.any():
        return True, ALL_ON_BOUNDS, None
    if not free.all():  # the step with the held ones out
        scale, U, s, Vt = scaled_svd(Jw[:, free])
        full = (Vt.T @ ((U.T @ rw) / s)) / scale
    else:
        full = full[free]
    sigma2 = _sumsq(rw) / max(n - x.size, 1)
    se = np.sqrt(sigma2 * np.sum((Vt.T / s) ** 2, axis=1)) / scale
    ratio = np.zeros(x.size)
    # noise-free data (sigma 0): only a zero step is below any share of its standard error
    ratio[free] = np.divide(np.abs(full), se, out=np.where(full != 0, np.inf, 0.0), where=se > 0)
    j = int(np.argmax(ratio))
    if ratio[j] <= STEP_SE:
        return True, STEP_BELOW_SE.format(lim=STEP_SE, se=ratio[j], name=prob.names[j]), None
    left = start_test(x, np.zeros(x.size), rw, Jw, np.full(x.size, -np.inf), np.full(x.size, np.inf), n)[0] ** 2
    return False, STEP_ABOVE_SE.format(se=ratio[j], name=prob.names[j]), left


def _halved_step(prob, x, rw, wt, step):
    """x + step, halved (up to 9 times) until the residual does not increase (trials run the model
    only, the Jacobian once accepted); None when none lowers it."""
    for _ in range(10):
        xn = np.clip(x + step, prob.lower, prob.upper)
        if _sumsq(wt(prob.y - prob.model(xn))) <= rw @ rw:
            return xn
        step = 0.5 * step
    return None


def _damped_step(prob, x, rw, wt, svd, lam):
    """Levenberg-Marquardt (Marquardt scaling): (x + the step damped by lam, raised 4x until the
    residual decreases; the next lam), or (None, lam) when no damping up to 1e12 lowers it. Strictly
    lower: a step damped to rounding leaves the residual equal, and read as 'step below tolerance'
    it would call any start a minimum."""
    g, s, Vt, scale = svd
    while lam <= 1e12:
        xn = np.clip(x + (Vt.T @ (s * g / (s**2 + lam))) / scale, prob.lower, prob.upper)
        if _sumsq(wt(prob.y - prob.model(xn))) < rw @ rw:
            return xn, max(lam / 3, 1e-12)
        lam *= 4
    return None, lam


def _stalled_start(prob, x, full, rw, Jw, w, scale, tol):
    """(converged, message, points_to, left_chi2) of a fit no step leaves from its start: a minimum
    when the whole Gauss-Newton step is below the step tolerance or the start passes start_test
    (points_to None), else not converged, with where the slope points (in the message, and as
    points_to) and the step's squared length in standard errors."""
    se, p = start_test(x, full, rw, Jw, prob.lower, prob.upper, rw.size if w is None else float(w.sum()))
    if p >= START_TEST_LEVEL or np.all(np.abs(full) <= tol * (np.abs(x) + 1e-8 * scale.max() / scale)):
        return True, START_IS_MINIMUM.format(se=f"{se:.2g}", p=p), None, None
    to = np.clip(x + full, prob.lower, prob.upper)
    length = f"{se:.3g}" if np.isfinite(se) else "infinitely many (noise-free data)"
    where = ", ".join(f"{nm} = {v:.6g}" for nm, v in zip(prob.names, to))
    return False, START_NOT_MINIMUM.format(se=length, p=p, to=where), to, se ** 2


def ipopt_fit(prob, x0, log=None, max_iter=200) -> FitOutcome:
    """IPOPT (limited-memory Hessian) on 0.5 |y - model|^2 with the fit's bounds; the problem gives
    its model as a CasADi expression (`symbolic_model`); the samples it did not measure
    (Problem.measured) weigh 0."""
    phi = ca.MX.sym("phi", len(prob.names))
    keep = prob.measured
    r = ca.DM(prob.y) - prob.symbolic_model(phi)
    if keep is not None:
        r = r * ca.DM(keep.astype(float))
    nlp = {"x": phi, "f": 0.5 * ca.sumsqr(r)}
    sol = ca.nlpsol("fit", "ipopt", nlp, {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
                                          "ipopt.hessian_approximation": "limited-memory",
                                          "ipopt.tol": 1e-12, "ipopt.max_iter": int(max_iter)})
    with interrupt.deferred():  # IPOPT would report a signal in its callbacks as a failed solve
        res = sol(x0=x0, lbx=np.where(np.isfinite(prob.lower), prob.lower, -1e20),
                  ubx=np.where(np.isfinite(prob.upper), prob.upper, 1e20))
    x = np.asarray(res["x"]).ravel()
    m, J = prob.model_and_jacobian(x)
    st = sol.stats()
    w = None if keep is None else keep.astype(float)
    history = [{"params": dict(zip(prob.names, map(float, x0))), "rms": _wrms(prob.residual(x0), w), "iteration": 0},
               {"params": dict(zip(prob.names, map(float, x))), "rms": _wrms(prob.y - m, w),
                "iteration": int(st.get("iter_count", 0))}]
    status = str(st.get("return_status"))
    converged = bool(st.get("success")) or status in IPOPT_CONVERGED
    return FitOutcome(x, prob.y - m, J, history, converged, status, keep)
