"""Configuration file (spec §5): TOML -> validated `PumpConfig`.

Every rejection names the key path and the limit, and happens before any work starts.
"""
from __future__ import annotations

import math
import tomllib
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import ConfigError
from .model_spec.parameters import CONTACT_LAWS, DEFAULT_HARMONIC_SLOTS, MODELS, ParameterVector, Structure
from .pneumatics import config as _pneumatic_config

RPM = 2 * math.pi / 60

# key -> (type, required, default). Types: "num", "int", "str", "list".
_SCHEMA = {
    "name": ("str", False, None),
    "housing": {
        "shape": ("str", True, None), "radius": ("num", False, None), "a": ("num", False, None),
        "b": ("num", False, None), "harmonics": ("list", False, []),
        "center": ("list", False, [0.0, 0.0]), "angle": ("num", False, 0.0),
    },
    "rotor": {
        "radius": ("num", True, None), "inertia": ("num", True, None), "vanes": ("int", True, None),
        "slot_radius": ("num", True, None), "slot_tilt": ("num", False, 0.0),
        "first_slot_angle": ("num", False, 0.0),
    },
    "vane": {
        "length": ("num", True, None), "thickness": ("num", True, None), "mass": ("num", True, None),
        "inertia": ("num", False, None), "tip_radius": ("num", False, 0.0),
    },
    "friction": {
        "housing": {k: ("num", True, None) for k in ("static", "dynamic", "v_static", "v_dynamic")},
        "slot": {k: ("num", False, None) for k in ("static", "dynamic", "v_static", "v_dynamic")},
    },
    "contact": {
        side: {"law": ("str", False, "impact"), "stiffness": ("num", False, None),
               "exponent": ("num", False, 1.0), "damping": ("num", False, 0.0),
               "depth": ("num", False, 1e-5)}
        for side in ("housing", "bottom")
    },
    "operation": {
        "mode": ("str", False, "speed"), "speed": ("num", False, None),
        "speed_rpm": ("num", False, None), "angle": ("num", False, 0.0),
        "torque": ("num", False, None), "bearing_torque": ("num", False, 0.0),
        "initial_vane_state": ("str", False, None),
    },
    "effects": {
        "viscous_tip_friction": ("num", False, 0.0), "vane_friction_factors": ("list", False, None),
        "speed_ripple": ("list", False, None),
    },
}
# spec §8: gas, ports, valve, leak, booster, motor tables and their keys in [rotor] / [vane]
_SCHEMA.update(_pneumatic_config.SCHEMA)
for _table, _keys in _pneumatic_config.EXTRA_KEYS.items():
    _SCHEMA[_table].update(_keys)


def _is_num(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _walk(raw: dict, schema: dict, prefix: str) -> dict:
    """Check keys and types against the schema; return a dict with defaults filled in."""
    out = {}
    for key in raw:
        if key not in schema:
            path = f"{prefix}{key}"
            import difflib

            close = difflib.get_close_matches(key, list(schema), n=1)
            hint = f" (did you mean '{prefix}{close[0]}'?)" if close else ""
            raise ConfigError(f"unknown key '{path}'{hint}")
    for key, spec in schema.items():
        path = f"{prefix}{key}"
        if isinstance(spec, dict):
            sub = raw.get(key, {})
            if not isinstance(sub, dict):
                raise ConfigError(f"'{path}' must be a table")
            out[key] = _walk(sub, spec, path + ".")
            out[key]["__present__"] = key in raw
            continue
        typ, required, default = spec
        if key not in raw:
            if required:
                raise ConfigError(f"missing required key '{path}'")
            out[key] = default
            continue
        v = raw[key]
        if typ == "num" and not _is_num(v):
            raise ConfigError(f"'{path}' must be a number, got {v!r}")
        if typ == "num" and not math.isfinite(v):
            raise ConfigError(f"'{path}' must be finite, got {v!r}")
        if typ == "int" and (not isinstance(v, int) or isinstance(v, bool)):
            raise ConfigError(f"'{path}' must be an integer, got {v!r}")
        if typ == "str" and not isinstance(v, str):
            raise ConfigError(f"'{path}' must be a string, got {v!r}")
        if typ == "list" and not isinstance(v, list):
            raise ConfigError(f"'{path}' must be a list, got {v!r}")
        out[key] = float(v) if typ == "num" else v
    return out


def _positive(path, v):
    if v is None or v <= 0:
        raise ConfigError(f"{path} must be > 0, got {v}")


def _range(path, v, lo, hi):
    if not lo <= v <= hi:
        raise ConfigError(f"{path} must be in [{lo:g}, {hi:g}], got {v:g}")


@dataclass
class PumpConfig:
    name: str
    shape: str
    vanes: int
    harmonics: list  # [[k, A, gamma], ...]
    values: dict  # parameter name -> value (see parameters.layout)
    mode: str  # speed | torque
    speed: float | None  # rad/s (speed mode: the prescribed speed; torque mode: initial speed)
    angle: float
    torque: float | None
    contact_laws: dict = field(default_factory=dict)
    initial_vane_state: str | None = None  # contact model: bottom | rotor | housing
    contact_given: bool = False
    path: str | None = None
    # speed mode: omega = speed (1 + amplitude cos(order theta_n + phase)), theta_n the nominal angle
    speed_ripple: tuple | None = None  # (order, relative amplitude, phase [rad])
    pneumatic: object = None  # spec §8 settings (pneumatics.config.PneumaticSettings) or None

    def with_harmonics(self, harmonics) -> "PumpConfig":
        """This config with the housing harmonics [[k, A, gamma], ...] (replacing the old ones)."""
        values = {n: v for n, v in self.values.items() if not n.startswith("housing.harmonics.")}
        for j, (k, A, g) in enumerate(harmonics):
            values.update(harmonic_values(j, float(k), float(A), float(g)))
        return dataclasses.replace(self, harmonics=[[float(k), float(A), float(g)] for k, A, g in harmonics],
                                   values=values)

    def structure_for(self, model: str = "constrained") -> Structure:
        if model not in MODELS:
            raise ConfigError(f"--model must be one of {', '.join(MODELS)}, got '{model}'")
        slots = max(DEFAULT_HARMONIC_SLOTS, len(self.harmonics))
        if model == "contact":
            return Structure("contact", self.vanes, slots, self.contact_laws["housing"],
                             self.contact_laws["bottom"])
        return Structure("constrained", self.vanes, slots)

    def parameters(self, model: str = "constrained") -> ParameterVector:
        st = self.structure_for(model)
        pv = ParameterVector(st, {})
        for name in pv.names:
            if name in self.values:
                pv.values[name] = self.values[name]
            elif name.startswith("housing.harmonics."):
                pv.values[name] = 0.0  # unused harmonic slot: zero amplitude
            elif name.startswith("contact."):
                raise ConfigError(f"the contact model needs '{name.rsplit('.', 1)[0]}' "
                                  f"with '{name.rsplit('.', 1)[1]}' in the config")
        return pv


def harmonic_values(j, k, A, gamma) -> dict:
    """Parameter values of housing harmonic slot j: A cos(k (alpha - psi - gamma))."""
    return {f"housing.harmonics.{j}.order": k, f"housing.harmonics.{j}.amplitude": A,
            f"housing.harmonics.{j}.phase": gamma}


def load_config(path, check_geometry: bool = True) -> PumpConfig:
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as e:
        raise ConfigError(f"cannot read config '{path}': {e.strerror}") from None
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"config '{path}' is not valid TOML: {e}") from None
    cfg = config_from_dict(raw, name_default=p.stem)
    cfg.path = str(p)
    if check_geometry:
        from .geometry import check_geometry as _check

        _check(cfg)
    return cfg


def config_from_dict(raw: dict, name_default: str = "pump") -> PumpConfig:
    c = _walk(raw, _SCHEMA, "")
    h, r, v, op = c["housing"], c["rotor"], c["vane"], c["operation"]
    values: dict = {}

    # rotor
    _positive("rotor.radius", r["radius"])
    _positive("rotor.inertia", r["inertia"])
    if r["vanes"] < 1:
        raise ConfigError(f"rotor.vanes must be >= 1, got {r['vanes']}")
    if r["vanes"] > 16:
        raise ConfigError(f"rotor.vanes must be <= 16, got {r['vanes']}")
    if not 0 <= r["slot_radius"] < r["radius"]:
        raise ConfigError(f"rotor.slot_radius must be in [0, rotor.radius ({r['radius']:.4f} m)), "
                          f"got {r['slot_radius']:.4f}")
    if not abs(r["slot_tilt"]) < math.pi / 2:
        raise ConfigError(f"rotor.slot_tilt must be in (-pi/2, pi/2), got {r['slot_tilt']:g}")
    values.update({"rotor.radius": r["radius"], "rotor.inertia": r["inertia"],
                   "rotor.slot_radius": r["slot_radius"], "rotor.slot_tilt": r["slot_tilt"],
                   "rotor.first_slot_angle": r["first_slot_angle"]})
    # vane
    for k in ("length", "thickness", "mass"):
        _positive(f"vane.{k}", v[k])
    if v["inertia"] is None:
        v["inertia"] = v["mass"] * (v["length"] ** 2 + v["thickness"] ** 2) / 12
    _positive("vane.inertia", v["inertia"])
    if not 0 <= v["tip_radius"] < v["length"] / 2:
        raise ConfigError(f"vane.tip_radius must be in [0, vane.length/2 ({v['length'] / 2:.4f} m)), "
                          f"got {v['tip_radius']:.4f}")
    values.update({"vane.length": v["length"], "vane.thickness": v["thickness"],
                   "vane.mass": v["mass"], "vane.inertia": v["inertia"],
                   "vane.tip_radius": v["tip_radius"]})
    # housing
    shape = h["shape"]
    if shape == "circle":
        for k in ("a", "b"):
            if h[k] is not None:
                raise ConfigError(f"housing.{k} is for shape = \"ellipse\"; a circle takes housing.radius")
        if h["radius"] is None:
            raise ConfigError("missing required key 'housing.radius' (shape = \"circle\")")
        _positive("housing.radius", h["radius"])
        if h["radius"] <= r["radius"]:
            raise ConfigError(f"housing.radius must be > rotor.radius ({r['radius']:.4f} m), "
                              f"got {h['radius']:.4f}")
        a = b = h["radius"]
    elif shape == "ellipse":
        if h["radius"] is not None:
            raise ConfigError("housing.radius is for shape = \"circle\"; an ellipse takes housing.a and housing.b")
        for k in ("a", "b"):
            if h[k] is None:
                raise ConfigError(f"missing required key 'housing.{k}' (shape = \"ellipse\")")
            _positive(f"housing.{k}", h[k])
            if h[k] <= r["radius"]:
                raise ConfigError(f"housing.{k} must be > rotor.radius ({r['radius']:.4f} m), "
                                  f"got {h[k]:.4f}")
        a, b = h["a"], h["b"]
    else:
        raise ConfigError(f"housing.shape must be \"circle\" or \"ellipse\", got {shape!r}")
    center = h["center"]
    if len(center) != 2 or not all(_is_num(x) for x in center):
        raise ConfigError(f"housing.center must be a list of two numbers, got {center!r}")
    values.update({"housing.a": a, "housing.b": b, "housing.center.0": float(center[0]),
                   "housing.center.1": float(center[1]), "housing.angle": h["angle"]})
    harm = h["harmonics"]
    for j, item in enumerate(harm):
        path = f"housing.harmonics[{j}]"
        if not (isinstance(item, list) and len(item) == 3 and all(_is_num(x) for x in item)):
            raise ConfigError(f"{path} must be [order k, amplitude A_k, phase gamma_k], got {item!r}")
        k, A, g = (float(x) for x in item)
        if k < 1 or k != int(k):
            raise ConfigError(f"{path}: order k must be an integer >= 1, got {k:g}")
        if abs(A) >= 0.1 * min(a, b):
            raise ConfigError(f"{path}: amplitude must be < 10% of the housing size "
                              f"({0.1 * min(a, b):.4g} m), got {A:g}")
        values.update(harmonic_values(j, k, A, g))
    # friction
    fr = c["friction"]
    for side in ("housing", "slot"):
        src = fr[side] if side == "housing" or fr["slot"]["__present__"] else fr["housing"]
        for k in ("static", "dynamic", "v_static", "v_dynamic"):
            if src[k] is None:
                raise ConfigError(f"missing required key 'friction.{side}.{k}'")
        for k in ("static", "dynamic"):
            _range(f"friction.{side}.{k}", src[k], 0.0, 2.0)
        _positive(f"friction.{side}.v_static", src["v_static"])
        if src["v_static"] >= src["v_dynamic"]:
            raise ConfigError(f"friction.{side}.v_static must be < friction.{side}.v_dynamic "
                              f"({src['v_dynamic']:g} m/s), got {src['v_static']:g}")
        for k in ("static", "dynamic", "v_static", "v_dynamic"):
            values[f"friction.{side}.{k}"] = src[k]
    # contact (Model 1)
    ct = c["contact"]
    laws = {}
    for side in ("housing", "bottom"):
        src = ct[side] if side == "housing" or ct["bottom"]["__present__"] else ct["housing"]
        if src["law"] not in CONTACT_LAWS:
            raise ConfigError(f"contact.{side}.law must be one of {', '.join(CONTACT_LAWS)}, "
                              f"got {src['law']!r}")
        laws[side] = src["law"]
        if src["stiffness"] is not None:
            _positive(f"contact.{side}.stiffness", src["stiffness"])
            _positive(f"contact.{side}.exponent", src["exponent"])
            _positive(f"contact.{side}.depth", src["depth"])
            if src["damping"] < 0:
                raise ConfigError(f"contact.{side}.damping must be >= 0, got {src['damping']:g}")
            for k in ("stiffness", "exponent", "damping", "depth"):
                values[f"contact.{side}.{k}"] = src[k]
    # operation
    mode = op["mode"]
    if mode not in ("speed", "torque", "motor"):
        raise ConfigError(f"operation.mode must be \"speed\" or \"torque\" (or \"motor\" with the gas "
                          f"tables, spec §8), got {mode!r}")
    if op["speed"] is not None and op["speed_rpm"] is not None:
        raise ConfigError("give operation.speed (rad/s) or operation.speed_rpm, not both")
    speed = op["speed"] if op["speed_rpm"] is None else op["speed_rpm"] * RPM
    if mode == "speed":
        if speed is None:
            raise ConfigError("missing required key 'operation.speed' (or operation.speed_rpm) for mode = \"speed\"")
        if speed <= 0:
            raise ConfigError(f"operation.speed must be > 0, got {speed:g}")
    elif mode == "motor":
        speed = 0.0 if speed is None else speed  # the motor starts the pump (from rest by default)
        if speed < 0:
            raise ConfigError(f"operation.speed (initial speed) must be >= 0, got {speed:g}")
    else:
        if op["torque"] is None:
            raise ConfigError("missing required key 'operation.torque' for mode = \"torque\"")
        speed = 0.0 if speed is None else speed
        if speed < 0:
            raise ConfigError(f"operation.speed (initial speed) must be >= 0, got {speed:g}")
    values["operation.bearing_torque"] = op["bearing_torque"]
    if op["initial_vane_state"] not in (None, "bottom", "rotor", "housing"):
        raise ConfigError("operation.initial_vane_state must be \"bottom\", \"rotor\" or \"housing\", "
                          f"got {op['initial_vane_state']!r}")
    # effects (absent = zero / factor one)
    ef = c["effects"]
    if ef["viscous_tip_friction"] < 0:
        raise ConfigError(f"effects.viscous_tip_friction must be >= 0, got {ef['viscous_tip_friction']:g}")
    values["effects.viscous_tip_friction"] = ef["viscous_tip_friction"]
    facs = ef["vane_friction_factors"] or [1.0] * r["vanes"]
    if len(facs) != r["vanes"] or not all(_is_num(x) and x >= 0 for x in facs):
        raise ConfigError(f"effects.vane_friction_factors must be {r['vanes']} numbers >= 0 "
                          f"(one per vane), got {facs!r}")
    for i, x in enumerate(facs):
        values[f"effects.vane_friction_factor.{i}"] = float(x)
    ripple = ef["speed_ripple"]
    if ripple is not None:
        if (len(ripple) != 3 or not all(_is_num(x) for x in ripple) or ripple[0] != int(ripple[0])
                or ripple[0] < 1):
            raise ConfigError("effects.speed_ripple must be [order (integer >= 1), relative amplitude, "
                              f"phase], got {ripple!r}")
        if not 0 <= ripple[1] < 1:
            raise ConfigError(f"effects.speed_ripple amplitude must be in [0, 1), got {ripple[1]:g}")
        if mode != "speed":
            raise ConfigError("effects.speed_ripple needs operation.mode = \"speed\" (a prescribed speed)")
        ripple = (int(ripple[0]), float(ripple[1]), float(ripple[2]))
    pneumatic = _pneumatic_config.parse(c, raw, mode)
    if pneumatic is not None:
        _pneumatic_config.check_tip(values)

    return PumpConfig(
        name=c["name"] or name_default, shape=shape, vanes=r["vanes"],
        harmonics=[list(map(float, x)) for x in harm], values=values, mode=mode, speed=speed,
        angle=op["angle"], torque=op["torque"], contact_laws=laws,
        initial_vane_state=op["initial_vane_state"],
        contact_given=ct["housing"]["stiffness"] is not None, speed_ripple=ripple,
        pneumatic=pneumatic,
    )


def as_array(pv: ParameterVector) -> np.ndarray:
    return np.asarray(pv.stacked(), dtype=float)
