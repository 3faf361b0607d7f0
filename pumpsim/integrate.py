"""Time integration with CasADi's SUNDIALS interfaces and located switches.

A pump model's right-hand side has kinks or jumps where a contact state, a friction direction or a
slot contact side changes. CasADi's integrator events are experimental (casadi issue 4393: CVODES
fires on one crossing direction only, IDAS ignores them), so switches are handled here by
step-and-check segmentation:

- the output grid is integrated in chunks of many output intervals per CVODES call (no restart
  inside a chunk, so BDF keeps its order and step size);
- the switching functions are evaluated on the whole chunk at once; at the first sign change the
  chunk is cut back to the output time before it;
- that interval is re-integrated from its start to locate the crossing (Illinois method on the
  integrated switching function, to `time_tol`), the integrator is restarted at the crossing and
  the remaining part of the interval is integrated from there.

Between located switches the equations are smooth, which is what BDF wants.
"""
from __future__ import annotations

import time as _time

import casadi as ca
import numpy as np

from . import cvodes_driver, interrupt
from .errors import ConfigError, SolverError
from .tolerances import ATOL, RTOL

# CVODES/IDAS statistics summed over calls (report Table 13), ours -> CasADi's name
STAT_KEYS = {"nsteps": "nsteps", "nfevals": "nfevals", "njevals": "n_call_jacF", "nlinsetups": "nlinsetups",
             "netfails": "netfails", "nniters": "nniters", "nncfails": "nncfails"}
CHUNK = 64  # output intervals per integrator call


class Integrator:
    """x(t0 + k dt), k = 1..m, in one call (`chunk`), and x(t0 + d) for any d (`step`)."""

    def __init__(self, rhs, nx: int, params, dt: float, method="cvodes", rtol=RTOL, atol=ATOL,
                 max_step=None, rk_steps=10, max_steps=500000, scale=None, bounds=None, names=None,
                 direct=None):
        """scale: a nominal size per state; the integrator works on x / scale, so the absolute
        tolerance of state i is atol * scale[i] (the relative one is unchanged).
        bounds: (lower, upper) per state, the physically possible range; a state outside it (or
        not finite) is a numerical failure, for every method (an explicit RK4 that diverges gives
        finite nonsense long before it overflows). names: the states' names for the message.
        direct: for method cvodes, a function (rtol, per-state atol, max_steps, max_step) ->
        cvodes_driver.Driver over the same right-hand side's compiled kernel, or None; used where
        the driver is available (chunks then carry on without a restart)."""
        for name, val in (("rtol", rtol), ("atol", atol)):
            if not 0 < val < 1:
                raise ConfigError(f"--{name} must be in (0, 1), got {val:g}")
        if max_step is not None and not max_step > 0:
            raise ConfigError(f"max_step must be > 0, got {max_step:g}")
        self.bounds = None if bounds is None else (np.asarray(bounds[0], float), np.asarray(bounds[1], float))
        self.names = list(names) if names is not None else [f"x[{i}]" for i in range(nx)]
        self.params = np.asarray(params, dtype=float).ravel()
        self.nx, self.dt, self.method = nx, float(dt), method
        self.rtol, self.atol, self.max_step, self.rk_steps = rtol, atol, max_step, rk_steps
        self.max_steps = int(max_steps)
        self.scale = np.ones(nx) if scale is None else np.asarray(scale, dtype=float).ravel()
        y = ca.MX.sym("x", nx)
        pp = ca.MX.sym("p", self.params.size + 1)
        self._x, self._pp = y, pp
        self._rhs = rhs(self.scale * y, pp[:-1]) / self.scale
        self.stats = {k: 0 for k in STAT_KEYS}
        self.calls = 0
        self._chunks = {}
        # any duration: normalised time [0, 1], the duration as the last parameter
        self._step = self._make("step", pp[-1] * self._rhs, [1.0], normalised=True)
        self.direct = None
        if direct is not None and method == "cvodes" and cvodes_driver.available()[0]:
            self.direct = direct(rtol, atol * self.scale, self.max_steps, max_step)
        self.driver = "cvodes (direct)" if self.direct else method + (" (casadi)" if method != "rk" else "")

    def _make(self, name, ode, grid, normalised=False):
        dae = {"x": self._x, "p": self._pp, "ode": ode}
        if self.method in ("cvodes", "idas"):
            opts = {"abstol": self.atol, "reltol": self.rtol, "max_num_steps": self.max_steps}
            if self.max_step and not normalised:
                opts["max_step_size"] = self.max_step
            return ca.integrator(name, self.method, dae, 0.0, grid, opts)
        if self.method == "rk":  # fixed steps: rk_steps per output interval (the option is a total)
            return ca.integrator(name, "rk", dae, 0.0, grid,
                                 {"number_of_finite_elements": self.rk_steps * len(grid)})
        raise ConfigError(f"method must be cvodes, idas or rk, got {self.method!r}")

    def _call(self, integ, x, extra, intervals=1):
        self.calls += 1
        with interrupt.deferred():
            res = integ(x0=np.asarray(x, dtype=float) / self.scale, p=np.concatenate([self.params, [extra]]))
        if self.method == "rk":  # RK4: four right-hand sides a step
            self.stats["nsteps"] += self.rk_steps * intervals
            self.stats["nfevals"] += 4 * self.rk_steps * intervals
        else:
            st = integ.stats()
            for k, name in STAT_KEYS.items():
                v = st.get(name)
                if isinstance(v, (int, float)):
                    self.stats[k] += int(v)
        return np.asarray(res["xf"]) * self.scale[:, None]

    def _call_direct(self, x, touts):
        """The direct driver on its own clock: from where its last call ended if x is the state
        it ended in (no restart), else restarted from x at 0."""
        self.calls += 1
        d = self.direct
        last = d.last
        x = np.asarray(x, dtype=float)
        t0 = last[0] if last is not None and np.array_equal(last[1], x) else 0.0
        try:
            with interrupt.deferred():
                X = d.run(t0, x, t0 + touts)
        except SolverError as e:
            raise RuntimeError(str(e)) from None
        self.stats.update(d.stats)
        return X

    def run_from(self, t0, x, touts):
        """The direct driver from x at t0 (no restart if that is where its last call ended) to
        touts; with its switching functions it stops at a root (self.direct.root)."""
        self.calls += 1
        try:
            with interrupt.deferred():
                X = self.direct.run(t0, np.asarray(x, dtype=float), touts)
        except SolverError as e:
            raise RuntimeError(str(e)) from None
        self.stats.update(self.direct.stats)
        return X

    def step(self, x, duration):
        if self.direct is not None:
            self.direct.last = None  # a step is a fresh start (event location re-integrates)
            return self._call_direct(x, np.array([duration]))[0] if duration > 0 else np.asarray(x, float)
        return self._call(self._step, x, duration).ravel()

    def chunk(self, x, m):
        if self.direct is not None:
            return self._call_direct(x, self.dt * np.arange(1, m + 1))
        if m not in self._chunks:
            grid = list(self.dt * np.arange(1, m + 1))
            self._chunks[m] = self._make(f"chunk{m}", self._rhs, grid)
        return self._call(self._chunks[m], x, 0.0, intervals=m).T  # (m, nx)


def integrate_segmented(integ: Integrator, x0, times, switch_fn=None, on_chunk=None,
                        time_tol=1e-11, progress=None):
    """Integrate to every output time (uniform grid), locating sign changes of the switching
    functions switch_fn(X) -> (len(X), n_switch) for states X (len, nx).

    Returns (states (n_times, nx), events [(time, switch index)], stats). A failure raises
    SolverError naming the time and state, an interruption Interrupted, either with (times,
    states) computed so far attached. Where the integrator's direct driver has the switching
    functions itself, CVODES locates them (_located_by_cvodes) and switch_fn is not used."""
    times = np.asarray(times, dtype=float)
    if integ.direct is not None and integ.direct.n_roots:
        return _located_by_cvodes(integ, x0, times, on_chunk, progress)
    n = times.size
    xs = np.empty((n, len(x0)))
    xs[0] = x = np.asarray(x0, dtype=float)
    events = []
    g = switch_fn(x[None, :])[0] if switch_fn else None
    wall0 = _time.perf_counter()
    k = 0
    interrupt.progress(f"at simulated t = {times[0]:.6g} s of {times[-1]:.6g} s")
    try:
        while k < n - 1:
            m = min(CHUNK, n - 1 - k)
            steps_before = integ.stats["nsteps"]
            X = _guarded(integ, lambda: integ.chunk(x, m), times[k], times[k + m], x, times[:k + 1],
                         xs[:k + 1])
            cut = m
            if switch_fn is not None:
                G = switch_fn(X)
                prev = np.vstack([g[None, :], G[:-1]])
                changed = (np.sign(G) != np.sign(prev)) & (prev != 0.0)
                rows = np.nonzero(changed.any(axis=1))[0]
                if rows.size:
                    cut = int(rows[0])  # intervals accepted before the one with the crossing
            if cut:
                xs[k + 1:k + 1 + cut] = X[:cut]
                x = X[cut - 1]
                k += cut
                g = switch_fn(x[None, :])[0] if switch_fn else None
                if on_chunk:
                    on_chunk(times[k], cut, integ.stats["nsteps"] - steps_before)
            if cut < m:  # the interval [times[k], times[k+1]] holds a crossing: locate, restart
                x, g = _cross_interval(integ, switch_fn, x, g, times[k], times[k + 1], events, time_tol,
                                       times[:k + 1], xs[:k + 1])
                xs[k + 1] = x
                k += 1
            interrupt.progress(f"at simulated t = {times[k]:.6g} s of {times[-1]:.6g} s")
            if progress:
                progress(times[k])
    except interrupt.Interrupted as e:  # xs[:k + 1] is done
        if e.partial is None:
            e.partial = (times[:k + 1], xs[:k + 1])
        raise
    stats = dict(integ.stats)
    stats["integrator_calls"] = integ.calls
    stats["driver"] = integ.driver
    stats["events"] = len(events)
    stats["wall_time"] = _time.perf_counter() - wall0
    return xs, events, stats


def _located_by_cvodes(integ, x0, times, on_chunk, progress):
    """integrate_segmented with CVODES' own root finding on its interpolant: output chunks carry
    on without a restart, a switch stops the chunk at its root, and the solver restarts there."""
    n, d = times.size, integ.direct
    xs = np.empty((n, len(x0)))
    xs[0] = x = np.asarray(x0, dtype=float)
    events, t, k = [], times[0], 0
    d.last = None
    wall0 = _time.perf_counter()
    try:
        while k < n - 1:
            touts = times[k + 1:k + 1 + min(CHUNK, n - 1 - k)]
            if touts[0] - t <= 1e-12 * max(1.0, abs(t)):  # a root on an output time: that row is x
                xs[k + 1], k, t = x, k + 1, touts[0]
                continue
            steps_before = integ.stats["nsteps"]
            X = _guarded(integ, lambda: integ.run_from(t, x, touts), t, touts[-1], x, times[:k + 1], xs[:k + 1])
            xs[k + 1:k + 1 + len(X)] = X
            k += len(X)
            if d.root is None:
                t, x = times[k], X[-1]
            else:  # restart at the root (d.last None): the right-hand side changes there
                t, x, found = d.root
                _guarded(integ, lambda: x, t, t, x, times[:k + 1], xs[:k + 1])
                events.extend((t, int(i)) for i in found)
                d.last = None
            if on_chunk and len(X):
                on_chunk(times[k], len(X), integ.stats["nsteps"] - steps_before)
            interrupt.progress(f"at simulated t = {times[k]:.6g} s of {times[-1]:.6g} s")
            if progress:
                progress(times[k])
    except interrupt.Interrupted as e:
        if e.partial is None:
            e.partial = (times[:k + 1], xs[:k + 1])
        raise
    stats = dict(integ.stats, integrator_calls=integ.calls, driver=integ.driver, events=len(events),
                 wall_time=_time.perf_counter() - wall0)
    return xs, events, stats


def _guarded(integ, fn, t_a, t_b, x, done_t, done_x):
    """Run one integrator call; a CasADi failure, a non-finite state or a state outside its
    physical bounds raises SolverError naming the interval and the state."""
    try:
        out = fn()
    except RuntimeError as e:
        interrupt.check(partial=(done_t, done_x))  # a signal inside the integrator's callbacks
        raise SolverError(
            f"integrator failed between t = {t_a:.9g} s and {t_b:.9g} s starting from state "
            f"{np.array2string(x, precision=6)}: {str(e).strip().splitlines()[-1]}",
            partial=(done_t, done_x)) from None
    rows = np.atleast_2d(out)
    bad = ~np.isfinite(rows)
    what = "a non-finite state"
    if not bad.any() and integ.bounds is not None:
        bad = (rows < integ.bounds[0]) | (rows > integ.bounds[1])
        what = "a state outside its physical bounds"
    if bad.any():
        k, i = np.argwhere(bad)[0]
        lo, hi = integ.bounds if integ.bounds is not None else (None, None)
        limit = f" (bounds {lo[i]:.4g} .. {hi[i]:.4g})" if lo is not None else ""
        raise SolverError(f"integrator returned {what} between t = {t_a:.9g} s and {t_b:.9g} s: "
                          f"{integ.names[i]} = {rows[k, i]:.6g}{limit}; the state at {t_a:.9g} s was "
                          f"{np.array2string(x, precision=6, max_line_width=10**6)} -- a smaller max_step or an implicit "
                          "method (cvodes) may help", partial=(done_t, done_x))
    return out


def _cross_interval(integ, switch_fn, x, g, t, t_end, events, time_tol, done_t, done_x):
    while t < t_end:
        dt = t_end - t
        x_new = _guarded(integ, lambda: integ.step(x, dt), t, t_end, x, done_t, done_x)
        g_new = switch_fn(x_new[None, :])[0]
        crossed = [i for i in np.nonzero(np.sign(g_new) != np.sign(g))[0] if g[i] != 0.0]
        if not crossed:
            return x_new, g_new
        roots = {i: illinois(lambda d, i=i: switch_fn(integ.step(x, d)[None, :])[0][i], 0.0, dt,
                              g[i], g_new[i], time_tol) for i in crossed}
        t_s = min(roots.values())
        simultaneous = [i for i, ti in roots.items() if ti <= t_s + 10 * time_tol]
        if t_s >= dt:  # crossing at the interval end
            events.extend((t_end, int(i)) for i in simultaneous)
            return x_new, g_new
        x = _guarded(integ, lambda: integ.step(x, t_s), t, t + t_s, x, done_t, done_x)
        t = t + t_s
        g = switch_fn(x[None, :])[0]
        for i in simultaneous:  # these crossings are done
            g[i] = g_new[i]
            events.append((t, int(i)))
    return x, g


def illinois(f, a, b, fa, fb, tol, max_iter=60):
    """Root of f on [a, b] (f(a), f(b) of opposite signs); returns a point just past it."""
    side = 0
    for _ in range(max_iter):
        c = (a * fb - b * fa) / (fb - fa) if fb != fa else 0.5 * (a + b)
        if not a < c < b:
            c = 0.5 * (a + b)
        fc = f(c)
        if fc == 0.0 or np.sign(fc) == np.sign(fb):
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
