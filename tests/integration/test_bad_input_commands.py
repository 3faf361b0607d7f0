"""Inputs a user can get wrong on the study, solver-study, pump-down and fit commands: each refused
before any work with exit 2, naming the key, flag or file and the fix, and nothing written; and
figures that do not exist (a speed-driven pump-down's supply energy) reported as absent, not 0."""
from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest

from pumpsim.config import config_from_dict
from pumpsim.errors import ConfigError
from pumpsim.pneumatics import pumpdown as pdm
from pumpsim.plausibility import check_config
from pumpsim.solver_study import default_rows
from tests.conftest import EXAMPLES, apply_changes, example_dict, toml_text
from tests.integration.test_bad_input import _debug, run  # noqa: F401  (_debug: the autouse fixture)
from tests.pneumatic_helpers import speed_config

RIG = EXAMPLES / "test_rig.toml"
RIG_DATA = EXAMPLES / "data" / "test_rig_measurement.csv"
STUDY = EXAMPLES / "studies" / "test_rig_tolerances.toml"


def _study_beside_its_config(tmp_path):
    shutil.copy(RIG, tmp_path / "base.toml")
    text = STUDY.read_text().replace('config = "../test_rig.toml"', 'config = "base.toml"')
    (tmp_path / "s.toml").write_text(text)
    return tmp_path / "s.toml", tmp_path / "base.toml"


@pytest.mark.parametrize("command,flag", [("sweep", "--csv"), ("sensitivity", "--json"), ("optimize", "--json")])
def test_a_study_output_onto_its_base_config_is_refused(tmp_path, capsys, command, flag):
    study, base = _study_beside_its_config(tmp_path)
    before = base.read_bytes()
    code, _, err = run(capsys, command, study, flag, base)
    assert code == 2 and "is an input file of this run" in err and flag in err, err
    assert base.read_bytes() == before


@pytest.mark.parametrize("argv,message", [
    (["sweep", STUDY, "--batch-size", "0"], "--batch-size must be >= 1, got 0"),
    (["sweep", STUDY, "--batch-size", "-1"], "--batch-size must be >= 1, got -1"),
    (["sweep", STUDY, "--workers", "0"], "--workers must be >= 1, got 0"),
    (["sensitivity", STUDY, "--samples", "0"], "--samples must be >= 2, got 0"),
    (["sensitivity", STUDY, "--samples", "1"], "--samples must be >= 2, got 1"),
    (["optimize", STUDY, "--max-iter", "0"], "--max-iter must be >= 1, got 0"),
    (["study", RIG, "--revolutions", "0.3"], "--revolutions must be >= 2"),
])
def test_flag_values_that_would_mean_nothing_are_refused(capsys, argv, message):
    code, _, err = run(capsys, *argv)
    assert code == 2 and message in err, err


def test_the_solver_study_of_a_gas_config_keeps_the_settings_the_gas_model_takes():
    gas = speed_config()
    rows = default_rows(gas)
    assert rows and all("max_step" not in r and r.get("method", "cvodes") == "cvodes" for r in rows)
    dry = config_from_dict(example_dict("startup_ellipse"))
    assert len(default_rows(dry)) == len(rows) + 2  # the maximum-step and the Runge-Kutta rows


def _rig_columns():
    lines = [ln for ln in RIG_DATA.read_text().splitlines() if ln and not ln.startswith("#")]
    return np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]])


@pytest.mark.parametrize("transform,header,message", [
    (lambda a: a, "time,torque [N*mm],speed", "the torque looks like N*m, but the torque unit option or the header says N*mm"),
    (lambda a: a * [1, -1, 1], "time,torque,speed", "the torque sensor's sign is reversed; negate the torque column"),
    (lambda a: a * [1, 1, -1], "time,torque,speed", "the speed sensor's sign is reversed; negate the speed column"),
])
def test_torque_records_off_by_a_unit_or_a_sign_are_refused(tmp_path, capsys, transform, header, message):
    rows = transform(_rig_columns())
    path = tmp_path / "d.csv"
    path.write_text(header + "\n" + "\n".join(",".join(f"{v:.10g}" for v in r) for r in rows) + "\n")
    code, _, err = run(capsys, "identify", RIG, path, "--json", tmp_path / "o.json")
    assert code == 2 and message in err and "d.csv" in err, err
    assert not (tmp_path / "o.json").exists()


def test_one_record_given_twice_is_refused(tmp_path, capsys):
    copy = tmp_path / "again.csv"
    shutil.copy(RIG_DATA, copy)
    code, _, err = run(capsys, "diagnose", RIG, RIG_DATA, copy)
    assert code == 2 and "holds the same measurement" in err and "again.csv" in err, err


def test_a_start_for_a_parameter_not_fitted_is_refused(capsys):
    code, _, err = run(capsys, "identify", RIG, RIG_DATA, "--start", "foo=1")
    assert code == 2 and "--start foo: not a fitted parameter" in err and "mu, theta0" in err, err


def test_a_start_outside_the_pumps_geometry_is_refused_naming_it(capsys):
    """A housing centre beyond the clearance: the model is not finite there (it was an internal
    error from the first singular-value decomposition)."""
    code, _, err = run(capsys, "identify", EXAMPLES / "ellipse_4vanes.toml", EXAMPLES / "data" / "ellipse_hidden_effects.csv",
                       "--params", "mu,theta0,housing.center.1", "--start", "housing.center.1=0.19")
    assert code == 2 and "not finite at the fit's start" in err and "housing.center.1 = 0.19" in err, err


@pytest.mark.parametrize("changes,message", [
    ({"booster.pressure": 101.3, "booster.target": 30.0}, "booster.pressure = 101.3 Pa"),
    ({"booster.target": 30.0}, "booster.target = 30 Pa"),
    ({"gas.wall_temperature": 20.0}, "20 degC is 293.15"),
    ({"gas.temperature": 20.0}, "gas.temperature = 20 K"),
])
def test_gas_pressures_in_kpa_and_temperatures_in_celsius_are_refused(changes, message):
    d = apply_changes(example_dict("evp_booster"), changes)
    try:
        cfg = config_from_dict(d)
    except ConfigError as e:  # a start below its target in Pa is refused while parsing, with the hint
        assert "looks like kPa" in str(e), e
        return
    with pytest.raises(ConfigError, match=message):
        check_config(cfg)


def test_a_booster_start_in_kpa_with_a_target_in_pa_names_the_start():
    d = apply_changes(example_dict("evp_booster"), {"booster.pressure": 101.3})
    with pytest.raises(ConfigError, match="booster.pressure = 101.3 Pa looks like kPa"):
        config_from_dict(d)


@pytest.mark.parametrize("exhaust", [[-1.5, 2.356], [-3.0, -2.0], [-2.356 + 2 * math.pi - 0.1, 7.0]])
def test_overlapping_port_windows_are_refused(exhaust):
    d = apply_changes(example_dict("evp_booster"), {"ports.exhaust": exhaust})
    with pytest.raises(ConfigError, match="ports.inlet .* and ports.exhaust .* overlap"):
        config_from_dict(d)


def test_windows_that_touch_are_accepted_and_the_command_names_an_overlap(tmp_path, capsys):
    d = apply_changes(example_dict("evp_booster"), {"ports.exhaust": [-0.785, 2.356]})
    assert config_from_dict(d).pneumatic is not None
    path = tmp_path / "c.toml"
    path.write_text(toml_text(apply_changes(example_dict("evp_booster"), {"ports.exhaust": [-1.0, 2.356]})))
    code, _, err = run(capsys, "pumpdown", path, "--duration", "0.01")
    assert code == 2 and "overlap" in err, err


def test_a_speed_driven_pumpdown_reports_no_supply_figures(tmp_path, capsys):
    res = pdm.pumpdown(speed_config(400.0), duration=0.02)
    for k in pdm.MOTOR_FIGURES:
        assert res.summary[k] is None, k
    assert res.summary["shaft_work"] > 0 and "no motor" in res.text()
    path = tmp_path / "c.toml"
    path.write_text(toml_text(apply_changes(example_dict("evp_booster"), {"operation.mode": "speed",
                                                                          "operation.speed": 400.0})))
    code, out, err = run(capsys, "pumpdown", path, "--duration", "0.02", "--json", tmp_path / "o.json")
    assert code == 0, err
    summary = json.loads((tmp_path / "o.json").read_text())
    assert summary["energy"] is None and summary["peak_current"] is None and "no motor" in out


@pytest.mark.parametrize("changes", [{"vane.thickness": 0.05}, {"vane.thickness": 0.029}])
def test_vanes_thicker_than_the_rotor_holds_are_refused(tmp_path, capsys, changes):
    # the test rig: a 20 mm rotor with 4 slots, their mouths 28.3 mm apart
    path = tmp_path / "c.toml"
    path.write_text(toml_text(apply_changes(example_dict(), changes)))
    code, _, err = run(capsys, "simulate", path, "--out", tmp_path / "o.csv")
    assert code == 2 and "vane.thickness" in err and "leave no rotor between them" in err, err
    assert not (tmp_path / "o.csv").exists()


def test_a_study_design_with_too_thick_vanes_fails_with_the_reason():
    from pumpsim import design
    from pumpsim.design.study import study_from_dict

    s = study_from_dict({"study": {"config": str(RIG), "sampler": "grid", "outputs": ["mean_torque"]},
                         "vary": {"vane.thickness": {"values": [0.003, 0.029]}}})
    df, _ = design.sweep(s, workers=0)
    by = {round(r._3, 6): r for r in df.itertuples()}  # vane.thickness
    assert by[0.003].status == "ok" and by[0.003].mean_torque > 0
    assert by[0.029].status.startswith("geometry: vane.thickness 0.029 m does not fit"), by[0.029].status


def test_optimisation_bounds_outside_the_admissible_designs_are_refused(tmp_path, capsys):
    study = tmp_path / "o.toml"
    study.write_text(f'[study]\nconfig = "{RIG.as_posix()}"\n[vary."vane.mass"]\nbounds = [-0.001, 0.0014]\n'
                     '[objective]\nminimize = "mean_torque"\n')
    code, _, err = run(capsys, "optimize", study)
    assert code == 2 and 'vary."vane.mass".bounds end -0.001' in err and "vane.mass must be > 0" in err, err


def test_the_run_up_lift_off_is_named_as_such_and_rounding_is_not_a_lift_off():
    from tests.pneumatic_helpers import evp_config

    res = pdm.pumpdown(evp_config(), duration=0.01)
    lift = [w for w in res.warnings if "lift off" in w]
    assert len(lift) == 1 and "start-up from rest" in lift[0] and "t = 0 s" not in lift[0], lift


def test_a_range_of_one_value_between_two_ends_is_refused():
    from pumpsim.design.study import study_from_dict

    with pytest.raises(ConfigError, match=r'range \[0.001, 0.0014, 1\] has one value but two ends'):
        study_from_dict({"study": {"config": str(RIG), "sampler": "grid"},
                         "vary": {"vane.mass": {"range": [0.001, 0.0014, 1]}}})
    one = study_from_dict({"study": {"config": str(RIG), "sampler": "grid"},
                           "vary": {"vane.mass": {"range": [0.001, 0.001, 1]}}})
    assert one.variables[0].values == [0.001]


def test_ipopt_keeps_the_iteration_limit(capsys):
    code, out, err = run(capsys, "identify", RIG, RIG_DATA, "--method", "ipopt", "--max-iter", "2")
    assert code == 1 and "NOT converged after 2 iterations" in out and "Maximum_Iterations_Exceeded" in err, out + err


def test_the_summary_of_a_run_with_its_own_sample_count_reads_it_back(tmp_path, capsys):
    st = tmp_path / "s.toml"
    st.write_text(f'[study]\nconfig = "{RIG.as_posix()}"\nsampler = "lhs"\nsamples = 64\nseed = 1\n'
                  '[vary."vane.mass"]\ndistribution = "normal"\nsd = 0.05\nrelative = true\n')
    out = tmp_path / "res"
    code, text, err = run(capsys, "sweep", st, "--out", out, "--samples", "6", "--workers", "1")
    assert code == 0 and "6 designs" in text, err
    code, text, err = run(capsys, "sweep", st, "--out", out, "--summary")
    assert code == 0 and "6 designs" in text and "status complete" in text, text + err


def test_a_gas_model_with_one_vane_runs_and_pumps_nothing(tmp_path, capsys):
    # one vane makes one cell that spans the inlet and the exhaust at once: a valid geometry (the
    # spec's closed form V = pi (R^2 - Rr^2) W / N holds for N = 1) whose cell moves no gas; its
    # per-cell columns come out as one column each, not as an IndexError after the integration
    path = tmp_path / "c.toml"
    path.write_text(toml_text(apply_changes(example_dict("evp_booster"), {"rotor.vanes": 1})))
    code, _, err = run(capsys, "pumpdown", path, "--duration", "0.1", "--out", tmp_path / "o.csv",
                       "--json", tmp_path / "o.json")
    assert code == 0, err
    header = (tmp_path / "o.csv").read_text().splitlines()[0].split(",")
    assert "pressure_0" in header and "pressure_1" not in header
    summary = json.loads((tmp_path / "o.json").read_text())
    # past the first milliseconds (the manifold's gas settling) no work goes into the gas: over
    # 0.1 s it is < 0.1 % of the friction's (measured -3.8e-5 J against 0.68 J)
    assert abs(summary["gas_work"]) < 1e-3 * summary["friction_work"]
