"""Simulation of the contact model (Model 1): every vane moves on its own (s_i, sdot_i)."""
from __future__ import annotations

import math
import time as _time
from types import SimpleNamespace

import casadi as ca
import numpy as np

from . import cvodes_driver, interrupt
from .config import PumpConfig, as_array
from .errors import ConfigError, SolverError
from .integrate import Integrator, integrate_segmented
from .kernels import evaluate, load_kernels
from .motion import sample_times
from .result import LazyOutputs, SimulationResult, contact_warnings
from .tolerances import ATOL, RK_MAX_STEP, RTOL

INITIAL_STATES = ("bottom", "rotor", "housing")
# a penetration or slot position this small [m] is a rounding zero (lengths ~1e-2 m carry ~1e-18 m):
# a vane started on the housing at Model 2's position is touching, not crossing (|delta| ~ 1e-50)
TOUCHING = 1e-15
# what a contact simulation evaluates up front: the spec columns and what the warnings read
CONTACT_REPORTED = ("torque", "normal", "slot1", "slot2", "penetration", "n_consistent", "ambiguity")


def initial_state(kern, p, cfg, initial):
    N = cfg.vanes
    th0, w0 = cfg.angle, cfg.speed
    s_c, sd_c, _ = (np.asarray(v).ravel() for v in kern["constrained_state"](th0, w0, p))
    if initial == "bottom":
        s0, sd0 = np.zeros(N), np.zeros(N)
    elif initial == "rotor":  # on its Model 2 position, carried by the rotor (no sliding yet)
        s0, sd0 = s_c, np.zeros(N)
    elif initial == "housing":  # Model 2 position and velocity
        s0, sd0 = s_c, sd_c
    else:
        raise ConfigError(f"initial vane state must be one of {', '.join(INITIAL_STATES)}, got '{initial}'")
    return np.concatenate([[th0, w0], s0, sd0])


def ode_with_jacobian(kern, name, p) -> ca.Function:
    """xdot(x, drive) of the compiled ODE `name` with the parameters fixed, carrying the compiled
    Jacobian (<name>_jac) as its own: CasADi cannot see inside a compiled function and would
    otherwise differentiate the whole ODE once per state colour (and in p)."""
    f, fj = kern[name], kern[name + "_jac"]
    x, d, out = ca.MX.sym("x", f.size1_in(0)), ca.MX.sym("drive"), ca.MX.sym("out_xdot", f.size1_out(0))
    P = ca.DM(p)
    jac = ca.Function("jac_xdot", [x, d, out], list(fj(x, d, P)), ["x", "drive", "out_xdot"],
                      ["jac_xdot_x", "jac_xdot_drive"])
    return ca.Function("xdot", [x, d], [f(x, d, P)], ["x", "drive"], ["xdot"],
                       {"custom_jacobian": jac, "jac_penalty": 0})


def direct_driver(kern, name, dyn, drive, p):
    """A builder of the direct CVODES driver over the compiled ODE `name`(x, drive, p) and its
    Jacobian `name`_jac (for Integrator's `direct`), with the contact-state switches (report
    Table 1: each vane's housing penetration from `dyn`, then its slot position s_i) located by
    CVODES."""

    def build(rtol, atol, max_steps, max_step):
        x, d, pv = np.zeros(kern[name].size1_in(0)), np.array([drive], float), np.asarray(p, float).copy()
        rhs, jac = cvodes_driver.rhs_and_jacobian(kern, name, [x, d, pv])
        blocks = [(kern[name + "_jac"].sparsity_out(0), 0), None]  # d xdot / dx; not d / d drive
        drv = cvodes_driver.Driver(x.size, rhs, [0], jac, blocks, rtol, atol, max_steps=max_steps,
                                   max_step=max_step)
        N = (x.size - 2) // 2
        # dyn(theta, omega, drive, s, sdot, p): the state's pieces at slots 0, 1, 3, 4
        g = cvodes_driver.KernelCall(cvodes_driver.kernel_library(kern), dyn, [x[:1], x[1:2], d, x[2:2 + N], x[2 + N:], pv], 0)
        drv.set_roots(g, [0, 1, 3, 4], [0, 1, 2, 2 + N], kern[dyn].name_out().index("penetration"), N,
                      list(range(2, 2 + N)), TOUCHING)
        return drv

    return build


def state_scale(cfg) -> np.ndarray:
    """Nominal sizes of (theta, omega, s_i, sdot_i) for the absolute tolerance: atol for positions
    (rad, m), atol * omega_0 for speeds (rad/s, m/s) -- a speed error counts as the position error
    it makes while the rotor turns one radian (1 rad/s from rest). Where a vane velocity passes
    zero the absolute tolerance alone decides the step."""
    w = abs(cfg.speed) if cfg.speed else 1.0
    N = cfg.vanes
    return np.concatenate([[1.0, w], np.ones(N), np.full(N, w)])


# A surface speed no pump reaches (10x the plausibility limit of a vane tip): beyond it a state is
# a numerical divergence, not physics.
MAX_SURFACE_SPEED = 1000.0  # m/s


def state_bounds(cfg, vanes: bool = True):
    """Physically possible ranges of (theta, omega[, s_i, sdot_i]): the rotor's surface and a vane
    slower than MAX_SURFACE_SPEED, a vane no deeper than its length below the slot bottom and no
    further out than the housing's diameter. Outside them a run has diverged (integrate.py)."""
    v = cfg.values
    size = max(v["housing.a"], v["housing.b"])
    w_max = MAX_SURFACE_SPEED / size
    lo, hi = [-np.inf, -w_max], [np.inf, w_max]
    names = ["theta", "omega"]
    if vanes:
        N = cfg.vanes
        lo += [-v["vane.length"]] * N + [-MAX_SURFACE_SPEED] * N
        hi += [2 * size] * N + [MAX_SURFACE_SPEED] * N
        names += [f"s_{i}" for i in range(N)] + [f"sdot_{i}" for i in range(N)]
    return (np.array(lo), np.array(hi)), names


def contact_states(penetration, s) -> list[str]:
    """Report Table 1: in contact with the housing, on the slot bottom, or free."""
    return ["on the housing" if d > 0 else ("on the slot bottom" if si < 0 else "free")
            for d, si in zip(penetration, s)]


def simulate_contact(cfg: PumpConfig, duration=None, rate=10000.0, method="cvodes", rtol=RTOL,
                     atol=ATOL, max_step=None, progress=None, initial=None, max_steps=500000,
                     **unknown) -> SimulationResult:
    if unknown:
        raise ConfigError(f"unknown simulate option(s): {', '.join(unknown)}")
    if not cfg.contact_given:
        raise ConfigError("the contact model needs [contact.housing] with a stiffness in the config")
    initial = initial or cfg.initial_vane_state or "rotor"
    pv = cfg.parameters("contact")
    kern = load_kernels(pv.structure)
    p = as_array(pv)
    if duration is None:
        duration = 2 * 2 * math.pi / cfg.speed if cfg.mode == "speed" and cfg.speed > 0 else 0.5
    t = sample_times(duration, rate)
    x0 = initial_state(kern, p, cfg, initial)
    if cfg.mode == "speed":
        ode, dyn, drive = "ode_speed", "contact_dynamics", 0.0
    else:
        ode, dyn, drive = "ode_torque", "contact_forward", float(cfg.torque)
    dt = t[1] - t[0]
    if method == "rk":  # explicit: fixed substeps no longer than max_step
        max_step = max_step or RK_MAX_STEP
    rk_steps = max(1, int(math.ceil(dt / max_step))) if method == "rk" else 1
    xdot = ode_with_jacobian(kern, ode, p)
    bounds, state_names = state_bounds(cfg)
    integ = Integrator(lambda x, pp: xdot(x, pp[0]), 2 + 2 * cfg.vanes, [drive], dt, method=method,
                       rtol=rtol, atol=atol, max_step=max_step, rk_steps=rk_steps,
                       max_steps=max_steps, scale=state_scale(cfg), bounds=bounds, names=state_names,
                       direct=direct_driver(kern, ode, dyn, drive, p))
    run = _integrate(integ, kern, dyn, drive, p, x0, t, cfg.vanes, progress)
    run.stats["method"] = method
    res = _result(cfg, kern, dyn, drive, p, pv.values, run)
    if run.failure is not None:
        run.failure.partial = res
        raise run.failure
    return res


def _integrate(integ, kern, dyn, drive, p, x0, t, N, progress) -> SimpleNamespace:
    """Integrate over the sample grid, locating contact-state changes; on an integrator failure
    keep what was computed and a message naming every vane's contact state (on an interruption,
    what was computed)."""

    def switches(X):
        """Contact-state changes (report Table 1): housing penetration and slot-bottom contact.
        Friction-direction and contact-side kinks are continuous and left to error control."""
        g = np.hstack([_grid(kern, dyn, X, drive, p, ["penetration"])["penetration"].T, X[:, 2:2 + N]])
        return np.where(np.abs(g) < TOUCHING, 0.0, g)

    dt = t[1] - t[0]
    step_log = []

    def on_chunk(t_end, intervals, steps):
        step_log.append((t_end, intervals * dt / max(steps, 1)))

    wall0 = _time.perf_counter()
    try:
        xs, ev, stats = integrate_segmented(integ, x0, t, switch_fn=switches, on_chunk=on_chunk,
                                            progress=progress)
        termination, failure = "completed", None
    except SolverError as e:
        tt, xx = e.partial
        o = _grid(kern, dyn, xx[-1:], drive, p)
        states = ", ".join(f"vane {i} {st}" for i, st in
                           enumerate(contact_states(o["penetration"][:, -1], xx[-1][2:2 + N])))
        failure = SolverError(f"{e} -- contact states at t = {tt[-1]:.9g} s: {states}")
        t, xs, ev = tt, xx, []
        stats = dict(integ.stats)
        termination = f"failed after t = {t[-1]:.9g} s"
    except interrupt.Interrupted as e:  # the samples before it make a result of their own
        failure, (t, xs), ev = e, e.partial, []
        stats = dict(integ.stats)
        termination = f"interrupted after t = {t[-1]:.9g} s"
    stats["wall_time"] = _time.perf_counter() - wall0
    return SimpleNamespace(t=t, xs=xs, ev=ev, stats=stats, termination=termination, failure=failure,
                           step_log=step_log)


def _result(cfg, kern, dyn, drive, p, values, run) -> SimulationResult:
    t, xs, N = run.t, run.xs, cfg.vanes
    out = _grid(kern, dyn, xs, drive, p, CONTACT_REPORTED)
    names = ["housing_contact", "bottom_contact"]
    events = [{"time": float(te), "kind": names[i // N], "vane": int(i % N),
               "message": f"{names[i // N]} of vane {i % N} changes"} for te, i in run.ev]
    warnings = []
    contact_warnings(out, t, warnings)
    vanes = {"s": xs[:, 2:2 + N].T, "sdot": xs[:, 2 + N:].T, "normal": out["normal"],
             "slot1": out["slot1"], "slot2": out["slot2"], "penetration": out["penetration"]}
    torque = out["torque"] if cfg.mode == "speed" else np.full_like(t, drive)
    # every other output on first use; the integrator's mean step per output chunk now
    extra = LazyOutputs(out, lambda names: _grid(kern, dyn, xs, drive, p, names), kern[dyn].name_out())
    extra["step_time"] = np.array([s[0] for s in run.step_log])
    extra["step"] = np.array([s[1] for s in run.step_log])
    return SimulationResult("contact", cfg.mode, t, xs[:, 0], xs[:, 1], torque, vanes, dict(values),
                            run.stats, events, warnings, run.termination, extra, kernel_key=kern.key,
                            config_name=cfg.name)


def _grid(kern, name, xs, drive, p, outputs=None):
    N = kern.structure.vanes
    n = xs.shape[0]
    samples = [xs[:, 0], xs[:, 1], np.full(n, drive)]
    # per-vane vector inputs (s, sdot) are N-by-1 per sample: stack as N rows of n columns
    return evaluate(kern, name, samples + [xs[:, 2:2 + N].T, xs[:, 2 + N:].T], p, n, outputs)
