"""Simulation of the constrained model (Model 2) without the gas tables: inverse dynamics at a
prescribed speed, or theta and omega integrated under an applied torque. `pumpsim.simulate` is
the entry point that checks the options and picks the model."""
from __future__ import annotations

import math

import numpy as np

from .config import PumpConfig, as_array
from .contact import state_bounds
from .errors import SolverError
from .integrate import Integrator, integrate_segmented
from .kernels import evaluate, load_kernels, sampled_inverse_dynamics
from .model_spec.parameters import FRICTION_KEYS
from .motion import sample_times, speed_profile
from .result import PER_VANE_COLUMNS, REPORTED, LazyOutputs, SimulationResult, contact_warnings
from .tolerances import POSITION_TOL


def simulate_constrained(cfg: PumpConfig, duration, rate, method, rtol, atol, max_step, progress,
                         max_steps) -> SimulationResult:
    """Model 2 over `duration` at `rate` (options already checked by `pumpsim.simulate`)."""
    pv = cfg.parameters("constrained")
    kern = load_kernels(pv.structure)
    p = as_array(pv)
    if duration is None:
        duration = 2 * 2 * math.pi / cfg.speed if cfg.mode == "speed" else 0.5
    t = sample_times(duration, rate)
    warnings, events, stats = [], [], {}
    if cfg.mode == "speed":
        theta, omega, omegadot = speed_profile(cfg.angle, cfg.speed, t, cfg.speed_ripple)
        out = sampled_inverse_dynamics(kern, p, theta, omega, omegadot, ("torque", *REPORTED))
        torque = out["torque"]

        def more(names):  # every other output, on first use
            return sampled_inverse_dynamics(kern, p, theta, omega, omegadot, names)
    else:
        theta, omega, torque, out, stats, ev = _torque_drive(kern, p, cfg, t, method, rtol, atol,
                                                             max_step, progress, max_steps)
        events.extend(ev)
        more = None  # forward dynamics evaluated every output already
    _check_positions(out, t)
    contact_warnings(out, t, warnings, events, lift_off=True)
    vanes = {c: out[c] for c in PER_VANE_COLUMNS}
    extra = LazyOutputs(out, more, kern["inverse_dynamics"].name_out())
    return SimulationResult("constrained", cfg.mode, t, theta, omega, torque, vanes, dict(pv.values),
                            stats, events, warnings, extra=extra, kernel_key=kern.key,
                            config_name=cfg.name)


def _check_positions(out, time):
    """The position solve must have closed the contact (Model 2): a numerical failure otherwise."""
    res = out["position_residual"]
    if np.nanmax(res) > POSITION_TOL or not np.all(np.isfinite(res)):
        k = int(np.nanargmax(np.where(np.isfinite(res), res, np.inf).max(axis=0)))
        raise SolverError(f"position problem did not converge at t = {time[k]:.6g} s "
                          f"(residual {np.nanmax(res):.3g} m)")


def switching_functions(kern, p, torque, friction_on):
    """Signs whose change is a kink in the equations: friction directions and contact sides
    (and the housing reaction, whose sign change is a would-be lift-off)."""

    def g(X):
        n = X.shape[0]
        d = evaluate(kern, "forward_dynamics", [X[:, 0], X[:, 1], np.full(n, torque)], p, n)
        parts = [d["normal"]]
        if friction_on:
            parts += [d["sdot"], d["slot1"], d["slot2"], d["tip_slip"]]
        return np.vstack(parts).T

    return g


def _torque_drive(kern, p, cfg, t, method, rtol, atol, max_step, progress, max_steps):
    torque = float(cfg.torque)
    ode = kern["ode_rhs"]
    npar = p.size

    def rhs(x, pp):
        return ode(x, pp[npar], pp[:npar])

    bounds, names = state_bounds(cfg, vanes=False)
    integ = Integrator(rhs, 2, np.concatenate([p, [torque]]), t[1] - t[0], method=method, rtol=rtol,
                       atol=atol, max_step=max_step, max_steps=max_steps, bounds=bounds, names=names)
    v = dict(zip(cfg.parameters().names, p))
    friction_on = any(v[f"friction.{s}.{k}"] > 0 for s in ("housing", "slot") for k in FRICTION_KEYS[:2])
    gfun = switching_functions(kern, p, torque, friction_on)
    x0 = np.array([cfg.angle, cfg.speed])
    xs, ev, stats = integrate_segmented(integ, x0, t, switch_fn=gfun, progress=progress)
    theta, omega = xs[:, 0], xs[:, 1]
    out = evaluate(kern, "forward_dynamics", [theta, omega, np.full_like(t, torque)], p, t.size)
    if np.nanmax(np.abs(out["torque_residual"])) > 1e-9 * max(1.0, abs(torque)) * 1e3:
        k = int(np.nanargmax(np.abs(out["torque_residual"])))
        raise SolverError(f"forward dynamics did not converge at t = {t[k]:.6g} s "
                          f"(theta {theta[k]:.6g} rad, omega {omega[k]:.6g} rad/s)")
    N = kern.structure.vanes
    names = ["normal"] + (["sdot", "slot1", "slot2", "tip_slip"] if friction_on else [])
    events = [{"time": float(te), "kind": f"switch_{names[i // N]}", "vane": int(i % N),
               "message": f"{names[i // N]} of vane {i % N} changes sign"} for te, i in ev]
    return theta, omega, np.full_like(t, torque), out, stats, events
