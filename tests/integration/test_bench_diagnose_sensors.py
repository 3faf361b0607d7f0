"""The bench's sensors in `pumpsim diagnose CONFIG LOG` (pump_effects, identification.bench_sensors):
the twin logs of test_bench_diagnose (0.5 s, 0.5 % noise, seed 1) read by a miscalibrated sensor.
A current shunt 5 % high is named (the mean-level detector sees what the vane COF leaves of it);
a pressure sensor's span or offset is named when the booster's start is known (atmosphere_known),
and from the pump-down curve alone it is named or reported `confounded` with the pump effect that
reads the same, with the check that separates them -- never a pump effect alone. ~1 min each: slow."""
import pytest

from tests.integration.test_bench_diagnose import cfg, diagnosed  # noqa: F401  (cfg: the module's fixture)

SENSOR_FAULTS = {"current_gain": 0.05, "pressure_gain": 0.03, "pressure_offset": 1500.0}
CHECKS = {"pressure_gain": "reference gauge", "pressure_offset": "barometer"}


def test_a_clean_log_with_a_known_start_names_no_sensor(cfg):  # noqa: F811
    res = diagnosed(cfg, None, 0.0, atmosphere_known=True)
    assert res.effects == [] and res.confounded == [] and not res.unexplained, str(res)
    assert "booster.pressure" not in res.baseline["params"]  # known: not fitted


@pytest.mark.slow
def test_a_current_shunt_reading_high_is_named(cfg):  # noqa: F811
    res = diagnosed(cfg, "current_gain", SENSOR_FAULTS["current_gain"])
    assert res.effects == ["current_gain"] and not res.unexplained, str(res)
    assert res.steps[0].params["change"] == pytest.approx(0.05, rel=0.3), str(res)
    # the vane COF no longer carries the shunt's error (the baseline read it as mu +8 %)
    assert res.final["params"]["mu"]["value"] == pytest.approx(0.17, rel=0.03), str(res)


@pytest.mark.slow
@pytest.mark.parametrize("fault", ["pressure_gain", "pressure_offset"])
def test_a_pressure_sensor_error_is_named_when_the_start_is_known(cfg, fault):  # noqa: F811
    res = diagnosed(cfg, fault, SENSOR_FAULTS[fault], atmosphere_known=True)
    assert res.effects == [fault] and not res.unexplained, str(res)
    assert res.steps[0].params["change"] == pytest.approx(SENSOR_FAULTS[fault], rel=0.3), str(res)


@pytest.mark.slow
@pytest.mark.parametrize("fault", ["pressure_gain", "pressure_offset"])
def test_a_pressure_sensor_error_from_the_curve_alone_is_never_a_pump_effect(cfg, fault):  # noqa: F811
    res = diagnosed(cfg, fault, SENSOR_FAULTS[fault])
    assert res.effects in ([], [fault]), str(res)
    if not res.effects:
        assert any(fault in pair for pair in res.confounded), str(res)
        assert "confounded" in res.verdict and any(CHECKS[fault] in n for n in res.notes), str(res)


@pytest.mark.slow
def test_a_late_valve_is_named_when_the_start_is_known(cfg):  # noqa: F811
    """From the curve alone a valve 10 kPa late and a span 5.7 % high read the same (confounded);
    a known start tells them apart: the span would scale the start, the valve does not move it."""
    res = diagnosed(cfg, "valve_late", 10000.0, atmosphere_known=True)
    assert res.effects == ["valve_late"] and not res.consistency["fires"], str(res)
    assert not any("assuming calibrated sensors" in n for n in res.notes)
