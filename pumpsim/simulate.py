"""`simulate`: one entry point for every model variant -- the constrained model (Model 2) or the
contact model (Model 1), each with or without the gas tables (spec §8)."""
from __future__ import annotations

from .config import PumpConfig
from .errors import ConfigError
from .result import SimulationResult
from .tolerances import ATOL, RTOL


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
        raise ConfigError(f"max_step must be > 0, got {max_step:g}")
    if model == "contact":
        from .contact import simulate_contact

        return simulate_contact(cfg, duration=duration, rate=rate, method=method, rtol=rtol,
                                atol=atol, max_step=max_step, progress=progress,
                                max_steps=max_steps, **options)
    if model != "constrained":
        raise ConfigError(f"model must be 'constrained' or 'contact', got '{model}'")
    if options:
        raise ConfigError(f"option(s) {', '.join(options)} are for the contact model (model='contact')")
    from .constrained import simulate_constrained

    return simulate_constrained(cfg, duration, rate, method, rtol, atol, max_step, progress, max_steps)


def _simulate_gas(cfg, model, max_step, options, **run):
    """simulate() on a config with the spec §8 gas tables: Model 2 (pneumatics.simulate) or Model 1
    (pneumatics.contact) with the gas; `run` holds duration, rate, method, rtol, atol, progress,
    max_steps."""
    if max_step is not None:
        raise ConfigError(f"max_step {max_step:g}: the gas model (the config's spec §8 tables) takes "
                          "CVODES's own steps; tighten rtol/atol instead")
    if model == "contact":
        from .pneumatics.contact import simulate as simulate_gas_contact

        return simulate_gas_contact(cfg, **run, **options)
    if model != "constrained":
        raise ConfigError(f"model must be 'constrained' or 'contact', got '{model}'")
    if options:
        raise ConfigError(f"option(s) {', '.join(options)} are for the contact model (model='contact')")
    from .pneumatics.simulate import simulate as simulate_gas

    return simulate_gas(cfg, **run)
