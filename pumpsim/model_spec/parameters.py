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
