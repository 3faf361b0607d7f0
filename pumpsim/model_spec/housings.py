"""The housing-shape registry: every shape `housing.shape` may name, declared once.

The compiled kernels know one family of housing curves: about the centre `housing.center`,
turned by `housing.angle` (psi), the polar radius is an ellipse's with semi-axes `housing.a`,
`housing.b` plus the out-of-round terms `housing.harmonics` (codegen/housing.py). A shape is a
way to give the base curve in the user's terms: its config keys under [housing] and, for each,
the compiled parameters it sets (parameter = factor x value). Config validation, its messages,
the fit and study aliases (`housing.radius` sets both semi-axes) and the configuration reference
are loops over `SHAPES`; a new shape within the family is one `HousingShape` here.

`radius` is the shape's closed form r(beta) about its centre at beta = alpha - psi, harmonics
left out: the tests compare it with the compiled housing curve.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable


PREFIX = "housing."
COMPILED = ("housing.a", "housing.b")  # the base curve's parameters a shape sets


@dataclass(frozen=True)
class ShapeKey:
    """A config key under [housing] and the compiled parameters it sets."""

    name: str  # key under [housing], e.g. "radius"
    sets: tuple  # ((compiled parameter, factor), ...): parameter = factor * value
    doc: str  # for the configuration reference

    @property
    def path(self) -> str:
        return PREFIX + self.name


@dataclass(frozen=True)
class HousingShape:
    name: str  # the value of housing.shape
    article: str  # how a message names it: "a circle"
    keys: tuple  # ShapeKey, ...: all required for this shape
    radius: Callable  # (key values by name, beta) -> r about the centre, harmonics left out
    description: str  # for the configuration reference
    example: dict  # key values by name of a realistic pump (the reference's and the tests')
    check: Callable | None = None  # (key values by name) -> a message naming the keys, or None

    def parameters(self, given: dict) -> dict:
        """The compiled parameters from the key values by name."""
        return {target: factor * float(given[k.name]) for k in self.keys for target, factor in k.sets}

    def key_setting(self, parameter: str):
        """(ShapeKey, factor) of the key that sets compiled `parameter`, or None."""
        for k in self.keys:
            for target, factor in k.sets:
                if target == parameter:
                    return k, factor
        return None

    @property
    def takes(self) -> str:
        """'a circle takes housing.radius'."""
        return f"{self.article} takes {_and([k.path for k in self.keys])}"


def _and(items) -> str:
    items = list(items)
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} and {items[-1]}"


def _or(items) -> str:
    items = list(items)
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} or {items[-1]}"


def _ellipse(a, b, beta):
    import numpy as np  # here, not at import: the contract loads with the command line's start

    return a * b / np.sqrt((b * np.cos(beta)) ** 2 + (a * np.sin(beta)) ** 2)


def _circle(r, beta):
    import numpy as np

    return r + 0.0 * np.asarray(beta)


CIRCLE = HousingShape(
    "circle", "a circle",
    (ShapeKey("radius", (("housing.a", 1.0), ("housing.b", 1.0)),
              "Radius of a circular housing (sets both semi-axes)"),),
    radius=lambda v, beta: _circle(v["radius"], beta),
    description="a cylindrical bore", example={"radius": 0.0225})
ELLIPSE = HousingShape(
    "ellipse", "an ellipse",
    (ShapeKey("a", (("housing.a", 1.0),), "Semi-axis along the housing x axis"),
     ShapeKey("b", (("housing.b", 1.0),), "Semi-axis along the housing y axis")),
    radius=lambda v, beta: _ellipse(v["a"], v["b"], beta),
    description="an elliptic bore", example={"a": 0.0235, "b": 0.0215})

SHAPES = {s.name: s for s in (CIRCLE, ELLIPSE)}


def keys() -> dict:
    """Every shape key's name -> the shapes that take it, over the registry as it is now."""
    out: dict = {}
    for shape in SHAPES.values():
        for k in shape.keys:
            out.setdefault(k.name, []).append(shape.name)
    return out


def key(name: str) -> ShapeKey | None:
    """The declaration of shape key `name` (under [housing]), or None."""
    for shape in SHAPES.values():
        for k in shape.keys:
            if k.name == name:
                return k
    return None


def shape_names() -> str:
    """'"circle" or "ellipse"'."""
    return _or([f'"{name}"' for name in SHAPES])


def unknown_shape(got) -> str:
    """The message for a housing.shape that names no registered shape."""
    takes = "; ".join(s.takes for s in SHAPES.values())
    return f"housing.shape must be {shape_names()}, got {got!r} ({takes})"


def foreign_key(name: str, shape: HousingShape) -> str:
    """The message for key housing.`name` given with a shape that does not take it."""
    owners = _or([f'"{s}"' for s in keys()[name]])
    return f"{PREFIX}{name} is for shape = {owners}; {shape.takes}"


def aliases() -> dict:
    """Key path -> the compiled parameters it sets, for the keys that set several with factor
    one (housing.radius: both semi-axes): a fit or a study may name them as one parameter."""
    out = {}
    for shape in SHAPES.values():
        for k in shape.keys:
            targets = tuple(t for t, _ in k.sets)
            if len(targets) > 1 and all(f == 1.0 for _, f in k.sets):
                out[k.path] = targets
    return out


def config_key(shape_name: str, parameter: str) -> tuple[str, float]:
    """(config key path, factor) through which a config of `shape_name` sets compiled
    `parameter` (the parameter itself, factor 1, when the shape does not set it)."""
    found = SHAPES[shape_name].key_setting(parameter) if shape_name in SHAPES else None
    return (found[0].path, found[1]) if found else (parameter, 1.0)
