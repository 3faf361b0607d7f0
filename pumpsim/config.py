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
from .model_spec import housings
from .model_spec.parameters import (CONTACT_LAWS, DEFAULT_HARMONIC_SLOTS, MEASUREMENT_BY_NAME, MODELS,
                                    REQUIRED, DERIVED, SECTION_FALLBACK, Bound, Parameter, ParameterVector,
                                    Structure, checked_tolerance, derive, layout, registry, section)
from .pneumatics import config as _pneumatic_config

RPM = 2 * math.pi / 60

# Config keys that are not registry numbers: structure, shapes, lists, the operating point (the
# housing shapes' own keys come from their registry, model_spec/housings.py).
# Types: "num", "int", "str", "list"; (type, required, default).
_OTHER_KEYS = {
    "": {"name": ("str", False, None)},
    "housing": {"shape": ("str", True, None), "harmonics": ("list", False, []),
                "center": ("list", False, [0.0, 0.0])},
    "rotor": {"vanes": ("int", True, None)},
    "contact.housing": {"law": ("str", False, "impact")},
    "contact.bottom": {"law": ("str", False, "impact")},
    "operation": {"mode": ("str", False, "speed"), "speed": ("num", False, None),
                  "speed_rpm": ("num", False, None), "angle": ("num", False, 0.0),
                  "torque": ("num", False, None), "initial_vane_state": ("str", False, None),
                  "speed_tolerance": ("num", False, MEASUREMENT_BY_NAME["speed"].tolerance)},
    "effects": {"vane_friction_factors": ("list", False, None), "speed_ripple": ("list", False, None)},
}
SECTIONS = ("housing", "rotor", "vane", "friction.housing", "friction.slot", "contact.housing",
            "contact.bottom", "operation", "effects")
# sections the config may leave out (contact: the constrained model needs none)
OPTIONAL_SECTIONS = (*SECTION_FALLBACK, "contact.housing")
_LIST_VALUED = ("housing.center.0", "housing.center.1")  # given as housing.center = [x, y]


def _schema() -> dict:
    """The config schema: every registry number of a section, plus the other keys."""
    schema = dict(_OTHER_KEYS[""])
    by_shape = {t for s in housings.SHAPES.values() for k in s.keys for t, _ in k.sets}
    for sec in SECTIONS:
        node = schema
        for part in sec.split("."):
            node = node.setdefault(part, {})
        for q in section(sec):
            if q.name not in _LIST_VALUED:
                required = (q.default is REQUIRED and not q.derived and q.name not in by_shape
                            and sec not in OPTIONAL_SECTIONS)
                node[q.name.rsplit(".", 1)[1]] = ("num", required, q.default)
        node.update(_OTHER_KEYS.get(sec, {}))
    schema["housing"] = _with_shape_keys(schema["housing"])
    return schema


def _with_shape_keys(node: dict) -> dict:
    """The [housing] schema with every registered shape's keys (each required by its shape only)."""
    return {**node, **{name: ("num", False, None) for name in housings.keys() if name not in node}}


_SCHEMA = _schema()
# spec §8: gas, ports, valve, leak, booster, motor tables and their keys in [rotor] / [vane]
_SCHEMA.update(_pneumatic_config.SCHEMA)
for _table, _keys in _pneumatic_config.EXTRA_KEYS.items():
    _SCHEMA[_table].update(_keys)


def schema() -> dict:
    """The config schema (table -> key -> (type, required, default), nested by table) with the
    keys of every housing shape registered now: what `config_from_dict` checks a file against."""
    return {**_SCHEMA, "housing": _with_shape_keys(_SCHEMA["housing"])}


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
            out[key]["__given__"] = set(sub)
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


@dataclass
class PumpConfig:
    """A validated configuration (from `load_config`): the structure that selects a compiled variant
    (shape, vanes, harmonics, contact laws), the operating point (mode, speed, angle, torque) and
    every registry value by its key path in `values` (SI units)."""

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
    # relative band about `speed` inside which a fit may refine the speed of a measurement without
    # a speed column (the configured speed is the operating point, not a free guess)
    speed_tolerance: float = MEASUREMENT_BY_NAME["speed"].tolerance
    pneumatic: object = None  # spec §8 settings (pneumatics.config.PneumaticSettings) or None
    given: frozenset = frozenset()  # parameter names the file set (the others are defaults)

    def with_values(self, updates: dict) -> "PumpConfig":
        """This config with parameter values replaced; a derived default (vane.inertia from the
        mass) the file did not set follows its inputs."""
        values = {**self.values, **updates}
        fill_derived(values, self.given | set(updates))
        return dataclasses.replace(self, values=values)
    warnings: list = field(default_factory=list)  # unit-mistake warnings accepted under force (checks)

    def with_harmonics(self, harmonics) -> "PumpConfig":
        """This config with the housing harmonics [[k, A, gamma], ...] (replacing the old ones)."""
        values = {n: v for n, v in self.values.items() if not n.startswith("housing.harmonics.")}
        for j, (k, A, g) in enumerate(harmonics):
            values.update(harmonic_values(j, float(k), float(A), float(g)))
        return dataclasses.replace(self, harmonics=[[float(k), float(A), float(g)] for k, A, g in harmonics],
                                   values=values)

    def structure_for(self, model: str = "constrained") -> Structure:
        if model not in MODELS:
            raise ConfigError(f"model must be one of {', '.join(MODELS)}, got '{model}'")
        slots = max(DEFAULT_HARMONIC_SLOTS, len(self.harmonics))
        if model == "contact":
            return Structure("contact", self.vanes, slots, self.contact_laws["housing"],
                             self.contact_laws["bottom"])
        return Structure("constrained", self.vanes, slots)

    def parameters(self, model: str = "constrained") -> ParameterVector:
        """The compiled model's run-time parameter values by name (of `model`'s variant)."""
        st = self.structure_for(model)
        pv = ParameterVector(st, {})
        for q in layout(st):
            name = q.name
            if name in self.values:
                pv.values[name] = self.values[name]
            elif name.startswith("contact."):
                raise ConfigError(f"the contact model needs '{name.rsplit('.', 1)[0]}' "
                                  f"with '{name.rsplit('.', 1)[1]}' in the config")
            elif q.default is not REQUIRED:
                pv.values[name] = q.default  # e.g. an unused harmonic slot: zero amplitude
        return pv


def harmonic_values(j, k, A, gamma) -> dict:
    """Parameter values of housing harmonic slot j: A cos(k (alpha - psi - gamma))."""
    return {f"housing.harmonics.{j}.order": k, f"housing.harmonics.{j}.amplitude": A,
            f"housing.harmonics.{j}.phase": gamma}


def load_config(path) -> PumpConfig:
    """Read a TOML configuration and validate it against the parameter registry (keys, types,
    bounds, defaults); values are SI (m, kg, s, rad, N). Every rejection is a `ConfigError` naming
    the key path and the limit.

    path: the .toml file (UTF-8, a BOM allowed). The checks that need more than the file -- an
    admissible geometry, magnitudes that look like a unit mistake -- are
    `pumpsim.checks.checked_config`'s (the public `pumpsim.load_config` runs both).

    Example::

        cfg = pumpsim.config.load_config("examples/test_rig.toml")
        cfg.speed          # rad/s (operation.speed, or operation.speed_rpm converted)
    """
    from .data import decode_text

    p = Path(path)
    if p.is_dir():
        raise ConfigError(f"config '{path}' is a folder, not a TOML file")
    try:
        raw_bytes = p.read_bytes()
    except OSError as e:
        raise ConfigError(f"cannot read config '{path}': {e.strerror}") from None
    text = decode_text(raw_bytes, lambda msg: ConfigError(f"config '{path}' {msg}"))
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"config '{path}' is not valid TOML: {e}") from None
    cfg = config_from_dict(raw, name_default=p.stem)
    cfg.path = str(p)
    return cfg


def fill_derived(values: dict, given) -> None:
    """Derived defaults (registry `derived`) of the entries not in `given`, in place."""
    for q in DERIVED:
        if q.name not in given:
            values[q.name] = float(derive(q.derived, values))


def _take(c: dict, sec: str, values: dict, given: set, source: str | None = None) -> None:
    """The registry numbers of config section `sec` (read from section `source`, default sec)."""
    node = c
    for part in (source or sec).split("."):
        node = node[part]
    for q in section(sec):
        key = q.name.rsplit(".", 1)[1]
        if q.name in _LIST_VALUED or node.get(key) is None:
            continue
        values[q.name] = node[key]
        if (source or sec) == sec and key in node["__given__"]:
            given.add(q.name)


def _validate(values: dict, shape: str) -> None:
    """Every registry entry with a value within its bounds (the message names key and limit);
    the entries a housing shape sets are checked as the shape's keys."""
    by_shape = housings.SHAPES[shape]
    for q in layout(Structure("contact", 1, 0)):
        found = by_shape.key_setting(q.name)
        if q.name not in values:
            continue
        if found is None:
            q.check(values)
        elif found[0].sets[0][0] == q.name:  # a key setting several entries is checked once
            k, factor = found
            shape_key_parameter(k).check({**values, k.path: values[q.name] / factor})


def shape_key_parameter(k: "housings.ShapeKey") -> Parameter:
    """A housing shape key as a registry entry: the unit, bounds and plausible range of the first
    compiled parameter it sets, divided by its factor (a diameter: twice a semi-axis's)."""
    target, factor = k.sets[0]
    q = registry()[target]

    def scaled(b: Bound) -> Bound:
        if isinstance(b.value, str):
            return dataclasses.replace(b, factor=b.factor / factor)
        return dataclasses.replace(b, value=b.value / factor)

    plausible = q.plausible
    if plausible is not None and factor != 1.0:
        plausible = None if any(isinstance(x, str) for x in plausible) else tuple(x / factor for x in plausible)
    return dataclasses.replace(q, name=k.path, lower=scaled(q.lower), upper=scaled(q.upper),
                               plausible=plausible, doc=k.doc, aliases=())


def _housing(h: dict, values: dict, given: set) -> str:
    """housing.shape with its size: the registered shape's keys (all of them, no other shape's)
    give the compiled base curve's parameters."""
    shape = housings.SHAPES.get(h["shape"])
    if shape is None:
        raise ConfigError(housings.unknown_shape(h["shape"]))
    own = {k.name for k in shape.keys}
    for name in housings.keys():
        if name not in own and h.get(name) is not None:
            raise ConfigError(housings.foreign_key(name, shape))
    for k in shape.keys:
        if h[k.name] is None:
            raise ConfigError(f"missing required key '{k.path}' (shape = \"{shape.name}\")")
    set_values = shape.parameters({k.name: h[k.name] for k in shape.keys})
    values.update(set_values)
    given.update(set_values)
    if shape.check is not None:
        problem = shape.check({k.name: h[k.name] for k in shape.keys})
        if problem:
            raise ConfigError(problem)
    center = h["center"]
    if len(center) != 2 or not all(_is_num(x) for x in center):
        raise ConfigError(f"housing.center must be a list of two numbers, got {center!r}")
    values.update({"housing.center.0": float(center[0]), "housing.center.1": float(center[1])})
    return shape.name


def _harmonics(harm: list, a: float, b: float) -> dict:
    values = {}
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
    return values


def _sections_with_fallback(c: dict, values: dict, given: set) -> dict:
    """friction.slot / contact.bottom: their own table when present (complete), else the other's;
    returns the contact laws."""
    for sec in ("friction.housing", "friction.slot"):
        present = sec == "friction.housing" or c["friction"]["slot"]["__present__"]
        src = sec if present else SECTION_FALLBACK[sec]
        for q in section(sec):
            if c["friction"][src.split(".")[1]][q.name.rsplit(".", 1)[1]] is None:
                raise ConfigError(f"missing required key '{q.name}'")
        _take(c, sec, values, given, src)
    laws = {}
    for side in ("housing", "bottom"):
        src = c["contact"][side] if side == "housing" or c["contact"]["bottom"]["__present__"] else c["contact"]["housing"]
        if src["law"] not in CONTACT_LAWS:
            raise ConfigError(f"contact.{side}.law must be one of {', '.join(CONTACT_LAWS)}, "
                              f"got {src['law']!r}")
        laws[side] = src["law"]
        if src["stiffness"] is not None:  # the contact model's numbers: all or none
            _take(c, f"contact.{side}", values, given,
                  f"contact.{side}" if src is c["contact"][side] else "contact.housing")
    return laws


def _operation(op: dict) -> tuple[str, float]:
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
    if op["initial_vane_state"] not in (None, "bottom", "rotor", "housing"):
        raise ConfigError("operation.initial_vane_state must be \"bottom\", \"rotor\" or \"housing\", "
                          f"got {op['initial_vane_state']!r}")
    return mode, speed


def _effects(ef: dict, vanes: int, mode: str):
    """Per-vane COF factors (absent: one) and the speed ripple."""
    facs = ef["vane_friction_factors"] or [1.0] * vanes
    if len(facs) != vanes or not all(_is_num(x) and x >= 0 for x in facs):
        raise ConfigError(f"effects.vane_friction_factors must be {vanes} numbers >= 0 "
                          f"(one per vane), got {facs!r}")
    values = {f"effects.vane_friction_factor.{i}": float(x) for i, x in enumerate(facs)}
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
    return values, ripple


def config_from_dict(raw: dict, name_default: str = "pump") -> PumpConfig:
    """Validate a parsed config: registry numbers by loops over the registry (bounds, defaults,
    derived defaults), then the keys that are not numbers."""
    c = _walk(raw, schema(), "")
    vanes = c["rotor"]["vanes"]
    if not 1 <= vanes <= 16:
        raise ConfigError(f"rotor.vanes must be {'>= 1' if vanes < 1 else '<= 16'}, got {vanes}")
    values, given = {}, set()
    for sec in ("rotor", "vane", "housing", "operation", "effects"):
        _take(c, sec, values, given)
    shape = _housing(c["housing"], values, given)
    laws = _sections_with_fallback(c, values, given)
    fill_derived(values, given)
    _validate(values, shape)
    harm = c["housing"]["harmonics"]
    values.update(_harmonics(harm, values["housing.a"], values["housing.b"]))
    op = c["operation"]
    mode, speed = _operation(op)
    factors, ripple = _effects(c["effects"], vanes, mode)
    values.update(factors)
    pneumatic = _pneumatic_config.parse(c, raw, mode)
    if pneumatic is not None:
        _pneumatic_config.check_tip(values)
    return PumpConfig(
        name=c["name"] or name_default, shape=shape, vanes=vanes,
        harmonics=[list(map(float, x)) for x in harm], values=values, mode=mode, speed=speed,
        angle=op["angle"], torque=op["torque"], contact_laws=laws,
        initial_vane_state=op["initial_vane_state"],
        contact_given=c["contact"]["housing"]["stiffness"] is not None, speed_ripple=ripple,
        given=frozenset(given), pneumatic=pneumatic, speed_tolerance=_speed_tolerance(op),
    )


def _speed_tolerance(op: dict) -> float:
    return checked_tolerance("speed", op["speed_tolerance"], "operation.speed_tolerance")


def as_array(pv: ParameterVector) -> np.ndarray:
    return np.asarray(pv.stacked(), dtype=float)
