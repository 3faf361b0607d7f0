"""The parameter registry: config validation, fit bounds and derived defaults are loops over it."""
import math

import numpy as np
import pytest

from pumpsim.config import config_from_dict
from pumpsim.data import Dataset
from pumpsim.errors import ConfigError
from pumpsim.identification import ConstantSpeedProblem
from pumpsim.model_spec import parameters as reg
from tests.conftest import apply_changes, example_dict, make_config
from tests.tolerances import ROUNDING_REL, SEED_REL

# config keys whose registry entry has a numeric bound: a value beyond it must be refused, and the
# message must name the key (entries given in another form -- lists, the housing size -- aside)
def _numeric(bound):
    return not isinstance(bound.value, str) and math.isfinite(bound.value)


BOUNDED = [q for q in reg.ROTOR + reg.VANE + reg.EFFECTS + reg.OPERATION + reg._friction("housing")
           if _numeric(q.lower) or _numeric(q.upper)]


@pytest.mark.parametrize("q", BOUNDED, ids=lambda q: q.name)
def test_every_numeric_bound_is_enforced_by_the_config(q):
    bad = q.lower.value - 1.0 if _numeric(q.lower) else q.upper.value + 1.0
    with pytest.raises(ConfigError) as e:
        config_from_dict(apply_changes(example_dict(), {q.name: bad}))
    assert q.name in str(e.value) and "must be" in str(e.value)


def test_cof_bound_is_the_friction_entries_bound_for_every_fit_name():
    st = reg.Structure()
    for name in ("mu", "mu_slot", "friction.housing.static", "friction.slot.dynamic"):
        assert reg.fit_bounds(name, st) == (0.0, 2.0)
    assert reg.fit_bounds("housing.radius", st) == reg.fit_bounds("housing.a", st) == (0.0, math.inf)
    assert reg.fit_bounds("lag", st) == (0.0, math.inf)
    assert reg.fit_bounds("theta0", st) == (-math.inf, math.inf)


def test_derived_inertia_follows_the_mass_unless_the_file_sets_it():
    cfg = make_config()
    L, h = cfg.values["vane.length"], cfg.values["vane.thickness"]
    heavier = cfg.with_values({"vane.mass": 0.002})
    assert heavier.values["vane.inertia"] == pytest.approx(0.002 * (L**2 + h**2) / 12, rel=ROUNDING_REL)
    fixed = make_config(**{"vane.inertia": 3e-8}).with_values({"vane.mass": 0.002})
    assert fixed.values["vane.inertia"] == 3e-8


def test_fitted_mass_carries_the_derived_inertia_into_the_kernel():
    cfg = make_config()
    t = np.arange(200) / 10000.0
    prob = ConstantSpeedProblem(cfg, Dataset(t, np.zeros_like(t)), ["vane.mass", "mu"])
    p = np.asarray(prob.parameter_vector(np.array([0.002, 0.2]))).ravel()
    names = cfg.parameters().names
    L, h = cfg.values["vane.length"], cfg.values["vane.thickness"]
    assert p[names.index("vane.mass")] == 0.002
    assert p[names.index("vane.inertia")] == pytest.approx(0.002 * (L**2 + h**2) / 12, rel=ROUNDING_REL)
    # and the seed matrix (dz/dx) carries d inertia / d mass
    col = prob._seeds[:, 0]
    assert col[names.index("vane.inertia")] == pytest.approx((L**2 + h**2) / 12, rel=SEED_REL)


def test_measurement_registry_orders_the_fit_graph_inputs():
    assert reg.KERNEL_GRAPH_INPUTS == ("theta0", "speed", "delay", "torque_offset", "ripple_cos",
                                       "ripple_sin")
    assert reg.MEASUREMENT_BY_NAME["theta0"].period == pytest.approx(2 * math.pi, rel=ROUNDING_REL)
    assert reg.MEASUREMENT_BY_NAME["speed"].band == 0.5


def test_derive_evaluates_formulas_with_dotted_names_and_decimals():
    assert reg.derive("0.5 * vane.mass + vane.length", {"vane.mass": 2.0, "vane.length": 0.25}) == 1.25
    assert reg.derived_inputs(reg.VANE[3].derived) == ["vane.mass", "vane.length", "vane.thickness"]


def test_plausibility_ranges_flag_valid_but_unusual_values():
    cfg = make_config()
    assert reg.implausible(cfg.values) == []  # the bundled rig is an ordinary pump
    odd = reg.implausible({**cfg.values, "friction.housing.dynamic": 1.4, "vane.length": 0.08})
    assert len(odd) == 2 and any("friction.housing.dynamic = 1.4" in m for m in odd)
    assert any(m.startswith("vane.length = 0.08 m") for m in odd)
