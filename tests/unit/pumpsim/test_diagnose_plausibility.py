"""Issue 11, Build 2: every fitted quantity's physical range is declared once, with its parameter,
in the registry; diagnose only maps its parametrisation (harmonic pairs, mu x factor) onto it."""
import math

import pytest

from bench.diagnose_grid import rig
from pumpsim.diagnosis import clearance, plausible
from pumpsim.model_spec import parameters as reg

TORQUE_RMS, MEAN_TORQUE = 0.14, 0.13  # N m, the test rig's scale


@pytest.fixture(scope="module")
def cfg():
    return rig("concentric4")


def test_context_formulas_are_evaluated_and_skipped_without_context(cfg):
    ctx = {"clearance": clearance(cfg), "speed": cfg.speed, "vanes": cfg.vanes}
    lag_max = 1 / (cfg.vanes * cfg.speed)
    assert reg.implausible({"lag": 0.99 * lag_max}, context=ctx) == []
    assert len(reg.implausible({"lag": 1.01 * lag_max}, context=ctx)) == 1
    assert reg.implausible({"lag": 1.0}) == []  # no context: a relative bound is not checked


def test_eccentricity_is_bounded_as_a_norm_by_the_clearance(cfg):
    c = clearance(cfg)
    inside = 0.99 * c / math.sqrt(2)
    assert plausible(cfg, {"housing.center.0": inside, "housing.center.1": inside}, TORQUE_RMS, MEAN_TORQUE) == []
    out = 1.01 * c / math.sqrt(2)  # each component below the clearance, their norm above it
    msgs = plausible(cfg, {"housing.center.0": out, "housing.center.1": out}, TORQUE_RMS, MEAN_TORQUE)
    assert len(msgs) == 1 and msgs[0].startswith("eccentricity") and "clearance" in msgs[0]


def test_an_out_of_round_order_is_its_slot_pair_amplitude(cfg):
    cfg2 = cfg.with_harmonics([[2, 0.0, 0.0], [2, 0.0, math.pi / 4]])
    a = 0.2 * clearance(cfg)  # each slot below a quarter of the clearance, their hypot above
    msgs = plausible(cfg2, {"housing.harmonics.0.amplitude": a, "housing.harmonics.1.amplitude": a},
                     TORQUE_RMS, MEAN_TORQUE)
    assert len(msgs) == 1 and msgs[0].startswith("out-of-round k=2 amplitude"), msgs


def test_vane_factor_range_and_its_cof(cfg):
    assert plausible(cfg, {"mu": 0.2, "effects.vane_friction_factor.1": 4.0}, TORQUE_RMS, MEAN_TORQUE) == []
    assert len(plausible(cfg, {"mu": 0.3, "effects.vane_friction_factor.1": 4.0}, TORQUE_RMS, MEAN_TORQUE)) == 1
    assert len(plausible(cfg, {"mu": 0.2, "effects.vane_friction_factor.1": 0.1}, TORQUE_RMS, MEAN_TORQUE)) == 1


def test_one_range_per_quantity():
    """The COF, the vane factor and the ripple have one declaration each (no second copy in diagnose)."""
    r = reg.registry()
    assert r["friction.housing.dynamic"].plausible == (0.0, 1.0)
    assert r["effects.vane_friction_factor.1"].plausible == (0.2, 5.0)
    assert reg.MEASUREMENT_BY_NAME["ripple_cos"].plausible == reg.MEASUREMENT_BY_NAME["ripple_sin"].plausible
    for q in list(r.values()) + list(reg.MEASUREMENT):
        if q.plausible is not None:
            assert q.plausible_why or q.name.split(".")[0] in ("rotor", "vane", "housing", "friction"), q.name
