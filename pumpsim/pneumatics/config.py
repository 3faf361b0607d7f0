"""Configuration of the pneumatic model (spec §8): the [gas], [ports], [valve], [leak], [booster]
and [motor] tables, rotor.width and vane.slot_pressure. Validated like the rest: every rejection
names the key path and the limit, before any work starts.

Defaults are those of a small automotive vane pump (see examples/evp_booster.toml for the reasons).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..errors import ConfigError
from ..model_spec.parameters import (GAS_CONFIG_KEYS, GAS_ENCODED, GAS_PARAMETERS, SLOT_SOURCES,
                                      VALVE_TYPES, derive)

TABLES = ("gas", "ports", "valve", "leak", "booster", "motor")


_GAS = {q.name: q for q in GAS_PARAMETERS}
# A booster start or target below this is below any vane pump's ultimate pressure (~5-10 kPa): a
# value in kPa (also plausibility's limit)
MIN_BOOSTER_PRESSURE = 1.0e3  # Pa


def _num(default=None, required=False):
    return ("num", required, default)


SCHEMA = {
    "gas": {"gas_constant": _num(287.05), "gamma": _num(1.4), "temperature": _num(293.15),
            "wall_temperature": _num(None), "heat_transfer": _num(0.0), "atmosphere": _num(101325.0)},
    "ports": {"inlet": ("list", False, None), "exhaust": ("list", False, None),
              "width": _num(None), "inlet_width": _num(None), "exhaust_width": _num(None),
              "discharge_coefficient": _num(_GAS["ports.discharge_coefficient"].default),
              "hose_discharge_coefficient": _num(None), "check_discharge_coefficient": _num(None),
              "inlet_volume": _num(2.0e-6), "exhaust_volume": _num(2.0e-7),
              "hose_diameter": _num(4.0e-3), "check_cracking": _num(0.0), "check_full_open": _num(500.0)},
    "valve": {"type": ("str", False, "check"), "area": _num(None), "cracking": _num(0.0),
              "full_open": _num(2000.0), "mass": _num(None), "stiffness": _num(None),
              "damping": _num(0.0), "preload": _num(0.0), "lift_max": _num(None),
              "diameter": _num(None), "force_area": _num(None), "port_area": _num(None),
              "discharge_coefficient": _num(None)},
    "leak": {"tip_gap": _num(0.0), "end_gap": _num(0.0), "discharge_coefficient": _num(None)},
    "booster": {"volume": _num(None), "pressure": _num(None), "target": _num(None),
                "leak": _num(0.0)},
    "motor": {"voltage": _num(None), "resistance": _num(None),
              "inductance": _num(None), "constant": _num(None),
              "friction": _num(0.0), "inertia": _num(0.0)},
}
EXTRA_KEYS = {"rotor": {"width": _num(None)}, "vane": {"slot_pressure": ("any", False, "exhaust")}}


@dataclass
class PneumaticSettings:
    values: dict  # registry name -> value (gas entries)
    booster_start: float
    booster_target: float | None
    valve_type: str
    motor: bool
    present: tuple = field(default_factory=tuple)


def _or_derived(name: str, given, v: dict) -> float:
    """A key's value, or its registry default derived from entries already in v (the openings'
    discharge coefficients: the ports' value)."""
    return given if given is not None else float(derive(_GAS[name].derived, v))


def _pos(path, v):
    if v is None or not v > 0:
        raise ConfigError(f"{path} must be > 0, got {v}")


def _check(v: dict, prefix: str, keys: dict | None = None) -> None:
    """Every registry entry under `prefix` that v sets, within its registry bounds; the message
    names the config key (GAS_CONFIG_KEYS, or `keys`) and the limit."""
    keys = {**GAS_CONFIG_KEYS, **(keys or {})}
    for q in GAS_PARAMETERS:
        if q.name.startswith(prefix) and q.name in v and q.name not in GAS_ENCODED:
            q.check(v, keys.get(q.name, q.name))


def _window(path, v):
    if (not isinstance(v, list) or len(v) != 2
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
        raise ConfigError(f"{path} must be [start, end] in rad (housing polar angle), got {v!r}")
    a, b = float(v[0]), float(v[1])
    if not 0 < b - a < 2 * math.pi:
        raise ConfigError(f"{path} must have 0 < end - start < 2 pi, got [{a:g}, {b:g}]")
    start = (a + math.pi) % (2 * math.pi) - math.pi  # start in [-pi, pi)
    return start, start + (b - a)


def parse(c: dict, raw: dict, mode: str) -> PneumaticSettings | None:
    """c: the walked config (defaults filled), raw: the TOML dict. None without any gas table."""
    present = tuple(t for t in TABLES if t in raw)
    if not present:
        if mode == "motor":
            raise ConfigError("operation.mode = \"motor\" needs the [motor] table and the gas tables "
                              "([ports], [booster]; spec §8)")
        if c["rotor"]["width"] is not None:
            _check({"rotor.width": c["rotor"]["width"]}, "rotor.")
        return None
    for t in ("ports", "booster"):
        if t not in raw:
            raise ConfigError(f"the gas model needs the [{t}] table (found [{'], ['.join(present)}])")
    W = c["rotor"]["width"]
    if W is None:
        raise ConfigError("missing required key 'rotor.width' (the gas model needs the axial width)")
    gs = c["gas"]
    v = {"rotor.width": W}
    _check(v, "rotor.")
    _parse_gas(gs, v)
    _parse_ports(c["ports"], W, v)
    vt = _parse_valve(c["valve"], v)
    _parse_leak(c["leak"], v)
    start, target = _parse_booster(c["booster"], gs["atmosphere"], v)
    _parse_slot_pressure(c["vane"]["slot_pressure"], v)
    motor = mode == "motor"
    _parse_motor(c["motor"], raw, motor, v)
    v["operation.motor"] = 1.0 if motor else 0.0
    return PneumaticSettings(v, start, target, vt, motor, present)


def _parse_gas(gs: dict, v: dict) -> None:
    """Checks the [gas] table and adds its values to v."""
    wall_t = gs["temperature"] if gs["wall_temperature"] is None else gs["wall_temperature"]
    v.update({f"gas.{k}": gs[k] for k in ("gas_constant", "gamma", "temperature", "heat_transfer",
                                          "atmosphere")})
    v["gas.wall_temperature"] = wall_t
    _check(v, "gas.")


def _parse_ports(pt: dict, W: float, v: dict) -> None:
    """Checks the [ports] table (port widths against the rotor width W) and adds its values to v."""
    for name in ("inlet", "exhaust"):
        if pt[name] is None:
            raise ConfigError(f"missing required key 'ports.{name}' ([start, end] in rad)")
        a, b = _window(f"ports.{name}", pt[name])
        width = pt[f"{name}_width"] if pt[f"{name}_width"] is not None else pt["width"]
        if width is None:
            raise ConfigError(f"missing required key 'ports.{name}_width' (or ports.width)")
        v.update({f"ports.{name}.start": a, f"ports.{name}.end": b, f"ports.{name}.width": width})
    _windows_apart(v)
    _pos("ports.hose_diameter", pt["hose_diameter"])  # the registry holds the area
    v.update({f"ports.{k}": pt[k] for k in ("discharge_coefficient", "inlet_volume", "exhaust_volume",
                                            "check_cracking", "check_full_open")})
    v["ports.hose_area"] = math.pi * pt["hose_diameter"] ** 2 / 4
    for k in ("hose_discharge_coefficient", "check_discharge_coefficient"):
        v[f"ports.{k}"] = _or_derived(f"ports.{k}", pt[k], v)
    _check(v, "ports.")


def _windows_apart(v: dict) -> None:
    """The inlet and exhaust windows may not share a housing angle: a cell open to both short-circuits
    the pump (the exhaust would blow straight back into the inlet)."""
    arcs = [(v[f"ports.{n}.start"], v[f"ports.{n}.end"]) for n in ("inlet", "exhaust")]
    (a1, b1), (a2, b2) = arcs
    two_pi = 2 * math.pi
    if (a2 - a1) % two_pi < b1 - a1 or (a1 - a2) % two_pi < b2 - a2:
        raise ConfigError(f"ports.inlet [{a1:.4g}, {b1:.4g}] and ports.exhaust [{a2:.4g}, {b2:.4g}] rad "
                          "overlap: a cell open to both connects the exhaust to the inlet; move one window")


def _parse_valve(vl: dict, v: dict) -> str:
    """Checks the [valve] table (exhaust valve, check or reed), adds its values to v, returns its type."""
    vt = vl["type"]
    if vt not in VALVE_TYPES:
        raise ConfigError(f"valve.type must be \"check\" or \"reed\", got {vt!r}")
    reed_defaults = {"valve.mass": 1.0, "valve.stiffness": 0.0, "valve.damping": 0.0,
                     "valve.preload": 0.0, "valve.lift_max": 1.0, "valve.diameter": 1.0,
                     "valve.force_area": 1.0, "valve.mode": 1.0}
    v.update(reed_defaults)
    v["valve.discharge_coefficient"] = _or_derived("valve.discharge_coefficient",
                                                   vl["discharge_coefficient"], v)
    if vt == "check":
        _parse_check_valve(vl, v)
    else:
        _parse_reed_valve(vl, v)
    return vt


def _parse_check_valve(vl: dict, v: dict) -> None:
    for k in ("mass", "stiffness", "lift_max", "diameter", "force_area", "port_area"):
        if vl[k] is not None:
            raise ConfigError(f"valve.{k} is for type = \"reed\"")
    area = vl["area"] if vl["area"] is not None else math.pi * 0.004 ** 2 / 4
    v.update({"valve.reed": 0.0, "valve.area": area, "valve.cracking": vl["cracking"],
              "valve.full_open": vl["full_open"]})
    _check(v, "valve.")


def _parse_reed_valve(vl: dict, v: dict) -> None:
    for k in ("mass", "stiffness", "lift_max", "diameter"):
        if vl[k] is None:
            raise ConfigError(f"missing required key 'valve.{k}' (type = \"reed\")")
    d = vl["diameter"]
    port = vl["port_area"] if vl["port_area"] is not None else math.pi * d * d / 4
    force = vl["force_area"] if vl["force_area"] is not None else math.pi * d * d / 4
    v.update({"valve.reed": 1.0, "valve.area": port, "valve.cracking": 0.0, "valve.full_open": 1.0,
              "valve.mass": vl["mass"], "valve.stiffness": vl["stiffness"],
              "valve.damping": vl["damping"], "valve.preload": vl["preload"],
              "valve.lift_max": vl["lift_max"], "valve.diameter": d, "valve.force_area": force,
              "valve.mode": 1.0})
    _check(v, "valve.", {"valve.area": "valve.port_area"})


def _parse_leak(lk: dict, v: dict) -> None:
    """Checks the [leak] table (gaps at most 1 mm) and adds its values to v."""
    v.update({f"leak.{k}": lk[k] for k in ("tip_gap", "end_gap")})
    v["leak.discharge_coefficient"] = _or_derived("leak.discharge_coefficient",
                                                  lk["discharge_coefficient"], v)
    _check(v, "leak.")


def _parse_booster(bo: dict, atmosphere: float, v: dict) -> tuple:
    """Checks the [booster] table, adds its values to v, returns (start pressure, target or None)."""
    if bo["volume"] is None:
        raise ConfigError("missing required key 'booster.volume' (m^3)")
    v.update({"booster.volume": bo["volume"], "booster.leak": bo["leak"]})
    _check(v, "booster.")
    start = atmosphere if bo["pressure"] is None else bo["pressure"]
    _pos("booster.pressure", start)
    if start > atmosphere:
        raise ConfigError(f"booster.pressure must be <= gas.atmosphere ({atmosphere:g} Pa), got {start:g}")
    target = bo["target"]
    if target is not None and not 0 < target < start:
        hint = (f"; booster.pressure = {start:g} Pa looks like kPa: pressures are absolute in Pa, "
                f"{start:g} kPa is {start * 1000:g}") if start < MIN_BOOSTER_PRESSURE else ""
        raise ConfigError(f"booster.target must be in (0, booster.pressure ({start:g} Pa)), got {target:g}{hint}")
    return start, target


def _parse_slot_pressure(sp, v: dict) -> None:
    """Checks vane.slot_pressure (a source name or a pressure in Pa) and adds its encoding to v."""
    if isinstance(sp, str):
        if sp not in SLOT_SOURCES[1:]:
            raise ConfigError("vane.slot_pressure must be \"inlet\", \"exhaust\", \"atmosphere\" or a "
                              f"pressure in Pa, got {sp!r}")
        v.update({"vane.slot_pressure.source": float(SLOT_SOURCES.index(sp)),
                  "vane.slot_pressure.value": 0.0})
    elif isinstance(sp, (int, float)) and not isinstance(sp, bool):
        v.update({"vane.slot_pressure.source": 0.0, "vane.slot_pressure.value": float(sp)})
        _check(v, "vane.slot_pressure")
    else:
        raise ConfigError(f"vane.slot_pressure must be a source name or a number, got {sp!r}")


def _parse_motor(mo: dict, raw: dict, motor: bool, v: dict) -> None:
    """Checks the [motor] table (required in motor mode) and adds its values (or inert ones) to v."""
    if motor and "motor" not in raw:
        raise ConfigError("operation.mode = \"motor\" needs the [motor] table")
    if "motor" in raw:
        for k in ("voltage", "resistance", "inductance", "constant"):
            if mo[k] is None:
                raise ConfigError(f"missing required key 'motor.{k}'")
        v.update({f"motor.{k}": mo[k] for k in ("voltage", "resistance", "inductance", "constant",
                                                 "friction", "inertia")})
        _check(v, "motor.")
    else:
        v.update({"motor.voltage": 1.0, "motor.resistance": 1.0, "motor.inductance": 1.0,
                  "motor.constant": 1.0, "motor.friction": 0.0, "motor.inertia": 0.0})


def check_tip(values: dict) -> None:
    """The gas model's vane outline needs a flat tip (rho = 0) or a tip arc reaching both flanks."""
    rho, h = values["vane.tip_radius"], values["vane.thickness"]
    if 0 < rho < h / 2:
        raise ConfigError(f"vane.tip_radius must be 0 or >= vane.thickness/2 ({h / 2:g} m) for the gas "
                          f"model (the tip arc must reach both flanks), got {rho:g}")
