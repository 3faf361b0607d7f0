"""Time integration of the pneumatic pump (spec §8): CVODES on the compiled right-hand side with
its compiled exact Jacobian, energy and mass budgets as CVODES quadratures, and the reed valve's
seat and stop as located events.

The reed is a hybrid system: free (m x'' + c x' + k x = dp A - preload), seated (x = 0) or on its
stop (x = x_max). Its mode is a runtime parameter of the kernel. Switching functions: free -> lift x
(reaching the seat) and x_max - x (reaching the stop); seated -> the net opening force; on the stop
-> the net force. A crossing is located by Illinois root finding on re-integrations from the last
output time (to EVENT_TIME_TOL), the mode changes there with the lift rate set to zero (the reed
stops dead on seat and stop), and the integration restarts: the lift never steps past x_max.
"""
from __future__ import annotations

import math
import time as _time
from contextlib import contextmanager
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from .. import cvodes_driver, interrupt
from . import geometry_table as geometry_tables
from ..errors import SolverError
from ..integrate import illinois
from ..tolerances import GAS_ATOL, GAS_RTOL
from ..kernels.pneumatic import kernels, parameter_index, parameter_vector
from ..model_spec.parameters import REED_MODES
from ..model_spec.outputs import shape as output_shape

EVENT_TIME_TOL = 1e-10  # s
CHUNK = 50  # output intervals per integrator call
MAX_ORDER = 3  # BDF order cap (see PumpIntegrator)
# Steps between Jacobian updates of the direct driver (CVODES' default 51): the gas dynamics change
# within a vane passage, and an old Jacobian costs Newton failures and steps. Measured on the EVP
# pump-down (rtol = atol = 1e-7 reference: time to target 5.1879 s): every 51 steps 153,758 steps,
# 276,401 rhs, 14,361 Jacobians, 5.1949 s; every 10: 149,975 / 263,548 / 17,595, 5.1915 s; every
# 4: 143,675 / 246,708 / 25,226, 5.1915 s; every 2: 141,843 / 239,653 / 31,487, 5.1909 s
# (CasADi's plugin, a Jacobian per set-up: 144,913 / 244,119 / 43,431, 5.1911 s). A Jacobian costs
# about 1.6 right-hand sides.
JAC_EVERY = 4
# After a successful step CVODES keeps the step unless the ratio it proposes leaves (0, 1.5): it
# never shrinks a step before it fails, and the port edges and orifice branches then cost error-
# test and Newton failures (each a wasted Newton solve and a step cut to a quarter or less).
# Keeping it only within (0.9, 1.2), on the EVP pump-down: 143,909 -> 132,723 steps, 247,170 ->
# 229,309 rhs, 10,759 -> 8,437 error-test and 11,455 -> 10,036 Newton failures, 25,398 -> 27,058
# Jacobians and 41,919 -> 54,336 set-ups; time to target 5.19133 -> 5.19118 s (rtol = atol = 1e-7
# reference: 5.18792 s). (0.9, 1.1), (0.7, 1.1): fewer steps (129,561, 126,880), more rhs and
# set-ups; (0, 1.2): 131,275 steps but 242,725 rhs; (0.9, 1.3): 136,305 steps.
KEEP_STEP = (0.9, 1.2)
OUTPUT_BLOCK = 4096  # rows per pump_outputs map call (evaluate_outputs)
STAT_KEYS = {"nsteps": "nsteps", "nfevals": "nfevals", "njevals": "n_call_jacF",
             "nlinsetups": "nlinsetups", "netfails": "netfails", "nniters": "nniters",
             "nncfails": "nncfails"}
QUAD_NAMES = ("electrical_energy", "shaft_work", "gas_work", "friction_work", "copper_loss",
              "motor_friction_work", "valve_damping_work", "atmosphere_mass")


def state_names(N):
    return (["theta", "omega", "current"] + [f"mass_{i}" for i in range(N)]
            + [f"energy_{i}" for i in range(N)]
            + ["inlet_mass", "exhaust_mass", "booster_mass", "inlet_energy", "exhaust_energy",
               "reed_lift", "reed_rate"])


@dataclass
class PumpdownRun:
    time: np.ndarray
    states: np.ndarray  # (n, nx)
    quad: np.ndarray  # (n, nq), cumulative from t = 0
    outputs: dict  # name -> array (per sample, or (n, N) per cell / vane)
    stats: dict
    events: list = field(default_factory=list)
    time_to_target: float | None = None
    p: np.ndarray | None = None
    peak_current: float = 0.0  # A, |current| at its located maximum (peak_current)


class PumpIntegrator:
    """x(t) of the pneumatic kernel with CVODES; `valve mode` is the one integrator parameter."""

    driver_geometry = "exact"  # "table": the direct driver reads the cell geometry from a table

    def __init__(self, kern, p, rtol=GAS_RTOL, atol=GAS_ATOL, scale=None, max_steps=2_000_000, drive=None,
                 geometry_table=None):
        """drive: the supply voltage (drive.VoltageDrive, a bench log's measured voltage) in place of
        motor.voltage; the integrations then take their start time t0.
        geometry_table: the direct driver reads the cell geometry from a table over one turn
        (pneumatics.geometry_table; None: unless PUMPSIM_GEOMETRY=exact), else computes it."""
        self.kern, self.p, self.drive = kern, np.asarray(p, dtype=float), drive
        self.geometry_table = geometry_tables.enabled() if geometry_table is None else bool(geometry_table)
        nx = kern["pump_rhs"].size1_in(0)
        self.nx = nx
        self.scale = np.ones(nx) if scale is None else np.asarray(scale, float)
        self.mode_index = parameter_index(kern.structure, "valve.mode")
        e = np.zeros(self.p.size)
        e[self.mode_index] = 1.0
        p0 = self.p.copy()
        p0[self.mode_index] = 0.0
        f, fj = kern["pump_rhs"], kern["pump_rhs_jac"]
        # the quadratures ride along as states (one kernel call gives both rates); their
        # columns of the Jacobian are zero
        nq = f.size1_out(1)
        self.nq = nq
        y, mode = ca.MX.sym("y", nx + nq), ca.MX.sym("mode")
        S = ca.DM(np.concatenate([self.scale, np.ones(nq)]))
        P = ca.DM(p0) + ca.DM(e) * mode
        ins, names = [y, mode], ["y", "mode"]
        if drive is not None:  # the voltage enters like the mode: a runtime input of the kernel
            volt = ca.MX.sym("volt")
            ev = np.zeros(self.p.size)
            ev[parameter_index(kern.structure, "motor.voltage")] = 1.0
            P = ca.DM(p0 * (1 - ev)) + ca.DM(e) * mode + ca.DM(ev) * volt
            ins, names = ins + [volt], names + ["volt"]
        xs = y[:nx] * S[:nx]
        xdot, qdot = f(xs, P)
        Jx, Jq = fj(xs, P)
        J = ca.vertcat(ca.horzcat(Jx, ca.MX(nx, nq)), ca.horzcat(Jq, ca.MX(nq, nq)))
        out = ca.MX.sym("out", nx + nq)
        jac = ca.Function("jac_ydot", ins + [out],
                          [ca.mtimes(ca.diag(1 / S), ca.mtimes(J, ca.diag(S)))] + [ca.MX(nx + nq, 1)] * (len(ins) - 1),
                          names + ["out_ydot"], [f"jac_ydot_{n}" for n in names])
        ydot = ca.Function("ydot", ins, [ca.vertcat(xdot, qdot) / S], names, ["ydot"],
                           {"custom_jacobian": jac, "jac_penalty": 0, "never_inline": True})
        self.S = np.asarray(S).ravel()
        tt, t0, t = ca.MX.sym("T"), ca.MX.sym("t0"), ca.MX.sym("t")  # T: duration (normalised time)
        pp = ca.vertcat(mode, tt, t0)
        arg = (lambda s: [y, mode, drive.function(t0 + s)]) if drive is not None else (lambda s: [y, mode])
        self._dae = {"x": y, "t": t, "p": pp, "ode": ydot(*arg(t))}
        self._dae_T = {"x": y, "t": t, "p": pp, "ode": tt * ydot(*arg(tt * t))}
        # BDF order capped at 3: the right-hand side is only piecewise smooth (port edges, valve
        # ramps, orifice branches), and orders 4-5 are rejected there anyway; measured on the EVP
        # pump-down: 2.5 % fewer steps, 5 % fewer error-test failures, time to target closer to a
        # rtol 1e-7 reference (0.41 ms vs 0.68 ms)
        self.opts = {"abstol": atol, "reltol": rtol, "max_num_steps": max_steps, "max_order": MAX_ORDER}
        self._grids = {}
        self._step = ca.integrator("step", "cvodes", self._dae_T, 0.0, [1.0], self.opts)
        self.stats = {k: 0 for k in STAT_KEYS}
        self.calls = 0
        self.integrator_wall = 0.0  # s inside CVODES calls (the rest of a run's wall is Python)
        self.integrator_cpu = 0.0  # CPU s of this process inside them
        self.direct = self._direct(rtol, atol, max_steps)
        self.driver = "cvodes (direct)" if self.direct else "cvodes (casadi)"

    def _direct(self, rtol, atol, max_steps):
        """The direct CVODES driver over pump_rhs / pump_rhs_jac (cvodes_driver), the same states
        (quadratures riding along) and per-component tolerances; None where it is not available."""
        if not cvodes_driver.available()[0]:
            return None
        self._pbuf = self.p.copy()
        rhs, jac, fj, attach = geometry_tables.driver_calls(self.kern, self.p, self._pbuf, self.nx, self.geometry_table)
        blocks = [(fj.sparsity_out(0), 0), (fj.sparsity_out(1), self.nx)]
        # the quadratures do not feed back: with their Jacobian rows zero, CVODES' Newton systems
        # are solved on the states' block alone (16 x 16 instead of 24 x 24 on the EVP example)
        quads_free = fj.sparsity_out(1).nnz() == 0
        d = cvodes_driver.Driver(self.nx + self.nq, rhs, [0, self.nx], jac, blocks, rtol, atol * self.S,
                                 max_order=MAX_ORDER, max_steps=max_steps, jac_every=JAC_EVERY,
                                 lin_size=self.nx if quads_free else None, keep_step=KEEP_STEP)
        self.driver_geometry = attach(d)
        if self.drive is not None:  # the voltage interpolated in C before every kernel call
            d.set_drive(self._pbuf, parameter_index(self.kern.structure, "motor.voltage"), self.drive.step,
                        self.drive.values, self.drive.stops)
        return d

    def _run_direct(self, touts, x, mode, start, clock):
        """(states, quadratures since `start`) at touts by the direct driver, carrying on without
        a restart when (start, x, mode) is where its last call ended; the drive's time is the
        solver's plus `clock`."""
        d = self.direct
        d.shift_drive(clock)
        if self._pbuf[self.mode_index] != mode:
            self._pbuf[self.mode_index] = mode
            d.last = None
        last = d.last
        if last is not None and last[0] == start and np.array_equal(last[1][:self.nx], x):
            y0 = last[1]
        else:
            y0 = np.concatenate([np.asarray(x, float), np.zeros(self.nq)])
        Y = d.run(start, y0, touts)
        self.stats.update(d.stats)
        if d.timed:
            self.stats.update(d.times())
        return Y[:, :self.nx].T, (Y[:, self.nx:] - y0[self.nx:]).T

    def p_at(self, t):
        """The kernel's parameter vector at time t (the drive's voltage put in)."""
        if self.drive is None:
            return self.p
        p = self.p.copy()
        p[parameter_index(self.kern.structure, "motor.voltage")] = float(self.drive(t))
        return p

    @contextmanager
    def _timed(self):
        """Wall and CPU time inside the integrator (the CPU time stays meaningful on a loaded
        machine)."""
        t0, c0 = _time.perf_counter(), _time.process_time()
        try:
            yield
        finally:
            self.integrator_wall += _time.perf_counter() - t0
            self.integrator_cpu += _time.process_time() - c0

    def _run(self, integ, x, mode, T=0.0, start=0.0, touts=None, clock=0.0):
        self.calls += 1
        if self.direct is not None:
            with self._timed(), interrupt.deferred():
                return self._run_direct(touts, x, mode, start, clock)
        y0 = np.concatenate([np.asarray(x, float), np.zeros(self.nq)]) / self.S
        try:
            with self._timed(), interrupt.deferred():
                r = integ(x0=y0, p=[mode, T, start])
        except RuntimeError as e:
            interrupt.check()  # a signal inside the integrator's callbacks
            raise SolverError(f"integrator failed: {str(e).strip().splitlines()[-1]}") from None
        st = integ.stats()
        for k, nm in STAT_KEYS.items():
            v = st.get(nm)
            if isinstance(v, (int, float)):
                self.stats[k] += int(v)
        Y = np.asarray(r["xf"]) * self.S[:, None]
        return Y[:self.nx], Y[self.nx:]

    def grid(self, x, mode, dt, m, start=0.0):
        """States and quadratures at start + dt, ..., start + m dt from x at `start`."""
        key = (dt, m)
        if self.direct is None and key not in self._grids:
            self._grids[key] = ca.integrator(f"g{m}", "cvodes", self._dae, 0.0,
                                             list(dt * np.arange(1, m + 1)), self.opts)
        X, Q = self._run(self._grids.get(key), x, mode, start=start, touts=start + dt * np.arange(1, m + 1))
        return X.T, Q.T

    def step(self, x, mode, d, start=0.0):
        """State and quadratures at start + d (the direct driver integrates on a local clock
        from 0, its drive shifted by `start`: a d of 1e-12 s is not 'too close' to a start at 5 s)."""
        if d <= 0:
            return np.asarray(x, float).copy(), np.zeros(self.nq)
        X, Q = self._run(self._step, x, mode, d, start if self.direct is None else 0.0, touts=np.array([d]),
                         clock=start)
        return X[:, 0], Q[:, 0]


def initial_state(cfg, kern, p, theta0=None, omega0=None, booster_start=None):
    """Everything at rest at gas.temperature: cells and exhaust port at the atmosphere, inlet
    manifold and booster at the booster's start pressure (booster_start, else the config's), reed
    seated."""
    st = kern.structure
    v = dict(zip([q for q in _names(st)], p))
    th = cfg.angle if theta0 is None else theta0
    om = cfg.speed if omega0 is None else omega0
    V = np.asarray(kern["cell_geometry"](th, p)[0]).ravel()
    R, g, T0 = v["gas.gas_constant"], v["gas.gamma"], v["gas.temperature"]
    pa = v["gas.atmosphere"]
    x = np.concatenate([[th, om, 0.0], pa * V / (R * T0), pa * V / (g - 1),
                        [0.0, pa * v["ports.exhaust_volume"] / (R * T0), 0.0,
                         0.0, pa * v["ports.exhaust_volume"] / (g - 1), 0.0, 0.0]])
    return at_booster_pressure(x, st, p, cfg.pneumatic.booster_start if booster_start is None else booster_start)


def at_booster_pressure(x, st, p, pressure):
    """x with the booster and the inlet manifold at `pressure` and gas.temperature (their masses,
    and the manifold's energy), for the volumes in p."""
    v = dict(zip(_names(st), p))
    R, g, T0 = v["gas.gas_constant"], v["gas.gamma"], v["gas.temperature"]
    i_in, nx = 3 + 2 * st.vanes, len(x)
    x = np.array(x, dtype=float)
    x[i_in] = pressure * v["ports.inlet_volume"] / (R * T0)
    x[i_in + 2] = pressure * v["booster.volume"] / (R * T0)
    x[nx - 4] = pressure * v["ports.inlet_volume"] / (g - 1)
    return x


def _names(st):
    from ..model_spec.parameters import pneumatic_layout

    return [q.name for q in pneumatic_layout(st)]


def state_scale(x0, p, st):
    """Nominal sizes for the absolute tolerance: masses and energies at their start values, the
    rotor angle 1 rad, speed 100 rad/s, current 1 A, reed lift its stop and rate stop x 1 kHz.
    (One mass scale for every cell and plenum -- the largest cell's charge -- was tried: 10 % fewer
    steps, but the time to target moved 2.5x further from a tight reference: the small charges,
    the exhaust port and the cell at the dead volume, need their own scale.)"""
    v = dict(zip(_names(st), p))
    sc = np.abs(np.asarray(x0, float)).copy()
    N = st.vanes
    sc[0], sc[1], sc[2] = 1.0, 100.0, 1.0
    sc[3:3 + 2 * N] = np.maximum(sc[3:3 + 2 * N], 1e-12)
    sc[3 + 2 * N:3 + 2 * N + 3] = np.maximum(sc[3 + 2 * N:3 + 2 * N + 3], 1e-12)
    sc[-4:-2] = np.maximum(sc[-4:-2], 1e-12)  # the manifold's and the exhaust port's energies
    lift = v["valve.lift_max"] if v["valve.reed"] > 0.5 else 1e-3
    sc[-2], sc[-1] = lift, lift * 1e3
    return sc


def evaluate_outputs(kern, X, p, names=None):
    """pump_outputs over the rows of X (n, nx): by the direct driver's row loop into NumPy arrays
    where it is available (the same compiled function, no map to make, no padding, no conversion
    of CasADi matrices), else CasADi's map, long runs in blocks of OUTPUT_BLOCK rows (the last
    one padded) so that one cached map serves every run (making a map costs ~0.1 s)."""
    f = kern["pump_outputs"]
    if cvodes_driver.available()[0]:
        return _outputs_by_rows(kern, f, X, p, names)
    n = X.shape[0]
    P = np.asarray(p).reshape(-1, 1)
    if n <= OUTPUT_BLOCK:
        res = [np.asarray(r) for r in kern.mapped("pump_outputs", n)(X.T, P)]
    else:
        fm = kern.mapped("pump_outputs", OUTPUT_BLOCK)
        parts = []
        for i in range(0, n, OUTPUT_BLOCK):
            B = X[i:i + OUTPUT_BLOCK]
            B = np.vstack([B, np.repeat(B[-1:], OUTPUT_BLOCK - len(B), axis=0)])
            parts.append([np.asarray(r)[:, :min(OUTPUT_BLOCK, n - i)] for r in fm(B.T, P)])
        res = [np.hstack(cols) for cols in zip(*parts)]
    out = {}
    for nm, a in zip(f.name_out(), res):
        if names is not None and nm not in names:
            continue
        out[nm] = a.ravel() if _per_sample(nm, a.shape[0], kern.structure.vanes == 1) else a.T  # per cell/vane: (n, N)
    return out


def _outputs_by_rows(kern, f, X, p, names):
    """evaluate_outputs through cvodes_driver's row loop: scalars (n,), vectors (n, size)."""
    call = cvodes_driver.KernelCall(cvodes_driver.kernel_library(kern), "pump_outputs",
                                    [np.zeros(f.size1_in(0)), np.asarray(p, float)], 0)
    sizes = [f.sparsity_out(k).numel() for k in range(f.n_out())]
    wanted = [names is None or nm in names for nm in f.name_out()]
    cols = call.rows(np.asarray(X, float).reshape(-1, f.size1_in(0)), sizes, wanted)
    one = kern.structure.vanes == 1
    return {nm: (a[:, 0] if _per_sample(nm, a.shape[1], one) else a) for nm, a, w in zip(f.name_out(), cols, wanted)
            if w}


def _per_sample(name, size, one_vane) -> bool:
    """An output of one value per sample: size 1 -- with one vane, only where the contract says
    so (a per-cell or per-vane output then has size 1 too and keeps its column)."""
    return size == 1 and (not one_vane or output_shape(name) == "sample")


def _reed_switch(kern, p, X, mode):
    """Switching functions of the reed in its current mode, per row of X."""
    o = evaluate_outputs(kern, X, p, ["reed_force"])
    lift = X[:, -2]
    if mode == REED_MODES["free"]:
        x_max = p[parameter_index(kern.structure, "valve.lift_max")]
        return np.stack([lift, x_max - lift], axis=1)
    return o["reed_force"][:, None]


def booster_pressure(st, p):
    """The booster pressure [Pa] of states X (..., n_x): its gas mass at the gas temperature."""
    ib = 3 + 2 * st.vanes + 2
    v_b = p[parameter_index(st, "booster.volume")]
    RT = p[parameter_index(st, "gas.gas_constant")] * p[parameter_index(st, "gas.temperature")]
    return lambda X: X[..., ib] * RT / v_b


@dataclass
class _Trace:
    """The output rows of a run: time, state, quadratures and valve mode (None: an event inside
    the interval before)."""

    times: list
    xs: list
    qs: list
    modes: list

    def add(self, t, x, q, mode):
        self.times.append(t)
        self.xs.append(x)
        self.qs.append(q)
        self.modes.append(mode)


def integrate(cfg, duration, rate, p=None, x0=None, until=None, rtol=GAS_RTOL, atol=GAS_ATOL,
              progress=None, max_steps=2_000_000, kern=None, scale=None, drive=None) -> PumpdownRun:
    """Integrate from x0 over `duration` on a uniform output grid at `rate`; stop early when the
    booster pressure falls to `until` (located to EVENT_TIME_TOL). kern, scale: another variant
    (Model 1 with gas) and its state scale; its p and x0 are then given. drive: the supply voltage
    (drive.VoltageDrive) in place of motor.voltage (PumpIntegrator)."""
    kern = kernels(cfg) if kern is None else kern
    p = parameter_vector(cfg) if p is None else np.asarray(p, float)
    st = kern.structure
    x0 = initial_state(cfg, kern, p) if x0 is None else np.asarray(x0, float)
    reed = p[parameter_index(st, "valve.reed")] > 0.5
    mode = float(p[parameter_index(st, "valve.mode")]) if reed else 0.0
    scale = state_scale(x0, p, st) if scale is None else scale
    integ = PumpIntegrator(kern, p, rtol, atol, scale, max_steps, drive)
    dt = 1.0 / rate
    n_total = int(math.floor(duration * rate + 1e-9))
    trace = _Trace([0.0], [x0], [np.zeros(integ.nq)], [mode])
    events = []
    t, x, q = 0.0, x0.copy(), np.zeros(integ.nq)
    p_booster = booster_pressure(st, p)
    t_target = None
    wall0 = _time.perf_counter()
    k = 0
    while k < n_total:
        m = min(CHUNK, n_total - k)
        X, Q = _grid(integ, x, mode, dt, m, t, p_booster)
        cut = _first_reed_switch(kern, p, x, X, mode) if reed else m
        stop_row = None
        if until is not None:
            below = np.nonzero(p_booster(X[:cut]) <= until)[0]
            if below.size:
                stop_row = int(below[0])
                cut = stop_row
        for r in range(cut):
            trace.add(t + (r + 1) * dt, X[r], q + Q[r], mode)
        if cut:
            t, x, q = t + cut * dt, X[cut - 1].copy(), q + Q[cut - 1]
            k += cut
        if stop_row is not None:  # locate the target crossing inside the next interval
            d = illinois(lambda d: p_booster(integ.step(x, mode, d, t)[0]) - until, 0.0, dt,
                          p_booster(x) - until, p_booster(X[stop_row]) - until, EVENT_TIME_TOL)
            xe, qe = integ.step(x, mode, d, t)
            t_target = t + d
            trace.add(t_target, xe, q + qe, mode)
            break
        if cut < m:  # a reed event inside [t, t + dt]
            x, q, mode = _reed_interval(integ, kern, p, x, q, mode, t, dt, events)
            t = t + dt
            k += 1
            trace.add(t, x.copy(), q.copy(), None)
        interrupt.progress(f"at simulated t = {t:.6g} s of {duration:.6g} s (booster {p_booster(x):.6g} Pa)", detail=True)
        if progress:
            progress(t, p_booster(x))
    return _finished(integ, kern, p, trace, events, t_target, wall0)


def _grid(integ, x, mode, dt, m, t, p_booster):
    """m output steps from (t, x); a failure names the interval and the state it started from."""
    try:
        return integ.grid(x, mode, dt, m, t)
    except SolverError as e:
        raise SolverError(f"the gas model's integration failed between t = {t:.6g} s and "
                          f"{t + m * dt:.6g} s (theta {x[0]:.6g} rad, omega {x[1]:.6g} rad/s, booster "
                          f"{p_booster(x):.6g} Pa): {e}") from None


def _finished(integ, kern, p, trace, events, t_target, wall0) -> PumpdownRun:
    X = np.array(trace.xs)
    stats = dict(integ.stats)
    stats.update(integrator_calls=integ.calls, events=len(events), driver=integ.driver, geometry=integ.driver_geometry,
                 wall_time=_time.perf_counter() - wall0, integrator_wall=integ.integrator_wall,
                 integrator_cpu=integ.integrator_cpu)
    outs = evaluate_outputs(kern, X, p)
    peak = peak_current(integ, np.array(trace.times), X, trace.modes)
    return PumpdownRun(np.array(trace.times), X, np.array(trace.qs), outs, stats, events, t_target, p, peak)


PEAK_SUBSTEP = 5e-5  # s: the grid an output interval is re-integrated on to find the current's peak


def peak_current(integ, times, X, modes) -> float:
    """|current| at its maximum, located between the output samples, however coarse they are:
    the first interval (the inrush of a start from rest) and the two beside the largest sample are
    re-integrated on a PEAK_SUBSTEP grid (a peak can lie anywhere inside a long interval, the
    inrush's within milliseconds of the start), and the largest sub-sample's bracket, where
    di/dt (the kernel's rate) changes sign, is closed by Illinois on re-integrations from the
    bracket's start, as the target is. The largest sample itself where nothing brackets (a maximum
    at the run's ends, a valve event inside the interval, constant speed)."""
    i = np.abs(X[:, 2])
    k = int(np.argmax(i))
    best = float(i[k])
    for a in sorted({0, k - 1, k}):
        if 0 <= a < len(X) - 1 and modes[a + 1] is not None:
            best = max(best, _interval_peak(integ, times[a], times[a + 1], X[a], modes[a + 1]))
    return best


def _interval_peak(integ, t_a, t_b, x_a, mode) -> float:
    """The largest |current| over [t_a, t_b] from x_a: on a sub-grid, then located (peak_current)."""
    m = max(1, int(math.ceil((t_b - t_a) / PEAK_SUBSTEP - 1e-9)))
    h = (t_b - t_a) / m
    # one sub-step: a step (a grid of one would make CasADi's plugin an integrator per length)
    after = integ.grid(x_a, mode, h, m, t_a)[0] if m > 1 else integ.step(x_a, mode, h, t_a)[0][None, :]
    Xs = np.vstack([x_a[None, :], after])
    cur = np.abs(Xs[:, 2])
    k = int(np.argmax(cur))
    sign = 1.0 if Xs[k, 2] >= 0 else -1.0
    rate = lambda x, t: sign * float(integ.kern["pump_rhs"](x, integ.p_at(t))[0][2])  # noqa: E731
    g_k = rate(Xs[k], t_a + k * h)
    j = k + 1 if g_k > 0 else k - 1  # the neighbour on the side the maximum lies
    if g_k == 0.0 or not 0 <= j < len(Xs):
        return float(cur[k])
    lo = min(j, k)
    g_lo, g_hi = (g_k, rate(Xs[j], t_a + j * h)) if lo == k else (rate(Xs[j], t_a + j * h), g_k)
    if not g_lo > 0 > g_hi:
        return float(cur[k])
    t_lo = t_a + lo * h
    root = illinois(lambda s: rate(integ.step(Xs[lo], mode, s, t_lo)[0], t_lo + s), 0.0, h, g_lo, g_hi,
                    EVENT_TIME_TOL)
    return max(float(cur[k]), abs(float(integ.step(Xs[lo], mode, root, t_lo)[0][2])))


def _first_reed_switch(kern, p, x, X, mode) -> int:
    """Row of the first output interval (from x to X[0], then between rows of X) in which a reed
    switch function changes sign; len(X) if none does."""
    g0 = _reed_switch(kern, p, x[None, :], mode)[0]
    G = _reed_switch(kern, p, X, mode)
    prev = np.vstack([g0[None, :], G[:-1]])
    changed = (np.sign(G) != np.sign(prev)) & (prev != 0.0)
    rows = np.nonzero(changed.any(axis=1))[0]
    return int(rows[0]) if rows.size else len(X)


def _reed_interval(integ, kern, p, x, q, mode, t, dt, events):
    """Integrate over [t, t + dt], which holds at least one reed switch: locate each switch in
    turn, change the mode there (the lift rate stops dead on seat and stop) and go on; returns
    (state, quadratures, mode) at t + dt."""
    lift_max = p[parameter_index(kern.structure, "valve.lift_max")]
    t_end = t + dt
    for _ in range(100):
        g0 = _reed_switch(kern, p, x[None, :], mode)[0]
        x1, q1 = integ.step(x, mode, t_end - t, t)
        g1 = _reed_switch(kern, p, x1[None, :], mode)[0]
        crossed = [i for i in range(g0.size) if np.sign(g1[i]) != np.sign(g0[i]) and g0[i] != 0.0]
        if not crossed:
            return x1, q + q1, mode
        roots = {i: illinois(lambda d, i=i: _reed_switch(kern, p, integ.step(x, mode, d, t)[0][None, :],
                                                             mode)[0][i],
                              0.0, t_end - t, g0[i], g1[i], EVENT_TIME_TOL) for i in crossed}
        i, d = min(roots.items(), key=lambda kv: kv[1])
        xe, qe = integ.step(x, mode, d, t)
        q = q + qe
        t = t + d
        x = xe.copy()
        if mode == REED_MODES["free"]:
            if i == 0:  # on the seat
                x[-2], x[-1], mode, kind = 0.0, 0.0, REED_MODES["seated"], "reed_closes"
            else:  # on the stop
                x[-2], x[-1], mode, kind = lift_max, 0.0, REED_MODES["stop"], "reed_stop"
        else:
            kind = "reed_opens" if mode == REED_MODES["seated"] else "reed_leaves_stop"
            mode = REED_MODES["free"]
            x[-1] = 0.0
        events.append({"time": float(t), "kind": kind})
        if t_end - t <= EVENT_TIME_TOL:
            return x, q, mode
    raise SolverError(f"reed valve chatters: 100 switches within {dt:.3g} s at t = {t:.6g} s")
