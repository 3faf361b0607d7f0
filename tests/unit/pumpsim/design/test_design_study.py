"""Study files (spec §9): validation messages, distributions, samplers and seeds."""
import math

import numpy as np
import pytest
from scipy import stats

from pumpsim.design.execute import study_designs
from pumpsim.design.sampling import unit_points
from pumpsim.design.study import study_from_dict
from pumpsim.errors import ConfigError
from tests.conftest import EXAMPLES
from tests.tolerances import MEAN_SIGMAS, ROUNDING_REL, SAMPLE_MEAN_REL, SAMPLE_SD_REL, TRUNCNORM_SD_ABS

RIG = str(EXAMPLES / "test_rig.toml")


def study(vary, **st):
    return study_from_dict({"study": {"config": RIG, **st}, "vary": vary})


@pytest.mark.parametrize("raw, message", [
    ({"study": {"config": RIG}, "vary": {"vane.mas": {"values": [1e-3]}}}, 'vary."vane.mas" is not a numeric config key'),
    ({"study": {"config": RIG}, "vary": {"vane.mass": {"distribution": "gauss", "sd": 1}}}, "distribution must be one of"),
    ({"study": {"config": RIG, "sampler": "halton"}, "vary": {"vane.mass": {"values": [1e-3]}}}, "study.sampler must be one of"),
    ({"study": {"config": RIG, "samples": 0}, "vary": {"vane.mass": {"values": [1e-3]}}}, "study.samples must be an integer >= 1"),
    ({"study": {"config": RIG, "sampler": "grid"}, "vary": {"vane.mass": {"distribution": "normal", "sd": 1e-5}}}, "needs values or range for every key"),
    ({"study": {"config": RIG}, "vary": {"vane.mass": {"values": [1e-3]}}, "limits": {"torque": {"upper": 1}}}, "unknown output 'torque'"),
    ({"study": {"config": RIG}, "vary": {"vane.mass": {"values": [1e-3]}}, "limits": {"mean_torque": {"lower": 2, "upper": 1}}}, "lower (2) must be < upper (1)"),
    ({"study": {"config": RIG}, "vary": {"vane.mass": {"distribution": "truncnormal", "sd": 1e-5, "low": 2e-3, "high": 1e-3}}}, "low (0.002) must be < high (0.001)"),
    ({"study": {"config": "nope.toml"}, "vary": {"vane.mass": {"values": [1e-3]}}}, "study.config: cannot read"),
    ({"study": {"config": RIG, "speeds": [100.0]}, "vary": {"operation.speed": {"values": [1.0]}}}, "not both"),
    ({"study": {"config": RIG}, "vary": {"rotor.vanes": {"values": [2.5]}}}, "integer key"),
    ({"study": {"config": RIG}, "vary": {"contact.housing.stiffness": {"values": [1e5]}}}, "does not enter the constrained or gas model"),
    ({"study": {"config": RIG}, "vary": {"housing.a": {"values": [0.0225]}}}, 'vary."housing.a": housing.a is for shape = "ellipse"'),
    ({"study": {"config": RIG, "colour": 1}, "vary": {"vane.mass": {"values": [1e-3]}}}, "unknown key 'study.colour'"),
])
def test_bad_study_is_rejected_with_the_key(raw, message):
    with pytest.raises(ConfigError) as e:
        study_from_dict(raw)
    assert message in str(e.value)


def test_distribution_parameters_and_defaults():
    s = study({
        "housing.radius": {"distribution": "normal", "sd": 4e-6},  # mean: the config's radius
        "vane.mass": {"distribution": "lognormal", "sd": 0.05, "relative": True},
        "friction.housing.dynamic": {"distribution": "truncnormal", "sd": 0.02, "low": 0.15, "high": 0.25},
        "vane.length": {"distribution": "uniform", "low": 0.998, "high": 1.002, "relative": True},
    }, samples=4096, sampler="sobol", seed=5)
    X = study_designs(s)
    r, m, mu, L = X.T
    assert abs(r.mean() - 0.0225) < 4e-6 * MEAN_SIGMAS / math.sqrt(4096)
    assert abs(r.std() / 4e-6 - 1) < SAMPLE_SD_REL
    # lognormal with the variable's own mean and sd (5 % of 1.2 g)
    assert abs(m.mean() / 0.0012 - 1) < SAMPLE_MEAN_REL and abs(m.std() / (0.05 * 0.0012) - 1) < SAMPLE_SD_REL
    assert mu.min() >= 0.15 and mu.max() <= 0.25
    assert abs(mu.std() - stats.truncnorm(-2.5, 2.5, 0.2, 0.02).std()) < TRUNCNORM_SD_ABS
    assert L.min() >= 0.998 * 0.012 and L.max() <= 1.002 * 0.012


def test_grid_is_the_product_and_range_is_inclusive():
    s = study({"vane.mass": {"values": [1e-3, 2e-3]}, "vane.length": {"range": [0.011, 0.012, 3]}},
              sampler="grid")
    X = study_designs(s)
    assert X.shape == (6, 2)
    assert sorted(set(X[:, 1])) == pytest.approx([0.011, 0.0115, 0.012], rel=ROUNDING_REL)


def test_random_stream_per_design_does_not_depend_on_the_count():
    """Design d's values come from SeedSequence(seed, spawn_key=(d,)): the first 10 designs of a
    20-design study are the 10 designs of a 10-design study."""
    a, b = unit_points("random", 10, 3, 7), unit_points("random", 20, 3, 7)
    assert np.array_equal(a, b[:10])
    assert not np.array_equal(unit_points("random", 10, 3, 8), a)


def test_zero_spread_gives_the_mean_exactly():
    s = study({"vane.mass": {"distribution": "normal", "sd": 0.0},
               "housing.radius": {"distribution": "lognormal", "sd": 0.0}}, samples=8)
    X = study_designs(s)
    assert np.all(X[:, 0] == 0.0012) and np.all(X[:, 1] == 0.0225)


def test_study_hash_follows_the_study_and_the_config():
    a = study({"vane.mass": {"values": [1e-3]}})
    b = study({"vane.mass": {"values": [1e-3]}})
    c = study({"vane.mass": {"values": [1.1e-3]}})
    assert a.study_hash() == b.study_hash() != c.study_hash()


def test_keys_reach_registry_entries_and_derived_defaults_follow():
    from pumpsim.design.study import key_targets
    from tests.conftest import example_dict

    base = example_dict("test_rig")
    assert sorted(key_targets(base, "housing.radius", 0.0225)) == ["housing.a", "housing.b"]
    assert sorted(key_targets(base, "vane.mass", 0.0012)) == ["vane.inertia", "vane.mass"]
    assert key_targets(base, "operation.speed", 600.0) == ["speed"]
    assert key_targets(base, "rotor.vanes", 4) == ["structure"]


def test_implausible_ranges_are_warned_not_refused():
    s = study({"friction.housing.dynamic": {"values": [0.2, 1.5]}, "vane.mass": {"values": [0.0012]}},
              sampler="grid")
    # the rig has no [friction.slot]: its slot COF follows the housing's, and is named too
    assert len(s.warnings) == 2 and all("plausible range [0, 1]" in w for w in s.warnings)
    assert "reaches friction.housing.dynamic = 1.5" in s.warnings[0]
    assert "reaches friction.slot.dynamic = 1.5" in s.warnings[1]
    assert study({"vane.mass": {"distribution": "normal", "sd": 0.02, "relative": True}}).warnings == []
