"""The housing-shape registry: every shape's keys reach the compiled housing curve as its closed
form says, messages list the registered shapes, and a shape declared at run time is accepted by
config validation with nothing else changed."""
import copy
import math

import numpy as np
import pytest

from pumpsim.config import as_array, config_from_dict
from pumpsim.errors import ConfigError
from pumpsim.kernels import load_kernels
from pumpsim.model_spec import housings
from pumpsim.model_spec.housings import HousingShape, ShapeKey
from tests.conftest import example_dict

# a circle given by its diameter: the shape a test may add without touching any module
ROUND = HousingShape(
    "round", "a round bore",
    (ShapeKey("diameter", (("housing.a", 0.5), ("housing.b", 0.5)), "Bore diameter"),),
    radius=lambda v, beta: 0.5 * v["diameter"] + 0.0 * np.asarray(beta),
    description="a cylindrical bore given by its diameter", example={"diameter": 0.045})
# rounding of r(alpha): a handful of operations on values ~2e-2 m, compiled vs NumPy
CURVE_REL = 1e-12


@pytest.fixture
def with_round(monkeypatch):
    monkeypatch.setitem(housings.SHAPES, ROUND.name, ROUND)
    return ROUND


def _raw(shape: HousingShape, **keys) -> dict:
    """The bundled test rig with its [housing] table given as `shape` (its example, or `keys`)."""
    raw = copy.deepcopy(example_dict("test_rig"))
    housing = {"shape": shape.name, "center": [4e-4, -2e-4], "angle": 0.3}
    raw["housing"] = {**housing, **(keys or shape.example)}
    return raw


def _kernel_radius(cfg, alpha):
    pv = cfg.parameters("constrained")
    kern = load_kernels(pv.structure)
    _, _, r, _ = kern.mapped("housing_curve", alpha.size)(alpha[None, :], as_array(pv).reshape(-1, 1))
    return np.asarray(r).ravel()


def _round_trip(shape):
    cfg = config_from_dict(_raw(shape))
    alpha = np.linspace(-math.pi, math.pi, 64, endpoint=False)
    expected = shape.radius(shape.example, alpha - cfg.values["housing.angle"])
    np.testing.assert_allclose(_kernel_radius(cfg, alpha), expected, rtol=CURVE_REL, atol=0)
    return cfg


@pytest.mark.parametrize("name", list(housings.SHAPES))
def test_every_registered_shape_reaches_the_compiled_curve_as_its_closed_form(name):
    shape = housings.SHAPES[name]
    assert set(shape.example) == {k.name for k in shape.keys}
    cfg = _round_trip(shape)
    assert cfg.shape == name


def test_the_closed_forms_differ_where_the_shapes_do():
    # guards the round trip against a closed form that ignores its keys: the ellipse's radius is
    # a at beta = 0 and b at beta = pi/2
    ell = housings.SHAPES["ellipse"]
    r = ell.radius({"a": 0.03, "b": 0.02}, np.array([0.0, math.pi / 2]))
    np.testing.assert_allclose(r, [0.03, 0.02], rtol=1e-15)


def test_an_unknown_shape_lists_the_registered_ones_and_their_keys(with_round):
    raw = _raw(housings.SHAPES["circle"])
    raw["housing"]["shape"] = "square"
    with pytest.raises(ConfigError) as e:
        config_from_dict(raw)
    msg = str(e.value)
    assert msg.startswith('housing.shape must be "circle", "ellipse" or "round", got \'square\'')
    for shape in housings.SHAPES.values():
        assert shape.takes in msg  # "a circle takes housing.radius", ...


def test_a_shape_declared_at_run_time_is_validated_from_its_declaration(with_round):
    cfg = _round_trip(with_round)
    circle = config_from_dict(_raw(housings.SHAPES["circle"], radius=0.0225))
    assert cfg.parameters().values == circle.parameters().values  # the same bore, compiled alike
    rejections = [
        ({"diameter": 0.039}, "housing.diameter must be > 2 * rotor.radius (0.0400 m), got 0.0390"),
        ({}, "missing required key 'housing.diameter' (shape = \"round\")"),
        ({"diameter": 0.045, "radius": 0.0225},
         'housing.radius is for shape = "circle"; a round bore takes housing.diameter'),
        ({"diameter": "wide"}, "'housing.diameter' must be a number, got 'wide'"),
    ]
    for keys, message in rejections:
        raw = _raw(with_round)
        raw["housing"] = {"shape": "round", **keys}
        with pytest.raises(ConfigError, match=None) as e:
            config_from_dict(raw)
        assert str(e.value) == message
    raw = _raw(housings.SHAPES["circle"])
    raw["housing"]["diameter"] = 0.045
    with pytest.raises(ConfigError, match='housing.diameter is for shape = "round"; a circle takes housing.radius'):
        config_from_dict(raw)


def test_a_key_that_sets_both_semi_axes_is_a_fit_and_study_alias():
    from pumpsim.model_spec.parameters import alias_targets

    assert alias_targets("housing.radius") == ("housing.a", "housing.b")
    assert alias_targets("housing.a") == ()  # the ellipse's keys are the parameters themselves
    assert housings.config_key("circle", "housing.b") == ("housing.radius", 1.0)
    assert housings.config_key("ellipse", "housing.b") == ("housing.b", 1.0)
