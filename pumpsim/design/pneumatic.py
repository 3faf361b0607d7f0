"""A design study of a config with the gas tables (spec §8): every output from the gas model's
periodic steady state with the booster held at one pressure (`pneumatics.pumpdown.pump_maps` and
`steady_revolution`). The drive torque then includes the gas torque and the vanes carry the gas
loads, so mean_torque, the friction powers and the vane forces are those of the pump pumping;
`gas_power`, `pumping_speed` and `mean_current` are the gas model's own outputs. (A study of the
mechanics alone runs on the config without its gas tables.)

Operating point: the booster held at `study.booster_pressure` (default: the config's
booster.pressure, the start of a pump-down). Drive:
- operation.mode = "motor": the motor sets the speed; a design's row carries the mean speed of its
  periodic steady state, and the mechanical outputs are evaluated at that speed (constant speed:
  Model 2's assumption; the motor's speed ripple is left out of them). study.speeds would
  contradict the motor and is refused when gas outputs are asked.
- operation.mode = "speed": one periodic steady state per speed; there is no motor, so
  mean_current is refused.
Definitions (means over MAP_REVOLUTIONS whole revolutions):
- gas_power      W     mean gas torque x mean speed: the power the shaft puts into the gas
- pumping_speed  m^3/s mass flow drawn from the booster / gas density at booster conditions
- mean_current   A     electrical energy / (supply voltage x time)
"""
from __future__ import annotations

import dataclasses

from ..errors import ConfigError

GAS_OUTPUTS = ("gas_power", "pumping_speed", "mean_current")


def check_gas_outputs(asked: list, cfg, speeds, model: str, booster_pressure) -> float | None:
    """Before any work: the gas outputs asked are computable for this base config and study.
    Returns the booster pressure of the operating point, or None when the gas model is not run
    (a config without the gas tables)."""
    gas = [o for o in asked if o in GAS_OUTPUTS]
    if cfg.pneumatic is None:
        if gas:
            raise ConfigError(f"study.outputs: {gas[0]} needs the gas model's tables in the config "
                              "([ports] and [booster], with [gas], [valve], [leak], [motor] as needed; spec §8)")
        if booster_pressure is not None:
            raise ConfigError("study.booster_pressure is the gas model's operating point; the config has "
                              "no gas tables ([ports], [booster])")
        return None
    gas = gas or ["the gas-loaded outputs"]
    if model != "constrained":
        raise ConfigError("study.model: a config with the gas tables is studied with the constrained "
                          "model's gas version (its outputs carry the gas loads); use study.model = "
                          "\"constrained\", or the config without its gas tables for the mechanics alone")
    motor = cfg.pneumatic.motor
    if motor and speeds is not None:
        raise ConfigError(f"study.speeds: the config drives the pump with its motor (operation.mode = "
                          f"\"motor\"), which sets the speed {gas[0]} is computed at; omit study.speeds "
                          "or use operation.mode = \"speed\"")
    if not motor and "mean_current" in gas:
        raise ConfigError("study.outputs: mean_current needs a motor (operation.mode = \"motor\" and "
                          "[motor]); the config runs at a given speed")
    pb = cfg.pneumatic.booster_start if booster_pressure is None else booster_pressure
    if isinstance(pb, bool) or not isinstance(pb, (int, float)) or not 0 < pb <= 1e7:
        raise ConfigError(f"study.booster_pressure must be a pressure in (0, 1e7] Pa, got {pb!r}")
    return float(pb)


def motor_driven(study, cfg) -> bool:
    """The rows' speed comes from the motor (a motor-driven config without study.speeds)."""
    return study.booster_pressure is not None and cfg.pneumatic is not None and cfg.pneumatic.motor


def gas_outputs(cfg, booster_pressure: float, speed: float | None = None,
                angles=None, names=None) -> tuple[float, dict, dict | None]:
    """(mean speed [rad/s], {gas output: value}, revolution) of one design in periodic steady
    state with the booster at booster_pressure; speed: the constant speed (speed mode), None under
    the motor. revolution: the gas model's outputs `names` at the rotor angles `angles` (one
    revolution; per vane as (N, n), like the mechanical kernel's), None without angles."""
    from ..pneumatics.pumpdown import pump_maps, steady_revolution

    if speed is not None:
        cfg = dataclasses.replace(cfg, mode="speed", speed=float(speed))
    m = pump_maps(cfg, [booster_pressure])
    w = float(m.speed[0])
    out = {"gas_power": float(m.gas_torque[0]) * w, "pumping_speed": float(m.pumping_speed[0])}
    if cfg.pneumatic.motor:
        out["mean_current"] = float(m.current[0])
    if angles is None:
        return w, out, None
    rev = steady_revolution(cfg, m, 0, angles, names)
    return w, out, {nm: (a if a.ndim == 1 else a.T) for nm, a in rev.items()}


__all__ = ["GAS_OUTPUTS", "check_gas_outputs", "gas_outputs", "motor_driven"]
