"""The pump-down model (spec §8) sampled as a bench log is (spec §10): driven by the log's measured
voltage, the booster pressure per sample, the current and the speed as block means (the module doc
of pumpdown_fit says why and how).

Without a reed exhaust valve the model has no events, and a run over the whole log is one CVODES
call on the log's output grid: by the direct driver (bench_sens.DirectRuns, with forward
sensitivities for a Jacobian) where it is available, else by CasADi's plugin (`GridRuns`, the runs
of several parameter vectors -- a finite-difference Jacobian -- at once in threads). No restart
every few revolutions, no quadratures carried along. With a reed valve the runtime's
event-locating integration (pneumatics.run) is used.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ..errors import SolverError
from ..pneumatics.drive import VoltageDrive
from ..model_spec.parameters import pneumatic_layout
from ..tolerances import BENCH_FIT_ATOL, BENCH_FIT_RTOL
from . import bench_sens

BLOCK_REVOLUTIONS = 1.0  # current and speed are compared as means over blocks this many revolutions long
MAX_ORDER = 3  # BDF order cap, as the runtime's (pneumatics.run.PumpIntegrator says why)
RUNUP_TIME_CONSTANTS = 3.0  # the run-up: this many mechanical time constants (runup_blocks)
START_NAME = "booster.pressure"  # the fitted start pressure's name (the config key of the booster's start)
MAX_STEPS = 20_000_000  # a whole log in one call: ~80,000 steps per simulated second at rtol 1e-6


def block_samples(cfg, step) -> int:
    """Samples per block: BLOCK_REVOLUTIONS at the motor's no-load speed V/k (the fastest the pump
    turns, so a block holds at least N vane passings there and more below it), at least 1."""
    v = cfg.pneumatic.values
    omega = v["motor.voltage"] / v["motor.constant"]
    return max(1, int(round(BLOCK_REVOLUTIONS * 2 * np.pi / omega / step)))


def block_edges(n, m) -> np.ndarray:
    """Sample indices bounding consecutive blocks of m intervals (the tail shorter than m dropped)."""
    return np.arange(0, n, m) if n > m else np.array([0, n - 1])


def block_means(y, edges) -> np.ndarray:
    """Means of a logged channel's samples over each block (both edges at half weight: the
    trapezoidal mean, as the model's is the mean over the interval)."""
    c = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]))])
    return np.diff(c[edges]) / np.diff(edges)


def runup_blocks(v, edge_times) -> int:
    """Blocks that start within RUNUP_TIME_CONSTANTS mechanical time constants (J R / k^2, the
    config's values) of the log's start. There the current changes within a sample interval (the
    inrush: V/R within L/R, then its decay as the motor speeds up), and the log's trapezoidal
    block mean is not the interval's mean: the model's is taken the same way from its own samples
    there. It is fixed per log, so the cost stays smooth in the parameters; the ripple's phase,
    which the exact mean avoids, has not drifted within it."""
    k = v["motor.constant"]
    tau = (v["motor.inertia"] + v["rotor.inertia"]) * v["motor.resistance"] / k ** 2 if k > 0 else 0.0
    return int(np.searchsorted(edge_times[:-1], RUNUP_TIME_CONSTANTS * tau, side="left"))


class GridRuns:
    """States on a uniform grid from x0 for runtime parameter vectors p, one CVODES call per run
    (the compiled right-hand side and its exact Jacobian in x, states scaled by `scale`); the
    voltage slot of p is replaced by the drive's (drive.VoltageDrive). `runs(x0s, ps)` integrates
    several at once."""

    def __init__(self, kern, grid, drive, scale, rtol, atol):
        from ..kernels.pneumatic import parameter_index
        from ..kernels.scalar import default_threads

        f, fj = kern["pump_rhs"], kern["pump_rhs_jac"]
        nx, n_p = f.size1_in(0), f.size1_in(1)
        self.nx, self.n_p, self.n = nx, n_p, len(grid)
        self.S = np.asarray(scale, float)
        S = ca.DM(self.S)
        iv = parameter_index(kern.structure, "motor.voltage")
        y, t, P = ca.MX.sym("y", nx), ca.MX.sym("t"), ca.MX.sym("p", n_p)
        pv = ca.vertcat(P[:iv], drive.function(t), P[iv + 1:])
        xs = y * S
        js = ca.mtimes(ca.diag(1 / S), ca.mtimes(fj(xs, pv)[0], ca.diag(S)))
        jac = ca.Function("jac_ydot", [y, t, P, ca.MX.sym("out", nx)], [js, ca.MX(nx, 1), ca.MX(nx, n_p)],
                          ["y", "t", "p", "out_ydot"], ["jac_ydot_y", "jac_ydot_t", "jac_ydot_p"])
        ydot = ca.Function("ydot", [y, t, P], [f(xs, pv)[0] / S], ["y", "t", "p"], ["ydot"],
                           {"custom_jacobian": jac, "jac_penalty": 0, "never_inline": True})
        opts = {"abstol": atol, "reltol": rtol, "max_num_steps": MAX_STEPS, "max_order": MAX_ORDER}
        self.integ = ca.integrator("bench_log", "cvodes", {"x": y, "t": t, "p": P, "ode": ydot(y, t, P)},
                                   0.0, list(grid[1:]), opts)
        y0 = ca.MX.sym("y0", nx)
        self._run = ca.Function("bench_run", [y0, P], [self.integ(x0=y0, p=P)["xf"]])
        self._maps = {}
        self.threads = default_threads()
        self.stats = {"runs": 0, "nsteps": 0, "nfevals": 0, "njevals": 0, "netfails": 0}

    def _mapped(self, k):
        if k not in self._maps:
            th = min(k, self.threads)
            self._maps[k] = self._run.map(k, "thread", th) if th > 1 else self._run.map(k, "serial")
        return self._maps[k]

    def runs(self, x0s, ps) -> list:
        """[(n, nx) states] for each (x0, p); one run alone keeps the integrator's statistics."""
        k = len(ps)
        Y0 = np.column_stack([np.asarray(x, float) / self.S for x in x0s])
        P = np.column_stack([np.asarray(p, float) for p in ps])
        try:
            if k == 1:
                out = np.asarray(self.integ(x0=Y0, p=P)["xf"])
                st = self.integ.stats()
                for key, name in (("nsteps", "nsteps"), ("nfevals", "nfevals"), ("njevals", "n_call_jacF"),
                                  ("netfails", "netfails")):
                    self.stats[key] += int(st.get(name, 0))
            else:
                out = np.asarray(self._mapped(k)(Y0, P))
        except RuntimeError as e:
            raise SolverError(f"the pump-down model's integration over the log failed: "
                              f"{str(e).strip().splitlines()[-1]}") from None
        self.stats["runs"] += k
        m = self.n - 1
        return [np.vstack([Y0[:, j], out[:, j * m:(j + 1) * m].T]) * self.S for j in range(k)]


def grid_runs(kern, grid, drive, scale, rtol, atol, direct=None):
    """The runs of the model driven by `drive` on a uniform grid: by the direct driver where it is
    available (direct None) or asked for (bench_sens.DirectRuns), else by CasADi's plugin (GridRuns)."""
    runs = bench_sens.DirectRuns if (bench_sens.usable() if direct is None else direct) else GridRuns
    return runs(kern, grid, drive, scale, rtol, atol)


class BenchModel:
    """The pump-down model driven by a logged voltage, sampled as a bench log is (module doc):
    `channels(p)` -> {booster_pressure, current, speed} at the log's times for the runtime
    parameter vector p."""

    def __init__(self, cfg, time, voltage, start_pressure, omega0=0.0, rtol=BENCH_FIT_RTOL, atol=BENCH_FIT_ATOL,
                 kern=None):
        from ..kernels.pneumatic import kernels, structure_of

        self.cfg, self.rtol, self.atol = cfg, rtol, atol
        self.kern = kernels(cfg) if kern is None else kern
        self.names = [q.name for q in pneumatic_layout(structure_of(cfg))]
        self.t0 = float(time[0])
        self.t = np.asarray(time, float) - self.t0
        self.n = self.t.size
        self.start_pressure, self.omega0 = float(start_pressure), float(omega0)
        self.step = float(self.t[-1] / max(self.n - 1, 1))
        self.grid = self.step * np.arange(self.n)  # the model's uniform grid, the log's times without jitter
        self.volt = volt = np.interp(self.grid, self.t, voltage)
        self.drive = VoltageDrive(self.step, volt)  # the logged voltage, linear between samples
        # integral of the voltage from the start to each sample
        self.volt_integral = np.concatenate([[0.0], np.cumsum(0.5 * (volt[1:] + volt[:-1]) * self.step)])
        self.jittered = bool(np.ptp(np.diff(self.t)) > 0)
        N = cfg.vanes
        self.i_b = 3 + 2 * N + 2  # the booster's mass (run.state_names)
        self.edges = block_edges(self.n, block_samples(cfg, self.step))
        from ..kernels.pneumatic import parameter_vector

        self.runup = runup_blocks(dict(zip(self.names, parameter_vector(cfg))), self.t[self.edges])
        self.block_time = 0.5 * (self.t[self.edges[1:]] + self.t[self.edges[:-1]]) + time[0]
        self.mean_speed = 0.0
        self._grid_runs = None  # GridRuns or DirectRuns, made at the first run (its state scale from that run's start)
        self.direct = bench_sens.usable()  # the direct driver: its runs, and sensitivities

    def compared(self, logged: dict) -> dict:
        """A log's channels as the model gives them: pressure per sample, current and speed as
        block means."""
        return {c: y if c == "booster_pressure" else block_means(y, self.edges) for c, y in logged.items()}

    def times(self, channel) -> np.ndarray:
        return self.t + self.t0 if channel == "booster_pressure" else self.block_time

    @property
    def stats(self) -> dict:
        """The integrator's work so far: runs, and steps, right-hand sides, Jacobians and error-test
        failures (CasADi's plugin: of the runs made one at a time, a threaded batch reports none;
        the direct driver: of every run, and the sensitivities' right-hand-side differences and
        jumps)."""
        return dict(self._grid_runs.stats) if self._grid_runs is not None else {}

    def split(self, p):
        """(the runtime parameter vector, the start pressure) of p: a vector one longer than the
        runtime's carries a fitted start pressure last (START_NAME), else the log's estimate."""
        p = np.asarray(p, float).ravel()
        return (p[:-1], float(p[-1])) if p.size == len(self.names) + 1 else (p, self.start_pressure)

    def start_state(self, p):
        """The state at the log's first sample: the pump at rest (or the logged speed), the cells at
        the atmosphere, inlet manifold and booster at the start pressure (split)."""
        from ..pneumatics import run

        p, start = self.split(p)
        return run.initial_state(self.cfg, self.kern, p, omega0=self.omega0, booster_start=start)

    def _grid_states(self, ps) -> list:
        from ..pneumatics import run

        x0s = [self.start_state(p) for p in ps]
        ps = [self.split(p)[0] for p in ps]
        reed = self.names.index("valve.reed")
        if any(p[reed] > 0.5 for p in ps):  # valve events: the runtime's event-locating integration
            out = []
            for p, x0 in zip(ps, x0s):
                r = run.integrate(self.cfg, self.step * (self.n - 1) * (1 + 1e-12), 1.0 / self.step, p=p,
                                  x0=x0, rtol=self.rtol, atol=self.atol, kern=self.kern, drive=self.drive)
                if r.states.shape[0] < self.n:
                    raise SolverError(f"the pump-down model stopped at sample {r.states.shape[0]} of {self.n}")
                out.append(r.states[:self.n])
            return out
        return self._runs(x0s[0], ps[0]).runs(x0s, ps)

    def _runs(self, x0, p):
        if self._grid_runs is None:
            from ..pneumatics import run

            scale = run.state_scale(x0, p, self.kern.structure)
            self._grid_runs = grid_runs(self.kern, self.grid, self.drive, scale, self.rtol, self.atol, self.direct)
        return self._grid_runs

    def has_sensitivities(self, p) -> bool:
        """Whether channels_and_jacobian can run at p (a fitted start pressure last or not): the
        direct driver, and no reed valve (its events go through the runtime's integration)."""
        return self.direct and self.split(p)[0][self.names.index("valve.reed")] <= 0.5

    def channels_and_jacobian(self, p, directions, scales):
        """(channels(p), {channel: (m, k) derivatives}) along the runtime parameter directions
        (k, n_p), one run with forward sensitivities (bench_sens); scales: the fitted parameters'
        sizes (the sensitivities' tolerances and the difference steps are relative to them). A
        fitted start pressure (p and the directions one longer, split) moves the start state only:
        its sensitivity starts at the start state's derivative and has no right-hand-side term."""
        x0, q = self.start_state(p), self.split(p)[0]
        h = bench_sens.MAP_STEP * np.asarray(scales, float)
        s0 = np.array([(self.start_state(p + hj * d) - self.start_state(p - hj * d)) / (2 * hj)
                       for hj, d in zip(h, directions)])
        X, SX = self._runs(x0, q).run(x0, q, np.ascontiguousarray(np.asarray(directions, float)[:, :q.size]),
                                      bench_sens.P_STEP * np.asarray(scales, float), scales, s0)
        if self.jittered:
            X = self._onto_log(X)
            SX = np.stack([self._onto_log(SX[:, j, :]) for j in range(SX.shape[1])], axis=1)
        self.mean_speed = float((X[-1, 0] - X[0, 0]) / max(self.t[-1], 1e-300))
        return bench_sens.channel_derivatives(lambda Y, q: self._compared(Y, dict(zip(self.names, q))), X, SX, p,
                                              directions, scales)

    def _onto_log(self, X):
        return np.column_stack([np.interp(self.t, self.grid, c) for c in X.T])

    def _states_many(self, ps) -> list:
        """[(states at the log's times, parameter values by name)] for runtime parameter vectors."""
        out = []
        for p, X in zip(ps, self._grid_states(ps)):
            if self.jittered:  # the model onto the log's own times
                X = self._onto_log(X)
            out.append((X, dict(zip(self.names, p))))
        X = out[0][0]
        self.mean_speed = float((X[-1, 0] - X[0, 0]) / max(self.t[-1], 1e-300))
        return out

    def _states(self, p):
        return self._states_many([p])[0]

    def _pressure(self, X, pv):
        return X[:, self.i_b] * pv["gas.gas_constant"] * pv["gas.temperature"] / pv["booster.volume"]

    def samples(self, p) -> dict:
        """What a bench would log, sample by sample: booster pressure, current, speed."""
        X, pv = self._states(p)
        return {"booster_pressure": self._pressure(X, pv), "current": X[:, 2], "speed": X[:, 1]}

    def channels(self, p) -> dict:
        """What is compared (module doc): pressure per sample, current and speed as block means."""
        return self.channels_many([p])[0]

    def channels_many(self, ps) -> list:
        """channels(p) for several parameter vectors, integrated at once (GridRuns)."""
        return [self._compared(X, pv) for X, pv in self._states_many(ps)]

    def _compared(self, X, pv) -> dict:
        theta, cur = X[self.edges, 0], X[self.edges, 2]
        dth, dcur, span = np.diff(theta), np.diff(cur), np.diff(self.t[self.edges])
        mean_i = (np.diff(self.volt_integral[self.edges]) - pv["motor.constant"] * dth
                  - pv["motor.inductance"] * dcur) / (pv["motor.resistance"] * span)
        k = self.runup
        if k:  # sampled as the log is (runup_blocks)
            mean_i[:k] = block_means(X[:, 2], self.edges[:k + 1])
        return {"booster_pressure": self._pressure(X, pv), "current": mean_i, "speed": dth / span}


