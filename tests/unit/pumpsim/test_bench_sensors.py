"""The bench's sensors as the model's output mapping (identification.bench_sensors) and the bench
diagnosis's mean-level detector, which sees a channel read off everywhere."""
import numpy as np
import pytest

from pumpsim.diagnosis.pump_effects import BY_NAME, PSEUDO
from pumpsim.diagnosis.pump_workflow import mean_level
from pumpsim.identification import bench_sensors as S


def test_read_maps_each_channel_by_its_own_sensor():
    ch = {"booster_pressure": np.array([100e3, 50e3]), "current": np.array([10.0, 8.0]), "speed": np.array([300.0])}
    v = {"sensor.current_gain": 1.05, "sensor.pressure_gain": 1.03, "sensor.pressure_offset": 1500.0}
    out = S.read(ch, v)
    assert out["booster_pressure"] == pytest.approx([1.03 * 100e3 + 1500.0, 1.03 * 50e3 + 1500.0])
    assert out["current"] == pytest.approx([10.5, 8.4])
    assert out["speed"] == pytest.approx([300.0])  # no sensor figure: read as it is
    assert not S.calibrated(v) and S.calibrated({}) and S.calibrated({"sensor.pressure_gain": 1.0})


def test_the_start_reading_maps_back_to_the_booster_pressure_behind_it():
    v = {"sensor.pressure_gain": 1.03, "sensor.pressure_offset": 1500.0}
    reading = S.read({"booster_pressure": np.array([101325.0])}, v)["booster_pressure"][0]
    assert S.true_start(reading, v) == pytest.approx(101325.0)
    assert S.true_start(reading, {}) == reading


def test_the_sensor_effects_are_library_effects_on_their_own_names():
    for effect, param, absent in (("current_gain", "sensor.current_gain", 1.0),
                                  ("pressure_gain", "sensor.pressure_gain", 1.0),
                                  ("pressure_offset", "sensor.pressure_offset", 0.0)):
        e = BY_NAME[effect]
        assert e.param == param and e.absent_value(None) == absent and param in PSEUDO and e.separate


def test_mean_level_sees_a_relevant_bias_and_ignores_a_small_one():
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(250)
    assert mean_level(noise, 1.0, 0.5)["p_value"] == 1.0
    biased = mean_level(noise + 0.8, 1.0, 0.5)
    assert biased["p_value"] < 1e-20 and biased["mean"] == pytest.approx(0.8, abs=0.15)
    # significant (z ~ 5) but below the relevance floor: no finding
    small = mean_level(noise - np.mean(noise) + 0.3, 1.0, 0.5)
    assert abs(small["z"]) > 4 and small["p_value"] == 1.0
