"""The parameter registry: every number the compiled model uses, declared once.

The stacked runtime vector `p` follows declaration order. Only *structure* (model type, vane count,
number of housing-harmonic slots, contact laws) changes the compiled kernel; every value here is an
entry of `p`, so changing it never recompiles.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field

from ..errors import ConfigError

INF = math.inf


@dataclass(frozen=True)
class Parameter:
    name: str  # config key path, e.g. "vane.mass"
    unit: str
    lower: float = -INF
    upper: float = INF
    positive: bool = False  # strictly > 0 (masses, lengths)
    doc: str = ""


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


def _friction(prefix: str) -> list[Parameter]:
    return [
        Parameter(f"{prefix}.static", "-", 0.0, 2.0, doc="static COF"),
        Parameter(f"{prefix}.dynamic", "-", 0.0, 2.0, doc="dynamic COF"),
        Parameter(f"{prefix}.v_static", "m/s", positive=True, doc="static transition speed"),
        Parameter(f"{prefix}.v_dynamic", "m/s", positive=True, doc="dynamic transition speed"),
    ]


def _contact(prefix: str) -> list[Parameter]:
    return [
        Parameter(f"{prefix}.stiffness", "N/m^e", positive=True),
        Parameter(f"{prefix}.exponent", "-", positive=True),
        Parameter(f"{prefix}.damping", "N s/m", 0.0),
        Parameter(f"{prefix}.depth", "m", positive=True, doc="IMPACT damping ramp depth"),
    ]


def layout(structure: Structure) -> tuple[Parameter, ...]:
    """Ordered parameter declarations for one compiled variant."""
    ps = [
        Parameter("rotor.radius", "m", positive=True),
        Parameter("rotor.inertia", "kg m^2", positive=True),
        Parameter("rotor.slot_radius", "m", 0.0),
        Parameter("rotor.slot_tilt", "rad", -math.pi / 2, math.pi / 2),
        Parameter("rotor.first_slot_angle", "rad"),
        Parameter("vane.length", "m", positive=True),
        Parameter("vane.thickness", "m", positive=True),
        Parameter("vane.mass", "kg", positive=True),
        Parameter("vane.inertia", "kg m^2", positive=True),
        Parameter("vane.tip_radius", "m", 0.0),
        Parameter("housing.a", "m", positive=True, doc="semi-axis along housing x (circle: radius)"),
        Parameter("housing.b", "m", positive=True, doc="semi-axis along housing y (circle: radius)"),
        Parameter("housing.center.0", "m"),
        Parameter("housing.center.1", "m"),
        Parameter("housing.angle", "rad"),
    ]
    for j in range(structure.harmonics):
        ps += [
            Parameter(f"housing.harmonics.{j}.order", "-", 0.0),
            Parameter(f"housing.harmonics.{j}.amplitude", "m"),
            Parameter(f"housing.harmonics.{j}.phase", "rad"),
        ]
    ps += _friction("friction.housing") + _friction("friction.slot")
    ps += [Parameter("operation.bearing_torque", "N m")]
    # Effect parameters: zero (or one, for factors) means "absent".
    ps += [Parameter("effects.viscous_tip_friction", "N s/m", 0.0, doc="tip force per slip speed")]
    ps += [Parameter(f"effects.vane_friction_factor.{i}", "-", 0.0, doc="per-vane housing-COF factor")
           for i in range(structure.vanes)]
    if structure.model == "contact":
        ps += _contact("contact.housing") + _contact("contact.bottom")
    return tuple(ps)


@dataclass
class ParameterVector:
    """Values by name, stacked in declaration order on demand."""

    structure: Structure
    values: dict = field(default_factory=dict)

    @property
    def names(self) -> list[str]:
        return [p.name for p in layout(self.structure)]

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
    """A pneumatic variant: Model 2 mechanics with N gas cells."""

    vanes: int = 4
    harmonics: int = 0
    model: str = "pneumatic"

    @property
    def variant(self) -> str:
        return f"pneumatic-n{self.vanes}-h{self.harmonics}"

    @property
    def mechanical(self) -> Structure:
        return Structure("constrained", self.vanes, self.harmonics)

    def as_dict(self) -> dict:
        return {"model": self.model, "vanes": self.vanes, "harmonics": self.harmonics}


def _p(name, unit, lower=-math.inf, upper=math.inf, positive=False, doc=""):
    return Parameter(name, unit, lower, upper, positive, doc)


GAS_PARAMETERS = (
    _p("rotor.width", "m", positive=True, doc="axial width of rotor, vanes and housing"),
    _p("gas.gas_constant", "J/(kg K)", positive=True),
    _p("gas.gamma", "-", 1.0, 2.0, doc="ratio of specific heats"),
    _p("gas.temperature", "K", positive=True, doc="atmosphere, booster and plenum temperature"),
    _p("gas.wall_temperature", "K", positive=True),
    _p("gas.heat_transfer", "W/(m^2 K)", 0.0, doc="cell-wall film coefficient, 0 = adiabatic"),
    _p("gas.atmosphere", "Pa", positive=True, doc="atmospheric pressure"),
    _p("ports.inlet.start", "rad", doc="inlet window start, housing polar angle (housing frame)"),
    _p("ports.inlet.end", "rad"),
    _p("ports.inlet.width", "m", 0.0, doc="axial width of the inlet window"),
    _p("ports.exhaust.start", "rad"),
    _p("ports.exhaust.end", "rad"),
    _p("ports.exhaust.width", "m", 0.0),
    _p("ports.discharge_coefficient", "-", 0.0, 1.0),
    _p("ports.inlet_volume", "m^3", positive=True, doc="inlet manifold between hose and window"),
    _p("ports.exhaust_volume", "m^3", positive=True, doc="exhaust port volume under the valve"),
    _p("ports.hose_area", "m^2", 0.0, doc="booster hose orifice area"),
    _p("ports.check_cracking", "Pa", 0.0, doc="inlet check valve cracking pressure difference"),
    _p("ports.check_full_open", "Pa", positive=True, doc="inlet check valve: excess for full area"),
    _p("valve.reed", "-", 0.0, 1.0, doc="exhaust valve: 0 check, 1 reed"),
    _p("valve.area", "m^2", 0.0, doc="check: full flow area; reed: port area (flow area cap)"),
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
    _p("leak.tip_gap", "m", 0.0),
    _p("leak.end_gap", "m", 0.0),
    _p("leak.discharge_coefficient", "-", 0.0, 1.0),
    _p("booster.volume", "m^3", positive=True),
    _p("booster.leak", "kg/s", 0.0, doc="booster leak mass flow at full atmospheric difference"),
    _p("vane.slot_pressure.source", "-", 0.0, 3.0, doc="0 value, 1 inlet, 2 exhaust, 3 atmosphere"),
    _p("vane.slot_pressure.value", "Pa", 0.0),
    _p("operation.motor", "-", 0.0, 1.0, doc="drive: 0 constant speed, 1 DC motor"),
    _p("motor.voltage", "V"),
    _p("motor.resistance", "ohm", positive=True),
    _p("motor.inductance", "H", positive=True),
    _p("motor.constant", "N m/A", positive=True, doc="torque and back-EMF constant k"),
    _p("motor.friction", "N m", 0.0, doc="motor friction torque"),
    _p("motor.inertia", "kg m^2", 0.0, doc="armature inertia"),
)


def pneumatic_layout(structure: PneumaticStructure) -> tuple[Parameter, ...]:
    """Model 2's layout followed by the gas entries (spec §8)."""
    return layout(structure.mechanical) + GAS_PARAMETERS
