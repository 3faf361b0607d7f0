"""Simulation of the constrained model (Model 2), by prescribed speed or applied torque."""
from __future__ import annotations

import math

import numpy as np

from .config import PumpConfig, as_array
from .errors import ConfigError, SolverError
from .integrate import Integrator, integrate_segmented
from .kernels import FAST_THREADED, default_threads, fast_kernel, load_kernels
from .model_spec import outputs as kernel_outputs
from .model_spec.parameters import FRICTION_KEYS
from .result import PER_VANE_COLUMNS, REPORTED, LazyOutputs, SimulationResult, contact_warnings
from .tolerances import ATOL, POSITION_TOL, RTOL

CHUNK = 20000  # samples per kernel call


def _per_vane(arr, n_vanes):
    """Mapped kernel output (1, n_vanes * n) -> (n_vanes, n)."""
    return np.asarray(arr).reshape(n_vanes, -1, order="F")


def _shaped(name, arr, n_vanes):
    """A mapped output in the shape the contract declares for it."""
    kind = kernel_outputs.shape(name)
    if kind == "sample":
        return arr.ravel()
    if kind == "vane":
        return _per_vane(arr, n_vanes)
    raise ValueError(f"kernel output '{name}' ({kind}) is not a per-sample or per-vane output")


def evaluate(kern, name, samples, p, n, outputs=None):
    """Evaluate a compiled function over n samples: `samples` are scalars or length-n arrays (one
    per leading input), `p` the parameter vector shared by all samples (the last input).
    `outputs`: the names to return (default all; converting is a good part of a short call)."""
    outs = None
    names = kern[name].name_out()
    keep = [i for i, nm in enumerate(names) if outputs is None or nm in outputs]
    pcol = np.asarray(p, dtype=float).reshape(-1, 1)
    for lo in range(0, n, CHUNK):
        hi = min(n, lo + CHUNK)
        call = []
        for a in samples:
            a = np.asarray(a, dtype=float)
            # 1-D: one value per sample; 2-D (k, n): a k-vector per sample; 0-D: shared
            call.append(a[lo:hi][None, :] if a.ndim == 1 else (a[:, lo:hi] if a.ndim == 2 else a))
        res = kern.mapped(name, hi - lo)(*call, pcol)
        res = res if isinstance(res, (list, tuple)) else [res]
        res = [np.asarray(res[i]) for i in keep]
        outs = res if outs is None else [np.concatenate([o, r], axis=1) for o, r in zip(outs, res)]
    N = kern.structure.vanes
    return {names[i]: _shaped(names[i], o, N) for i, o in zip(keep, outs)}


def inverse_dynamics(kern, p, theta, omega, omegadot, outputs=None):
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    n = theta.size
    omega = np.broadcast_to(np.asarray(omega, dtype=float), (n,)).copy()
    omegadot = np.broadcast_to(np.asarray(omegadot, dtype=float), (n,)).copy()
    return evaluate(kern, "inverse_dynamics", [theta, omega, omegadot], p, n, outputs)


def sampled_inverse_dynamics(kern, p, theta, omega, omegadot, outputs=None) -> dict:
    """inverse_dynamics through the fastest kernel this machine has: for a constrained variant the
    SIMD library (pumpsim.fastkernel; the entry point that computes only `outputs`, written into
    one buffer, split over threads from FAST_THREADED samples), else the CasADi map. The same
    names and shapes; the same numbers to ~1e-14 of each output's scale."""
    fast = fast_kernel(kern.structure)
    if fast is None:
        return inverse_dynamics(kern, p, theta, omega, omegadot, outputs)
    threads = default_threads() if np.size(theta) >= FAST_THREADED else 1
    return fast(theta, omega, omegadot, p, outputs=outputs, threads=threads)


def sample_times(duration, rate):
    if duration is None or not 0 < duration < math.inf:
        raise ConfigError(f"--duration must be > 0 and finite, got {duration}")
    if rate is None or not 0 < rate < math.inf:
        raise ConfigError(f"--rate must be > 0 and finite, got {rate}")
    n = int(math.floor(duration * rate + 1e-9)) + 1
    if n < 2:
        raise ConfigError(f"--duration {duration:g} s at --rate {rate:g} Hz gives fewer than 2 samples")
    if n > 5_000_000:
        raise ConfigError(f"--duration x --rate gives {n} samples; the limit is 5,000,000")
    return np.arange(n) / rate


def ripple_motion(theta_n, theta_start, omega0, rc, rs, k, lib=np):
    """Rotor angle, speed and acceleration under a shaft-order-k speed ripple, as functions of the
    nominal angle theta_n (= theta_start at the start): omega = omega0 (1 + rc cos(k theta_n) -
    rs sin(k theta_n)) -- rc = A cos(phase), rs = A sin(phase) -- and theta its exact integral from
    theta_start. lib: numpy, or casadi for symbolic arguments (simulation, fits and their graphs
    share this one formula)."""
    c, s = lib.cos(k * theta_n), lib.sin(k * theta_n)
    theta = theta_n + (rc * (s - lib.sin(k * theta_start)) + rs * (c - lib.cos(k * theta_start))) / k
    return theta, omega0 * (1 + rc * c - rs * s), -k * omega0**2 * (rc * s + rs * c)


def speed_profile(theta0, speed, t, ripple=None):
    """Prescribed rotor angle, speed and acceleration; ripple = (k, A, phase) gives
    omega = speed (1 + A cos(k theta_n + phase)) with theta_n = theta0 + speed t."""
    theta_n = theta0 + speed * t
    if not ripple or ripple[1] == 0:
        return theta_n, np.full_like(t, speed), np.zeros_like(t)
    k, A, phase = ripple
    return ripple_motion(theta_n, theta0, speed, A * math.cos(phase), A * math.sin(phase), k)


def _check_positions(out, time):
    """The position solve must have closed the contact (Model 2): a numerical failure otherwise."""
    res = out["position_residual"]
    if np.nanmax(res) > POSITION_TOL or not np.all(np.isfinite(res)):
        k = int(np.nanargmax(np.where(np.isfinite(res), res, np.inf).max(axis=0)))
        raise SolverError(f"position problem did not converge at t = {time[k]:.6g} s "
                          f"(residual {np.nanmax(res):.3g} m)")


def simulate(cfg: PumpConfig, model: str = "constrained", duration: float | None = None,
             rate: float = 10000.0, method: str = "cvodes", rtol: float = RTOL, atol: float = ATOL,
             max_step: float | None = None, progress=None, max_steps: int = 500000,
             **options) -> SimulationResult:
    """Simulate a pump configuration.

    Speed drive (operation.mode = "speed"): inverse dynamics at the prescribed speed, no
    integration. Torque drive: theta and omega integrated; vane positions follow from theta exactly.

    Parameters: cfg (PumpConfig, from `load_config`); model "constrained" (Model 2, the tip on the
    housing) or "contact" (Model 1, penalty contacts); duration [s] (default two revolutions at
    the configured speed, 0.5 s for a torque drive); rate: output samples per second [Hz];
    method "cvodes", "idas" or "rk" (explicit RK4, fixed step max_step, default 1e-6 s); rtol,
    atol: tolerances in (0, 1) (atol for positions [rad, m]); max_step [s]; progress:
    callable(simulated time); max_steps per integrator call; initial (contact model): "bottom",
    "rotor" or "housing". A numerical failure raises SolverError naming the time and the state.

    Returns a SimulationResult: columns by name (`res["torque"]`, `res["s_0"]`), `summary()`,
    `to_csv(path)`, `plot(path)`, `stats`, `events`, `warnings`.

    Example::

        cfg = pumpsim.load_config("examples/ellipse_4vanes.toml")
        res = pumpsim.simulate(cfg, duration=0.05, rate=20000)
        print(res.summary())
    """
    if cfg.pneumatic is not None:  # spec §8 tables: the gas-coupled model
        return _simulate_gas(cfg, model, max_step, options, duration=duration, rate=rate, method=method,
                             rtol=rtol, atol=atol, progress=progress, max_steps=max_steps)
    for name, val in (("rtol", rtol), ("atol", atol)):
        if not 0 < val < 1:
            raise ConfigError(f"--{name} must be in (0, 1), got {val:g}")
    if max_step is not None and not max_step > 0:
        raise ConfigError(f"--max-step must be > 0, got {max_step:g}")
    if model == "contact":
        from .contact import simulate_contact

        return simulate_contact(cfg, duration=duration, rate=rate, method=method, rtol=rtol,
                                atol=atol, max_step=max_step, progress=progress,
                                max_steps=max_steps, **options)
    if model != "constrained":
        raise ConfigError(f"--model must be 'constrained' or 'contact', got '{model}'")
    if options:
        raise ConfigError(f"option(s) {', '.join(options)} are for the contact model (--model contact)")
    pv = cfg.parameters("constrained")
    kern = load_kernels(pv.structure)
    p = as_array(pv)
    if duration is None:
        duration = 2 * 2 * math.pi / cfg.speed if cfg.mode == "speed" else 0.5
    t = sample_times(duration, rate)
    warnings, events, stats = [], [], {}
    N = cfg.vanes
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


def _simulate_gas(cfg, model, max_step, options, **run):
    """simulate() on a config with the spec §8 gas tables: Model 2 (pneumatics.simulate) or Model 1
    (pneumatics.contact) with the gas; `run` holds duration, rate, method, rtol, atol, progress,
    max_steps."""
    if max_step is not None:
        raise ConfigError(f"--max-step {max_step:g}: the gas model (the config's spec §8 tables) takes "
                          "CVODES's own steps; tighten --rtol/--atol instead")
    if model == "contact":
        from .pneumatics.contact import simulate as simulate_gas_contact

        return simulate_gas_contact(cfg, **run, **options)
    if model != "constrained":
        raise ConfigError(f"--model must be 'constrained' or 'contact', got '{model}'")
    if options:
        raise ConfigError(f"option(s) {', '.join(options)} are for the contact model (--model contact)")
    from .pneumatics.simulate import simulate as simulate_gas

    return simulate_gas(cfg, **run)


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

    from .contact import state_bounds

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
