"""A measured speed is evidence, not only a mean: a speed ripple the torque suggests is named only
when the speed column shows it."""
import dataclasses

import numpy as np
import pytest

import pumpsim
from pumpsim.data import Dataset
from pumpsim.diagnosis import diagnose
from tests.conftest import make_config


@pytest.mark.slow
def test_a_ripple_is_named_with_a_rippled_column_and_refused_with_a_flat_one():
    nominal = dataclasses.replace(make_config("ellipse_4vanes"), angle=0.4)
    truth = dataclasses.replace(nominal, speed_ripple=(1, 0.005, 0.5))
    r = pumpsim.simulate(truth, duration=0.1, rate=10000)
    rng = np.random.default_rng(1)
    y = r.torque + rng.normal(0, 0.02 * np.std(r.torque), r.torque.size)
    rippled = diagnose(nominal, Dataset(r.time, y, speed=r.speed + rng.normal(0, 0.2, y.size))).to_json()
    assert rippled["effects"] == ["speed_ripple"]
    flat = diagnose(nominal, Dataset(r.time, y, speed=np.full(y.size, nominal.speed) + rng.normal(0, 0.2, y.size)))
    flat = flat.to_json()
    assert "speed_ripple" not in flat["effects"]
    assert flat["unexplained"]  # the torque still shows what the model lacks: said, not hidden
    assert any("speed column disagrees" in n for n in flat["notes"])
