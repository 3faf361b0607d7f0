"""The parameter registry: every number the compiled model uses, declared once.

Each `Parameter` is a config key path with its unit, default (or derived default with its formula),
bounds (numbers or other entries), whether it may be fitted, its aliases and a physical
plausibility range. Config validation, identification bounds and the runtime vector's layout are
loops over `REGISTRY`; the measurement parameters a fit adds (theta0, speed, delay, offset, lag,
...) are in `MEASUREMENT`. A new config section is a block of entries here (and, if its numbers
reach the kernel, a use in codegen).

The stacked runtime vector `p` follows declaration order. Only *structure* (model type, vane count,
number of housing-harmonic slots, contact laws) changes the compiled kernel; every value here is an
entry of `p`, so changing it never recompiles.
"""
from __future__ import annotations

import difflib
import math
import functools
import re
from dataclasses import dataclass, field

from ..errors import ConfigError
from . import housings

INF = math.inf
REQUIRED = None  # default of an entry the config must give


@dataclass(frozen=True)
class Bound:
    """A limit: a number, or another entry's value times `factor` (named in messages by path)."""

    value: float | str
    open: bool = False
    factor: float = 1.0
    label: str = ""  # how a message names a numeric bound, e.g. "pi/2"

    def at(self, values) -> float:
        return values[self.value] * self.factor if isinstance(self.value, str) else self.value

    def text(self, values, unit) -> str:
        if not isinstance(self.value, str):
            return self.label or f"{self.value:g}"
        ref = self.value if self.factor == 1 else f"{self.value}/{1 / self.factor:g}"
        ref = f"{self.factor:g} * {self.value}" if self.factor > 1 else ref
        return f"{ref} ({_fmt(self.at(values), unit)} {unit})"


def _fmt(v, unit) -> str:
    return f"{v:.4f}" if unit == "m" else f"{v:g}"


NONE_LOW, NONE_HIGH = Bound(-INF), Bound(INF)
POSITIVE = Bound(0.0, open=True)
NONNEGATIVE = Bound(0.0)


@dataclass(frozen=True)
class Parameter:
    name: str  # config key path and name in the runtime vector, e.g. "vane.mass"
    unit: str
    default: float | None = REQUIRED
    lower: Bound = NONE_LOW
    upper: Bound = NONE_HIGH
    derived: str = ""  # formula of a derived default in other entries' names (evaluated below)
    below: str = ""  # another entry this one must stay below (v_static < v_dynamic)
    identifiable: bool = True  # may be fitted (--params)
    aliases: tuple = ()  # other names that set this entry (mu; housing shape keys: housings.py)
    plausible: tuple | None = None  # physical plausibility range [SI]: diagnose, sweeps (see PLAUSIBLE)
    plausible_why: str = ""  # the physics behind the range, quoted when a value leaves it
    norm: str = ""  # entries sharing a norm key: the range bounds their Euclidean norm
    doc: str = ""
    period: float | None = None  # an angle: a fit's start is scanned over one period (non-convex cost)

    @property
    def inputs(self) -> list[str]:
        """The entries a derived default is computed from."""
        return derived_inputs(self.derived)

    @property
    def positive(self) -> bool:
        return self.lower.value == 0.0 and self.lower.open

    def check(self, values, name=None) -> None:
        """ConfigError naming the key and the limit unless values[self.name] is within bounds."""
        name = name or self.name
        v = values[self.name]
        lo, hi = self.lower.at(values), self.upper.at(values)
        low_ok = v > lo if self.lower.open else v >= lo
        high_ok = v < hi if self.upper.open else v <= hi
        if not (low_ok and high_ok):
            raise ConfigError(f"{name} must be {self.limit_text(values)}, got {_fmt(v, self.unit)}")
        if self.below and not v < values[self.below]:
            raise ConfigError(f"{name} must be < {self.below} ({values[self.below]:g} {self.unit}), "
                              f"got {v:g}")

    def limit_text(self, values) -> str:
        lo, hi = self.lower, self.upper
        if math.isinf(hi.at(values)):
            return f"{'>' if lo.open else '>='} {lo.text(values, self.unit)}"
        if math.isinf(lo.at(values)):
            return f"{'<' if hi.open else '<='} {hi.text(values, self.unit)}"
        return (f"in {'(' if lo.open else '['}{lo.text(values, self.unit)}, "
                f"{hi.text(values, self.unit)}{')' if hi.open else ']'}")

    def fit_bounds(self) -> tuple[float, float]:
        """Bounds for a fit: the numeric limits (a limit by another entry: >= 0 below, none above,
        every such entry here is a length or speed)."""
        lo = self.lower.value if not isinstance(self.lower.value, str) else 0.0
        hi = self.upper.value if not isinstance(self.upper.value, str) else INF
        return float(lo), float(hi)


def derive(formula: str, values: dict):
    """Evaluate a derived default's formula with the entries' values (names with dots; numbers
    or CasADi expressions, so a fit's graph carries the dependence)."""
    env = {n.replace(".", "__"): values[n] for n in derived_inputs(formula)}
    code = re.sub(_NAME, lambda m: m.group(0).replace(".", "__"), formula)
    return eval(code, {"__builtins__": {}}, env)  # noqa: S307 (the registry's own formulas)


_NAME = r"[a-z_]+(?:\.[a-z_0-9]+)+"  # an entry's dotted name in a formula


def derived_inputs(formula: str) -> list[str]:
    return re.findall(_NAME, formula)


FRICTION_KEYS = ("static", "dynamic", "v_static", "v_dynamic")  # the friction law's argument order


def friction_args(values, side: str) -> list:
    """(mu_s, mu_d, v_s, v_d) of friction side "housing" | "slot" from values by name."""
    return [values[f"friction.{side}.{k}"] for k in FRICTION_KEYS]


COF = dict(lower=NONNEGATIVE, upper=Bound(2.0), plausible=(0.0, 1.0),
           plausible_why="a COF")  # the COF range, once


def _friction(side: str, default_from: str | None = None) -> list[Parameter]:
    pre = f"friction.{side}"
    alias = {"housing": ("mu",), "slot": ("mu_slot",)}[side]
    return [
        Parameter(f"{pre}.static", "-", **COF, doc="static COF"),
        Parameter(f"{pre}.dynamic", "-", **COF, aliases=alias, doc="dynamic COF"),
        Parameter(f"{pre}.v_static", "m/s", lower=POSITIVE, below=f"{pre}.v_dynamic",
                  plausible=(1e-6, 0.1), doc="static transition speed"),
        Parameter(f"{pre}.v_dynamic", "m/s", lower=POSITIVE, plausible=(1e-5, 1.0),
                  doc="dynamic transition speed"),
    ]


def _contact(side: str) -> list[Parameter]:
    pre = f"contact.{side}"
    return [
        Parameter(f"{pre}.stiffness", "N/m^e", lower=POSITIVE),
        Parameter(f"{pre}.exponent", "-", 1.0, lower=POSITIVE),
        Parameter(f"{pre}.damping", "N s/m", 0.0, lower=NONNEGATIVE),
        Parameter(f"{pre}.depth", "m", 1e-5, lower=POSITIVE, doc="IMPACT damping ramp depth"),
    ]


def _harmonic(j: int) -> list[Parameter]:
    pre = f"housing.harmonics.{j}"
    return [Parameter(f"{pre}.order", "-", 0.0, lower=NONNEGATIVE, identifiable=False),
            Parameter(f"{pre}.amplitude", "m", 0.0, plausible=("-0.25 * clearance", "0.25 * clearance"),
                      plausible_why="an out-of-round (one order) below a quarter of the clearance: more "
                      "would leave no running gap on the tight side"),
            Parameter(f"{pre}.phase", "rad", 0.0, period=2 * math.pi)]


# the rotor touches the housing where the centre offset reaches the radial gap
ECCENTRICITY = dict(plausible=(0.0, "clearance"), norm="eccentricity",
                    plausible_why="below the smallest rotor-housing clearance")
HOUSING_SIZE = dict(lower=Bound("rotor.radius", open=True), plausible=(5e-3, 0.1))
ROTOR = [
    Parameter("rotor.radius", "m", lower=POSITIVE, plausible=(5e-3, 0.1)),
    Parameter("rotor.inertia", "kg m^2", lower=POSITIVE, plausible=(1e-8, 1e-2)),
    Parameter("rotor.slot_radius", "m", lower=NONNEGATIVE, upper=Bound("rotor.radius", open=True)),
    Parameter("rotor.slot_tilt", "rad", 0.0, lower=Bound(-math.pi / 2, True, label="-pi/2"),
              upper=Bound(math.pi / 2, True, label="pi/2")),
    Parameter("rotor.first_slot_angle", "rad", 0.0),
]
VANE = [
    Parameter("vane.length", "m", lower=POSITIVE, plausible=(1e-3, 0.05)),
    Parameter("vane.thickness", "m", lower=POSITIVE, plausible=(5e-4, 0.01)),
    Parameter("vane.mass", "kg", lower=POSITIVE, plausible=(1e-4, 0.05)),
    Parameter("vane.inertia", "kg m^2", lower=POSITIVE,
              derived="vane.mass * (vane.length ** 2 + vane.thickness ** 2) / 12",
              doc="about the centre of mass; default: a uniform rectangular plate"),
    Parameter("vane.tip_radius", "m", 0.0, lower=NONNEGATIVE,
              upper=Bound("vane.length", open=True, factor=0.5)),
]
HOUSING = [
    # the base curve's semi-axes: a housing shape (housings.py) sets them from its config keys
    Parameter("housing.a", "m", **HOUSING_SIZE, doc="semi-axis along housing x"),
    Parameter("housing.b", "m", **HOUSING_SIZE, doc="semi-axis along housing y"),
    Parameter("housing.center.0", "m", 0.0, **ECCENTRICITY),
    Parameter("housing.center.1", "m", 0.0, **ECCENTRICITY),
    Parameter("housing.angle", "rad", 0.0),
]
OPERATION = [Parameter("operation.bearing_torque", "N m", 0.0)]
# Effect parameters: zero (or one, for factors) means "absent".
EFFECTS = [Parameter("effects.viscous_tip_friction", "N s/m", 0.0, lower=NONNEGATIVE,
                     plausible=(0.0, "abs(mean_torque) / (vanes * speed * housing_a ** 2)"),
                     plausible_why="its torque N c omega a^2 cannot exceed the measured mean torque",
                     doc="tip force per slip speed")]


def _factor(i: int) -> Parameter:
    return Parameter(f"effects.vane_friction_factor.{i}", "-", 1.0, lower=NONNEGATIVE,
                     plausible=(0.2, 5.0), plausible_why="a vane of another material or finish: COFs of "
                     "vane materials (carbon, PTFE and PEEK composites, steel) lie within a factor 5 of "
                     "each other; its COF mu x factor must also stay a COF",
                     doc="per-vane COF factor (tip and slot)")


@dataclass(frozen=True)
class Structure:
    """What selects a compiled variant. Everything else is a runtime parameter."""

    model: str = "constrained"  # constrained (Model 2) | contact (Model 1)
    vanes: int = 4
    harmonics: int = 4  # housing-harmonic slots compiled in (unused slots have zero amplitude)
    housing_law: str = "impact"  # Model 1 only
    bottom_law: str = "impact"  # Model 1 only

    @property
    def variant(self) -> str:
        base = f"{self.model}-n{self.vanes}-h{self.harmonics}"
        if self.model == "contact":
            base += f"-{self.housing_law}-{self.bottom_law}"
        return base

    def as_dict(self) -> dict:
        return {"model": self.model, "vanes": self.vanes, "harmonics": self.harmonics,
                "housing_law": self.housing_law, "bottom_law": self.bottom_law}


MODELS = ("constrained", "contact")
CONTACT_LAWS = ("linear", "hunt-crossley", "impact", "report-nonlinear")
DEFAULT_HARMONIC_SLOTS = 0  # a variant compiles exactly the configured harmonics
# a section the config may leave out: it then takes the other section's values
SECTION_FALLBACK = {"friction.slot": "friction.housing", "contact.bottom": "contact.housing"}


@functools.lru_cache(maxsize=None)
def layout(structure: Structure) -> tuple[Parameter, ...]:
    """Ordered parameter declarations for one compiled variant (declarations are frozen: one tuple
    per structure serves every config and design)."""
    ps = ROTOR + VANE + HOUSING
    for j in range(structure.harmonics):
        ps = ps + _harmonic(j)
    ps = ps + _friction("housing") + _friction("slot") + OPERATION + EFFECTS
    ps = ps + [_factor(i) for i in range(structure.vanes)]
    if structure.model == "contact":
        ps = ps + _contact("housing") + _contact("bottom")
    return tuple(ps)


@functools.lru_cache(maxsize=None)
def layout_names(structure: Structure) -> tuple[str, ...]:
    return tuple(p.name for p in layout(structure))


def registry(structure: Structure | None = None) -> dict:
    """name -> Parameter of every model parameter (of `structure`, default: the contact model's
    full set with 16 vanes' factors and no harmonics)."""
    st = structure or Structure("contact", 16, 0)
    return {q.name: q for q in layout(st)}


def section(prefix: str) -> list[Parameter]:
    """The static entries of one config section, e.g. "vane" or "friction.slot"."""
    return list(_section(prefix))


@functools.lru_cache(maxsize=None)
def _section(prefix: str) -> tuple[Parameter, ...]:
    pool = ROTOR + VANE + HOUSING + OPERATION + EFFECTS + _friction("housing") + _friction("slot") \
        + _contact("housing") + _contact("bottom")
    return tuple(q for q in pool if q.name.rsplit(".", 1)[0] == prefix)


def _aliases() -> dict:
    out: dict = {}
    for q in ROTOR + VANE + HOUSING + _friction("housing") + _friction("slot"):
        for a in q.aliases:
            out.setdefault(a, []).append(q.name)
    return {**{a: tuple(t) for a, t in out.items()}, **housings.aliases()}


ALIASES = _aliases()  # alias -> the entries it sets (housing.radius -> a, b; mu -> the dynamic COF)


def alias_targets(name: str) -> tuple:
    return ALIASES.get(name, ())


# entries whose default is derived from others (config: when the file does not set them;
# fits and sweeps: they follow their inputs)
DERIVED = tuple(q for q in ROTOR + VANE + HOUSING if q.derived)


# Names a context-dependent plausibility bound may use (formulas in PLAUSIBLE ranges): the pump's
# smallest radial gap [m], speed [rad/s], vane count, housing semi-axis a [m], and the measured
# torque's RMS and mean [N m].
PLAUSIBLE_CONTEXT = ("clearance", "speed", "vanes", "housing_a", "torque_rms", "mean_torque")


def plausible_range(spec, context: dict | None) -> tuple | None:
    """(low, high) of a plausibility declaration: numbers, or formulas in PLAUSIBLE_CONTEXT names
    evaluated with `context`; None when a formula needs a name the context lacks."""
    out = []
    for b in spec:
        if isinstance(b, str):
            env = {k: v for k, v in (context or {}).items() if k in PLAUSIBLE_CONTEXT}
            try:
                b = float(eval(b, {"__builtins__": {"abs": abs}}, env))  # noqa: S307 (the registry's formulas)
            except (NameError, ZeroDivisionError):
                return None
        out.append(b)
    return tuple(out)


def plausibility(name: str, structure: Structure | None = None):
    """The entry (Parameter or MeasurementParameter) that declares `name`'s plausible range, or None."""
    q = MEASUREMENT_BY_NAME.get(name) or registry(structure).get(name)
    m = re.fullmatch(r"housing\.harmonics\.(\d+)\.\w+", name)
    if q is None and m:  # a harmonic slot beyond the structure's: every slot is declared alike
        q = {h.name: h for h in _harmonic(int(m.group(1)))}.get(name)
    if q is None and alias_targets(name):
        q = registry(structure)[alias_targets(name)[0]]
    return q if q is not None and q.plausible is not None else None


def implausible(values: dict, structure: Structure | None = None, context: dict | None = None) -> list[str]:
    """Messages for values outside their entry's physical plausibility range (valid, but worth a
    second look: a fitted COF of 1.4, a 5 cm vane); for diagnose's and sweeps' checks. Entries
    sharing a norm key (the housing centre) are checked by their Euclidean norm; a bound that
    needs a context name missing from `context` is not checked."""
    out, norms = [], {}
    for name, v in values.items():
        q = plausibility(name, structure)
        if q is None:
            continue
        if q.norm:
            norms.setdefault(q.norm, [q, 0.0])[1] += v * v
            continue
        out += _outside(name, v, q, context)
    for key, (q, ss) in norms.items():
        out += _outside(key, math.sqrt(ss), q, context)
    return out


def _outside(label, v, q, context) -> list[str]:
    rng = plausible_range(q.plausible, context)
    if rng is None or rng[0] <= v <= rng[1]:
        return []
    why = f" ({q.plausible_why})" if q.plausible_why else ""
    return [f"{label} = {v:g} {q.unit} is outside the plausible range [{rng[0]:g}, {rng[1]:g}] {q.unit}{why}"]


# -- measurement parameters: what a fit adds to the model's (not in the config, not in p) --------
@dataclass(frozen=True)
class MeasurementParameter:
    name: str
    unit: str
    lower: float = -INF
    upper: float = INF
    in_kernel_graph: bool = False  # an input z of the compiled fit graph (after p)
    through_angle: bool = False  # acts through the rotor angle (sample-averaged Jacobian column)
    period: float | None = None  # periodic (theta0: 2 pi; the start is scanned over it)
    band: float | None = None  # relative band around the nominal value the start search keeps to
    tolerance: float | None = None  # default relative band a fit may move a known nominal value in
    transient: bool = False  # a transient (run-up) fit's parameter
    plausible: tuple | None = None  # as Parameter.plausible
    plausible_why: str = ""
    norm: str = ""
    doc: str = ""


# a drive holding its speed: a motor's speed ripple under a vane pump's load is a few per cent at most
RIPPLE = dict(plausible=(0.0, 0.05), norm="speed ripple", plausible_why="a few per cent of the speed")
MEASUREMENT = (
    MeasurementParameter("theta0", "rad", in_kernel_graph=True, through_angle=True,
                         period=2 * math.pi, transient=True, doc="rotor angle at the first sample"),
    MeasurementParameter("speed", "rad/s", in_kernel_graph=True, through_angle=True, band=0.5, tolerance=0.02,
                         doc="constant speed; its start from the torque spectrum within +-50 %; a "
                             "configured nominal speed is refined within operation.speed_tolerance"),
    MeasurementParameter("delay", "s", in_kernel_graph=True, through_angle=True,
                         doc="time shift between torque and angle"),
    MeasurementParameter("torque_offset", "N m", in_kernel_graph=True,
                         plausible=("-0.5 * torque_rms", "0.5 * torque_rms"),
                         plausible_why="a sensor zero error is a small part of the signal", doc="sensor zero offset"),
    MeasurementParameter("ripple_cos", "-", in_kernel_graph=True, through_angle=True, **RIPPLE,
                         doc="relative speed ripple A cos(phase) at shaft order ripple_order"),
    MeasurementParameter("ripple_sin", "-", in_kernel_graph=True, through_angle=True, **RIPPLE,
                         doc="relative speed ripple A sin(phase)"),
    MeasurementParameter("lag", "s", lower=0.0, plausible=(0.0, "1 / (vanes * speed)"),
                         plausible_why="a slower sensor would damp the vane-passing order by more than 30 %",
                         doc="first-order torque-sensor time constant"),
    MeasurementParameter("speed0", "rad/s", transient=True, doc="speed at the first sample (transient)"),
)
MEASUREMENT_BY_NAME = {m.name: m for m in MEASUREMENT}


def checked_tolerance(name: str, value, key: str) -> float:
    """A relative tolerance band for measurement parameter `name` (operation.speed_tolerance,
    --speed-tolerance): in [0, its start-search band]; ConfigError naming `key` otherwise."""
    upper = MEASUREMENT_BY_NAME[name].band
    if not 0 <= value <= upper:
        raise ConfigError(f"{key} must be in [0, {upper:g}], got {value:g}")
    return float(value)
KERNEL_GRAPH_INPUTS = tuple(m.name for m in MEASUREMENT if m.in_kernel_graph)
ANGLE_ACTING = tuple(m.name for m in MEASUREMENT if m.through_angle)
COF_ALIASES = ("mu", "mu_slot")  # fit names of the dynamic COFs (see _friction)


def fit_bounds(name: str, structure: Structure) -> tuple[float, float]:
    """Bounds of any fit name: measurement parameter, alias or parameter path."""
    if name in MEASUREMENT_BY_NAME:
        m = MEASUREMENT_BY_NAME[name]
        return m.lower, m.upper
    reg = registry(structure)
    if name in reg:
        return reg[name].fit_bounds()
    targets = alias_targets(name)
    if targets:
        return reg[targets[0]].fit_bounds()
    return -INF, INF


@dataclass
class ParameterVector:
    """Values by name, stacked in declaration order on demand."""

    structure: Structure
    values: dict = field(default_factory=dict)

    @property
    def names(self) -> list[str]:
        return list(layout_names(self.structure))

    def index(self, name: str) -> int:
        names = self.names
        if name not in names:
            close = difflib.get_close_matches(name, names, n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            raise ConfigError(f"unknown parameter '{name}'{hint}")
        return names.index(name)

    def stacked(self) -> list[float]:
        missing = [n for n in self.names if n not in self.values]
        if missing:
            raise ConfigError(f"parameters without a value: {', '.join(missing)}")
        return [float(self.values[n]) for n in self.names]

    def copy(self) -> "ParameterVector":
        return ParameterVector(self.structure, dict(self.values))


# -- spec §8: the pneumatic model ---------------------------------------------------------------
# A pneumatic variant compiles Model 2 (constrained) with N gas cells; the valve type, the drive
# (speed or motor), the slot-pressure source and the reed's contact mode are runtime values, so
# switching any of them never recompiles.
SLOT_SOURCES = ("value", "inlet", "exhaust", "atmosphere")
VALVE_TYPES = ("check", "reed")
REED_MODES = {"free": 0.0, "seated": 1.0, "stop": 2.0}


@dataclass(frozen=True)
class PneumaticStructure:
    """A pneumatic variant: Model 2 mechanics with N gas cells ("pneumatic"), or Model 1 (penalty
    contacts, each vane's s_i and sdot_i integrated with the gas: "pneumatic-contact", with the
    contact laws of the housing and the slot bottom)."""

    vanes: int = 4
    harmonics: int = 0
    model: str = "pneumatic"
    housing_law: str = "impact"  # pneumatic-contact only
    bottom_law: str = "impact"  # pneumatic-contact only

    @property
    def contact(self) -> bool:
        return self.model == "pneumatic-contact"

    @property
    def variant(self) -> str:
        if self.contact:
            return f"pneumatic-contact-n{self.vanes}-h{self.harmonics}-{self.housing_law}-{self.bottom_law}"
        return f"pneumatic-n{self.vanes}-h{self.harmonics}"

    @property
    def mechanical(self) -> Structure:
        if self.contact:
            return Structure("contact", self.vanes, self.harmonics, self.housing_law, self.bottom_law)
        return Structure("constrained", self.vanes, self.harmonics)

    def as_dict(self) -> dict:
        d = {"model": self.model, "vanes": self.vanes, "harmonics": self.harmonics}
        if self.contact:
            d.update(housing_law=self.housing_law, bottom_law=self.bottom_law)
        return d


def _p(name, unit, lower=-math.inf, upper=math.inf, positive=False, doc=""):
    return Parameter(name, unit, lower=POSITIVE if positive else Bound(lower), upper=Bound(upper),
                     doc=doc)


def _discharge(name, opening):
    """An opening's discharge coefficient: by default the ports' value (spec §8)."""
    return Parameter(name, "-", lower=POSITIVE, upper=Bound(1.0), derived="ports.discharge_coefficient",
                     doc=f"discharge coefficient of the {opening}; default: ports.discharge_coefficient")


GAS_PARAMETERS = (
    # a metre: wider than any vane pump (the mechanical lengths' plausibility limit); 25 for 25 mm
    # would otherwise give a pump 1000x too large that turns at a few rpm without a word
    Parameter("rotor.width", "m", lower=POSITIVE, upper=Bound(1.0, label="1 m (SI: a width in mm?)"),
              doc="axial width of rotor, vanes and housing"),
    _p("gas.gas_constant", "J/(kg K)", positive=True),
    Parameter("gas.gamma", "-", lower=Bound(1.0, open=True), upper=Bound(2.0),
              doc="ratio of specific heats"),
    _p("gas.temperature", "K", positive=True, doc="atmosphere, booster and plenum temperature"),
    _p("gas.wall_temperature", "K", positive=True),
    # above ~1e5 the cells are isothermal to 2e-3 already; the bound is where the pump-down's
    # tolerances are shown converged (tests/integration/test_gas_limits.py)
    Parameter("gas.heat_transfer", "W/(m^2 K)", lower=NONNEGATIVE,
              upper=Bound(1e6, label="1e6 W/(m^2 K) (isothermal cells)"),
              doc="cell-wall film coefficient, 0 = adiabatic"),
    _p("gas.atmosphere", "Pa", positive=True, doc="atmospheric pressure"),
    _p("ports.inlet.start", "rad", doc="inlet window start, housing polar angle (housing frame)"),
    _p("ports.inlet.end", "rad"),
    Parameter("ports.inlet.width", "m", lower=POSITIVE, upper=Bound("rotor.width"),
              doc="axial width of the inlet window"),
    _p("ports.exhaust.start", "rad"),
    _p("ports.exhaust.end", "rad"),
    Parameter("ports.exhaust.width", "m", lower=POSITIVE, upper=Bound("rotor.width")),
    Parameter("ports.discharge_coefficient", "-", default=0.7, lower=POSITIVE, upper=Bound(1.0),
              doc="discharge coefficient of the inlet and exhaust windows"),
    _p("ports.inlet_volume", "m^3", positive=True, doc="inlet manifold, booster check valve to inlet "
       "window: gas with its own mass and temperature, no wall heat exchange"),
    _p("ports.exhaust_volume", "m^3", positive=True, doc="exhaust port, exhaust window to valve: gas "
       "with its own mass and temperature, no wall heat exchange"),
    _p("ports.hose_area", "m^2", positive=True, doc="booster hose orifice area"),
    _p("ports.check_cracking", "Pa", 0.0, doc="inlet check valve cracking pressure difference"),
    _p("ports.check_full_open", "Pa", positive=True, doc="inlet check valve: excess for full area"),
    _discharge("ports.hose_discharge_coefficient", "booster hose orifice"),
    _discharge("ports.check_discharge_coefficient", "booster check valve"),
    _p("valve.reed", "-", 0.0, 1.0, doc="exhaust valve: 0 check, 1 reed"),
    _p("valve.area", "m^2", positive=True, doc="check: full flow area; reed: port area (flow area cap)"),
    _p("valve.cracking", "Pa", 0.0, doc="check: cracking pressure difference"),
    _p("valve.full_open", "Pa", positive=True, doc="check: excess over cracking for full area"),
    _p("valve.mass", "kg", positive=True, doc="reed: effective mass"),
    _p("valve.stiffness", "N/m", 0.0),
    _p("valve.damping", "N s/m", 0.0),
    _p("valve.preload", "N", 0.0),
    _p("valve.lift_max", "m", positive=True, doc="reed: stop"),
    _p("valve.diameter", "m", positive=True, doc="reed: port diameter d (curtain area pi d x)"),
    _p("valve.force_area", "m^2", positive=True, doc="reed: area the pressure difference acts on"),
    _p("valve.mode", "-", 0.0, 2.0, doc="reed contact mode (runtime): 0 free, 1 seated, 2 on the stop"),
    _discharge("valve.discharge_coefficient", "exhaust valve (check or reed)"),
    Parameter("leak.tip_gap", "m", lower=NONNEGATIVE, upper=Bound(1e-3, label="1 mm")),
    Parameter("leak.end_gap", "m", lower=NONNEGATIVE, upper=Bound(1e-3, label="1 mm")),
    _discharge("leak.discharge_coefficient", "tip and end-face leak gaps"),
    _p("booster.volume", "m^3", positive=True),
    _p("booster.leak", "kg/s", 0.0, doc="booster leak mass flow at full atmospheric difference"),
    _p("vane.slot_pressure.source", "-", 0.0, 3.0, doc="0 value, 1 inlet, 2 exhaust, 3 atmosphere"),
    _p("vane.slot_pressure.value", "Pa", 0.0),
    _p("operation.motor", "-", 0.0, 1.0, doc="drive: 0 constant speed, 1 DC motor"),
    # a reversed supply turns the pump backwards: the exhaust check valve then blocks the flow,
    # Model 2's tips would need pulling and friction work turns negative -- not an EVP, refused
    _p("motor.voltage", "V", positive=True, doc="supply voltage at the motor terminals"),
    _p("motor.resistance", "ohm", positive=True),
    _p("motor.inductance", "H", positive=True),
    _p("motor.constant", "N m/A", positive=True, doc="torque and back-EMF constant k"),
    _p("motor.friction", "N m", 0.0, doc="motor friction torque"),
    _p("motor.inertia", "kg m^2", 0.0, doc="armature inertia"),
)


# Config checks loop over GAS_PARAMETERS: an entry the config sets under another key is named by
# that key; encodings (valve type, reed mode, drive, slot-pressure source) and the hose area (from
# ports.hose_diameter) are checked as the config keys that set them.
GAS_CONFIG_KEYS = {"ports.inlet.width": "ports.inlet_width", "ports.exhaust.width": "ports.exhaust_width",
                   "vane.slot_pressure.value": "vane.slot_pressure"}
GAS_ENCODED = ("valve.reed", "valve.mode", "operation.motor", "vane.slot_pressure.source",
               "ports.hose_area", "ports.inlet.start", "ports.inlet.end", "ports.exhaust.start",
               "ports.exhaust.end")


def pneumatic_layout(structure: PneumaticStructure) -> tuple[Parameter, ...]:
    """Model 2's layout followed by the gas entries (spec §8)."""
    return layout(structure.mechanical) + GAS_PARAMETERS
