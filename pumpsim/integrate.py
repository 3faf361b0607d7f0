"""Time integration with CasADi's SUNDIALS interfaces and located switches.

The right-hand side of a pump model is continuous but has kinks where a friction direction or a
slot contact side changes (and jumps where Model 1 changes contact state). Rather than rely on
CasADi's experimental integrator events (casadi issue 4393), the integration is segmented: each
output interval is integrated, the switching functions are checked for a sign change, a change is
located by the Illinois method on re-integrations from the interval start, and the integrator is
restarted at the switch. Between switches the equations are smooth, which is what BDF wants.
"""
from __future__ import annotations

import time as _time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from .errors import SolverError

STAT_KEYS = ("nsteps", "nfevals", "nlinsetups", "netfails", "nniters", "nncfails", "njevals")


@dataclass
class Stepper:
    """x(t0 + dt) = step(x(t0), dt) with a fixed parameter vector."""

    integ: ca.Function
    params: np.ndarray
    method: str
    stats: dict = field(default_factory=lambda: {k: 0 for k in STAT_KEYS})
    calls: int = 0

    def __call__(self, x, dt):
        self.calls += 1
        res = self.integ(x0=x, p=np.concatenate([self.params, [dt]]))
        if self.method != "rk":
            st = self.integ.stats()
            for k in STAT_KEYS:
                v = st.get(k)
                if isinstance(v, (int, float)):
                    self.stats[k] += int(v)
        return np.asarray(res["xf"]).ravel()


def make_stepper(rhs, nx: int, params, method="cvodes", rtol=1e-8, atol=1e-10, max_step=None,
                 rk_steps=50):
    """Integrator over normalised time [0, 1] with the duration as the last parameter.

    rhs(x, p) -> xdot (CasADi, MX-callable). method: cvodes (BDF, Newton, exact Jacobian through the
    compiled forward derivatives), idas, or rk (explicit Runge-Kutta 4 with fixed substeps)."""
    params = np.asarray(params, dtype=float).ravel()
    x = ca.MX.sym("x", nx)
    pp = ca.MX.sym("p", params.size + 1)
    T = pp[-1]
    ode = T * rhs(x, pp[:-1])
    opts = {}
    if method == "cvodes":
        opts = {"abstol": atol, "reltol": rtol, "max_num_steps": 200000}
        if max_step:
            opts["max_step_size"] = max_step
        integ = ca.integrator("step", "cvodes", {"x": x, "p": pp, "ode": ode}, 0.0, 1.0, opts)
    elif method == "idas":
        opts = {"abstol": atol, "reltol": rtol, "max_num_steps": 200000}
        integ = ca.integrator("step", "idas", {"x": x, "p": pp, "ode": ode}, 0.0, 1.0, opts)
    elif method == "rk":
        integ = ca.integrator("step", "rk", {"x": x, "p": pp, "ode": ode}, 0.0, 1.0,
                              {"number_of_finite_elements": rk_steps})
    else:
        raise ValueError(f"unknown integration method {method!r}")
    return Stepper(integ, params, method)


def integrate_segmented(stepper: Stepper, x0, times, switch_fn=None, on_step=None,
                        time_tol=1e-11, progress=None):
    """Integrate to every output time, locating sign changes of switch_fn(x) -> 1-D array.

    Returns (states (n_times, nx), events list of (time, index), stats dict).
    A failure raises SolverError naming the time and state, with the partial result attached."""
    times = np.asarray(times, dtype=float)
    xs = np.empty((times.size, len(x0)))
    xs[0] = x0
    x = np.asarray(x0, dtype=float)
    events = []
    t = times[0]
    g = switch_fn(x) if switch_fn else None
    wall0 = _time.perf_counter()
    for k in range(1, times.size):
        t_end = times[k]
        while t < t_end:
            dt = t_end - t
            try:
                x_new = stepper(x, dt)
            except RuntimeError as e:
                raise SolverError(
                    f"integrator failed between t = {t:.9g} s and {t_end:.9g} s from state "
                    f"{np.array2string(x, precision=6)}: {str(e).splitlines()[-1]}",
                    partial=(times[:k], xs[:k])) from None
            if not np.all(np.isfinite(x_new)):
                raise SolverError(f"integrator returned a non-finite state after t = {t:.9g} s "
                                  f"(state {np.array2string(x, precision=6)})", partial=(times[:k], xs[:k]))
            if switch_fn is None:
                x, t = x_new, t_end
                break
            g_new = switch_fn(x_new)
            crossed = np.nonzero(np.sign(g_new) != np.sign(g))[0]
            crossed = [i for i in crossed if g[i] != 0.0]
            if not crossed:
                x, t, g = x_new, t_end, g_new
                break
            # locate the earliest crossing
            t_s, idx = None, None
            for i in crossed:
                ti = _illinois(lambda d: switch_fn(stepper(x, d))[i], 0.0, dt, g[i], g_new[i],
                               time_tol)
                if t_s is None or ti < t_s:
                    t_s, idx = ti, i
            if t_s <= 0.0:  # switching function sits at zero: step past it
                x, t, g = x_new, t_end, g_new
                break
            x = stepper(x, t_s)
            t = t + t_s
            g = switch_fn(x)
            g[idx] = g_new[idx]  # count this crossing as done
            events.append((t, int(idx)))
        xs[k] = x
        if on_step:
            on_step(t, x)
        if progress:
            progress(t)
    stats = dict(stepper.stats)
    stats["integrator_calls"] = stepper.calls
    stats["events"] = len(events)
    stats["wall_time"] = _time.perf_counter() - wall0
    return xs, events, stats


def _illinois(f, a, b, fa, fb, tol, max_iter=60):
    """Root of f on [a, b] with f(a) fa, f(b) fb of opposite signs; returns a point just after it."""
    side = 0
    for _ in range(max_iter):
        c = (a * fb - b * fa) / (fb - fa) if fb != fa else 0.5 * (a + b)
        if not a < c < b:
            c = 0.5 * (a + b)
        fc = f(c)
        if np.sign(fc) == np.sign(fb) or fc == 0.0:
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
        if b - a < tol:
            break
    return b
