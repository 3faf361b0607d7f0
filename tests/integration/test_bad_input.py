"""Issue 12, a new user's first day: each numbered finding reproduced (it failed on the old main).

The command line runs in-process (`pumpsim.cli.main(argv)` returns the exit status), which is fast
and still sees every message; a traceback would escape as an exception and fail the test.
"""
import json
import math
import os
import stat

import numpy as np
import pytest

from pumpsim.cli import main
from tests.conftest import EXAMPLES, apply_changes, example_dict, toml_text
from tests.tolerances import DATA_UNIT_REL, RIG_MU, RIG_MU_ABS

RIG = str(EXAMPLES / "test_rig.toml")
ELLIPSE = str(EXAMPLES / "ellipse_4vanes.toml")
RIG_DATA = EXAMPLES / "data" / "test_rig_measurement.csv"


@pytest.fixture(autouse=True)
def _debug(monkeypatch):
    monkeypatch.setenv("PUMPSIM_DEBUG", "1")  # an unexpected exception propagates and fails the test


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, out, err


def rig_columns():
    lines = [ln for ln in RIG_DATA.read_text().splitlines() if ln and not ln.startswith("#")]
    rows = np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]])
    return rows[:, 0], rows[:, 1], rows[:, 2]


def write(path, header, *cols, sep=",", decimal="."):
    body = "\n".join(sep.join(f"{v:.10g}".replace(".", decimal) for v in row) for row in zip(*cols))
    path.write_text(header + "\n" + body + "\n", encoding="utf-8")
    return path


def write_toml(path, d):
    path.write_text(toml_text(d))
    return path


# --- 1. unit mistakes are refused before any work, naming the unit and the fix ------------------

@pytest.mark.parametrize("transform,expect", [
    (lambda t, tq, w: (t, tq * 1000, w), ["N*mm", "set the torque unit N*mm"]),
    (lambda t, tq, w: (t, tq * 100, w), ["looks like N*cm (set the torque unit N*cm", "force option"]),
    (lambda t, tq, w: (t, tq, w * 60 / (2 * math.pi)), ["rpm", "set the speed unit rpm"]),
    (lambda t, tq, w: (t * 1000, tq, w), ["ms", "set the time unit ms"]),
])
def test_unit_mistakes_in_data_are_refused_with_the_fix(tmp_path, capsys, transform, expect):
    t, tq, w = transform(*rig_columns())
    data = write(tmp_path / "d.csv", "time,torque,speed", t, tq, w)
    js = tmp_path / "fit.json"
    code, _, err = run(capsys, "identify", RIG, data, "--params", "mu", "--json", js)
    assert code == 2 and all(e in err for e in expect) and "force option" in err, err
    assert not js.exists()
    if "N*cm" in expect[0]:  # named alone: N*mm would read it 10x too low and fit a COF 10x too low
        assert "N*mm" not in err, err


def test_a_torque_level_between_two_units_names_both(tmp_path, capsys):
    # the config's COF ~3x below the data's puts the torque in N*cm half a decade above the model's
    # level in N*cm and half a decade below it in N*mm: either unit could be meant
    t, tq, w = rig_columns()
    d = example_dict("test_rig")
    d["friction"]["housing"].update(static=0.067, dynamic=0.064)
    cfg = write_toml(tmp_path / "low.toml", d)
    data = write(tmp_path / "d.csv", "time,torque,speed", t, tq * 100, w)
    code, _, err = run(capsys, "identify", cfg, data, "--params", "mu")
    hint = err.split("looks like ", 1)[-1]
    assert code == 2 and "N*mm (" in hint and ") or N*" in hint and "N*cm (" in hint, err


def test_torque_in_n_mm_without_speed_column_is_refused(tmp_path, capsys):
    t, tq, _ = rig_columns()
    data = write(tmp_path / "d.csv", "time,torque", t, tq * 1000)
    code, _, err = run(capsys, "identify", RIG, data, "--params", "mu")
    assert code == 2 and "N*mm" in err


def test_force_proceeds_and_the_fit_on_its_bound_exits_1(tmp_path, capsys):
    """--force accepts the suspected unit; the fit then ends on the COF bound 2, which is reported
    and exits 1 (the outputs are complete and say so)."""
    t, tq, w = rig_columns()
    data = write(tmp_path / "d.csv", "time,torque,speed", t, tq * 1000, w)
    js = tmp_path / "fit.json"
    code, out, err = run(capsys, "identify", RIG, data, "--params", "mu", "--force", "--json", js)
    assert code == 1 and "ON ITS BOUND 2" in out and "ended on its bound" in err
    import json

    doc = json.loads(js.read_text())
    assert doc["on_bound"] == [{"name": "mu", "bound": 2.0}] and doc["problems"]


def test_header_units_fix_the_same_data(tmp_path, capsys):
    """The unit-annotated header makes the N*mm / rpm / ms file fit like the SI one."""
    t, tq, w = rig_columns()
    data = write(tmp_path / "d.csv", "time [ms];torque [N*mm];speed [rpm]", t * 1000, tq * 1000,
                 w * 60 / (2 * math.pi), sep=";", decimal=",")
    js = tmp_path / "fit.json"
    code, out, err = run(capsys, "identify", RIG, data, "--params", "mu", "--json", js)
    assert code == 0, err
    import json

    assert abs(json.loads(js.read_text())["params"]["mu"]["value"] - RIG_MU) < RIG_MU_ABS


@pytest.mark.parametrize("changes,key", [
    ({"rotor.radius": 20.0, "housing.radius": 22.5, "vane.length": 12.0, "vane.thickness": 3.0,
      "rotor.slot_radius": 9.0, "vane.mass": 1.2, "rotor.inertia": 2e4}, "rotor.radius = 20 m"),
    ({"vane.mass": 1.2}, "vane.mass = 1.2 kg"),
    ({"rotor.inertia": 20.0}, "rotor.inertia = 20 kg m^2"),
    ({"operation.speed_rpm": None, "operation.speed": 5800.0}, "operation.speed_rpm = 5800"),
])
def test_config_in_mm_g_or_rpm_is_refused(tmp_path, capsys, changes, key):
    cfg = write_toml(tmp_path / "c.toml", apply_changes(example_dict(), changes))
    out = tmp_path / "o.csv"
    code, _, err = run(capsys, "simulate", cfg, "--out", out)
    assert code == 2 and key in err and "SI" in err and "force option" in err and not out.exists(), err


# --- 2. a diverging explicit run is a numerical failure, exit 1, nothing written ---------------

def test_diverging_rk4_exits_1_naming_the_state(tmp_path, capsys):
    out = tmp_path / "o.csv"
    code, _, err = run(capsys, "simulate", ELLIPSE, "--model", "contact", "--method", "rk",
                       "--max-step", "1e-3", "--rate", "100", "--duration", "0.05", "--out", out)
    assert code == 1 and "outside its physical bounds" in err and "s_" in err and "t = " in err
    assert not out.exists()


# --- 3. the README's API runs (see also test_readme.py) ----------------------------------------

def test_package_level_api_takes_paths_and_cli_defaults():
    import pumpsim

    res = pumpsim.identify(RIG, RIG_DATA)  # a config path, a data path; defaults as the CLI
    assert list(res.estimates) == ["mu", "theta0"]
    assert abs(res.value("mu") - RIG_MU) < RIG_MU_ABS
    assert "mu" in repr(res) and "RMS" in str(res)
    for fn in (pumpsim.identify, pumpsim.diagnose, pumpsim.load_config, pumpsim.load_data,
               pumpsim.simulate, pumpsim.SimulationResult.to_csv, pumpsim.SimulationResult.plot):
        doc = fn.__doc__ or ""
        assert "Example" in doc and len(doc) > 200, fn.__name__


def test_identify_takes_arrays():
    import pumpsim

    t, tq, w = rig_columns()
    res = pumpsim.identify(pumpsim.load_config(RIG), {"time": t, "torque": tq, "speed": w}, params=["mu"])
    assert abs(res.value("mu") - RIG_MU) < RIG_MU_ABS


# --- 4. bad files and options: exit 2 with a message, never a traceback ------------------------

@pytest.mark.parametrize("content,message", [
    (b"\x00\x01\x02binary\x00", "c.toml' is a binary file"),
    ("name = 'x'\n".encode("utf-16"), "missing required key 'housing"),  # decoded, then validated
    ("name = \u00e9\n".encode("utf-16"), "c.toml' is not valid TOML"),
    (b"PK\x03\x04rest", "Excel"),
])
def test_binary_and_utf16_configs(tmp_path, capsys, content, message):
    cfg = tmp_path / "c.toml"
    cfg.write_bytes(content)
    code, _, err = run(capsys, "simulate", cfg)
    assert code == 2 and message in err, err


def test_utf16_config_is_read(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_bytes((EXAMPLES / "test_rig.toml").read_text().encode("utf-16"))
    out = tmp_path / "o.csv"
    code, _, err = run(capsys, "simulate", cfg, "--out", out, "--duration", "0.002")
    assert code == 0 and out.exists(), err


def test_header_only_csv(tmp_path, capsys):
    data = tmp_path / "d.csv"
    data.write_text("time,torque,speed\n")
    code, _, err = run(capsys, "identify", RIG, data)
    assert code == 2 and "no data rows" in err and "d.csv" in err


@pytest.mark.parametrize("args,message", [
    (["--rtol", "-1"], "--rtol must be in (0, 1)"),
    (["--atol", "0"], "--atol must be in (0, 1)"),
    (["--max-steps", "0"], "--max-steps must be >= 1"),
    (["--rate", "nan"], "rate must be > 0"),
])
def test_bad_tolerances_are_refused_before_casadi(capsys, args, message):
    code, _, err = run(capsys, "simulate", ELLIPSE, "--model", "contact", *args)
    assert code == 2 and message in err, err


# --- 5. outputs: checked before work, distinct, written together, modes follow the umask -------

@pytest.mark.parametrize("extra,message", [
    (["--out", "{d}"], "is a folder"),
    (["--plot", "{d}/x.foo"], "'.foo' is not supported"),
    (["--out", "{d}/missing/o.csv"], "does not exist"),
    (["--out", "{d}/o.png", "--plot", "{d}/o.png"], "name the same file"),
    (["--out", "{d}/o.png", "--plot", "{d}/./o.png"], "name the same file"),
    (["--out", RIG], "is an input file"),
    (["--out", "/proc/o.csv"], "cannot create a file in folder '/proc'"),  # even root cannot
])
def test_output_paths_checked_before_work(tmp_path, capsys, extra, message):
    args = [a.replace("{d}", str(tmp_path)) for a in extra]
    before = set(tmp_path.iterdir())
    code, out, err = run(capsys, "simulate", RIG, *args)
    assert code == 2 and message in err and out == "", err  # no summary: nothing was computed
    assert set(tmp_path.iterdir()) == before


def test_json_and_report_naming_one_file_and_missing_report_folder(tmp_path, capsys):
    js, rep = tmp_path / "fit.json", tmp_path / "fit.html"
    code, out, err = run(capsys, "identify", RIG, RIG_DATA, "--json", rep, "--report", rep)
    assert code == 2 and "name the same file" in err and out == ""
    code, out, err = run(capsys, "identify", RIG, RIG_DATA, "--json", js, "--report", tmp_path / "no" / "r.html")
    assert code == 2 and "does not exist" in err and out == "" and not js.exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_read_only_output_folder(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    code, _, err = run(capsys, "simulate", RIG, "--out", ro / "o.csv")
    assert code == 2 and "no permission" in err


def test_output_modes_follow_the_umask(tmp_path, capsys):
    old = os.umask(0o022)
    try:
        out, png = tmp_path / "o.csv", tmp_path / "o.png"
        code, _, err = run(capsys, "simulate", RIG, "--out", out, "--plot", png, "--duration", "0.002")
        assert code == 0, err
        for f in (out, png):
            assert stat.S_IMODE(f.stat().st_mode) == 0o644
    finally:
        os.umask(old)


def test_generated_kernel_folders_follow_the_umask(tmp_path, monkeypatch):
    """A kernel folder is built in a mkdtemp folder (0700) and renamed into place: it must get
    the umask's mode so colleagues sharing generated/ can load it (one 1-vane compile, ~5 s)."""
    from pumpsim.codegen.build import build_variant
    from tests.conftest import make_config

    monkeypatch.setenv("PUMPSIM_GENERATED", str(tmp_path))
    old = os.umask(0o022)
    try:
        folder = build_variant(make_config(**{"rotor.vanes": 1}).structure_for("constrained"))
    finally:
        os.umask(old)
    assert stat.S_IMODE(folder.stat().st_mode) == 0o755


def test_failure_in_a_later_writer_leaves_no_earlier_file(tmp_path, capsys, monkeypatch):
    """All outputs are renamed into place together: a failing plot leaves no CSV."""
    import pumpsim.result

    def broken(self, path, **kw):
        raise pumpsim.SolverError("plot failed")

    monkeypatch.setattr(pumpsim.result.SimulationResult, "plot", broken)
    out, png = tmp_path / "o.csv", tmp_path / "o.png"
    code, _, err = run(capsys, "simulate", RIG, "--out", out, "--plot", png, "--duration", "0.002")
    assert code == 1 and list(tmp_path.iterdir()) == []


# --- 6. over-parameterised fits are named, not given numbers; exit 1 --------------------------

def test_over_parameterised_fit_names_every_unidentifiable_parameter(tmp_path, capsys):
    js = tmp_path / "fit.json"
    code, out, err = run(capsys, "identify", RIG, RIG_DATA, "--params", "mu,mu_slot,torque_offset,speed",
                         "--json", js)
    assert code == 1 and "e+09" not in out and "e+10" not in out and "e+12" not in out
    import json

    doc = json.loads(js.read_text())
    assert {"mu", "torque_offset", "mu_slot"} <= set(doc["unidentifiable"])
    assert all(p["value"] is None for n, p in doc["params"].items() if n in doc["unidentifiable"])


def test_non_converged_fit_exits_1(tmp_path, capsys):
    code, out, err = run(capsys, "identify", ELLIPSE, EXAMPLES / "data" / "ellipse_hidden_effects.csv",
                         "--params", "mu,theta0", "--max-iter", "1", "--start", "mu=0.02")
    assert code == 1 and "NOT converged" in err


# --- 8. spreadsheet exports ---------------------------------------------------------------------

def test_spreadsheet_exports_are_read(tmp_path):
    from pumpsim.data import load_data

    t, tq, w = rig_columns()
    plain = load_data(RIG_DATA)
    bom = tmp_path / "bom.csv"
    bom.write_bytes("\ufefftime,torque,speed\n".encode() + "\n".join(
        f"{float(a)!r},{float(b)!r},{float(c)!r}" for a, b, c in zip(t, tq, w)).encode())
    semi = write(tmp_path / "semi.csv", "time [s];torque [N*mm];speed [1/min]", t, tq * 1000,
                 w * 60 / (2 * math.pi), sep=";", decimal=",")
    utf16 = tmp_path / "u16.txt"
    utf16.write_bytes(("time\ttorque (mNm)\tspeed\n" + "\n".join(
        f"{float(a)!r}\t{float(b) * 1000!r}\t{float(c)!r}" for a, b, c in zip(t, tq, w))).encode("utf-16"))
    for f in (bom, semi, utf16):
        ds = load_data(f)
        np.testing.assert_allclose(ds.torque, plain.torque, rtol=DATA_UNIT_REL)
        np.testing.assert_allclose(ds.speed, plain.speed, rtol=DATA_UNIT_REL)


def test_capitalised_and_annotated_column_names_are_found(tmp_path):
    from pumpsim.data import DataOptions, load_data

    t, tq, w = rig_columns()
    f = write(tmp_path / "d.csv", "Time,Torque [N*mm],n_motor [rpm]", t, tq * 1000, w * 60 / (2 * math.pi))
    ds = load_data(f, DataOptions(speed="n_motor [rpm]"))
    np.testing.assert_allclose(ds.torque, tq, rtol=DATA_UNIT_REL)
    np.testing.assert_allclose(ds.speed, w, rtol=DATA_UNIT_REL)


def test_unknown_header_unit_and_contradicting_option(tmp_path, capsys):
    t, tq, w = rig_columns()
    data = write(tmp_path / "d.csv", "time,torque [kgf],speed", t, tq, w)
    code, _, err = run(capsys, "identify", RIG, data)
    assert code == 2 and "torque unit must be one of" in err and "kgf" in err
    data = write(tmp_path / "e.csv", "time,torque [N*mm],speed", t, tq * 1000, w)
    code, _, err = run(capsys, "identify", RIG, data, "--torque-unit", "N*m")
    assert code == 2 and "annotated [N*mm]" in err


def test_multi_file_errors_name_the_file(tmp_path, capsys):
    t, tq, w = rig_columns()
    good = write(tmp_path / "good.csv", "time,torque,speed", t, tq, w)
    tq = tq.copy()
    tq[200] = np.nan
    bad = write(tmp_path / "second.csv", "time,torque,speed", t, tq, w)
    code, _, err = run(capsys, "diagnose", RIG, good, bad)
    assert code == 2 and "second.csv" in err and "row 202" in err


# --- 11. smaller ------------------------------------------------------------------------------

def test_help_shows_defaults_and_the_torque_drive_duration(capsys):
    code, out, _ = run(capsys, "simulate", "--help")
    out = " ".join(out.split())
    assert code == 0 and "(default: 10000.0)" in out and "0.5 s for a torque drive" in out
    code, out, _ = run(capsys, "identify", "--help")
    assert code == 0 and "default mu,theta0" in " ".join(out.split())


def test_ipopt_prints_no_banner_and_converges_where_the_others_do(tmp_path, capsys):
    code, out, err = run(capsys, "identify", RIG, RIG_DATA, "--params", "mu", "--method", "ipopt")
    assert "Ipopt" not in out and "*****" not in out
    assert code == 0, out + err
    import json

    rms = {}
    for method in ("gauss-newton", "ipopt"):
        js = tmp_path / f"{method}.json"
        code, out, err = run(capsys, "identify", ELLIPSE, EXAMPLES / "data" / "ellipse_hidden_effects.csv",
                             "--method", method, "--json", js)
        doc = json.loads(js.read_text())
        assert code == 0 and doc["converged"], err
        rms[method] = doc["rms"]
    assert rms["ipopt"] <= rms["gauss-newton"] * (1 + 1e-6)


@pytest.mark.parametrize("command,flag", [("identify", "--steady"), ("identify", "--transient"),
                                          ("diagnose", "--resample")])
def test_torque_only_options_are_refused_on_a_bench_log(tmp_path, capsys, command, flag):
    """A bench log (recognised by its columns) refuses before any work the options that only torque
    data takes, naming the flag and the fix."""
    t = np.arange(0.0, 0.05, 1e-3)
    path = write(tmp_path / "bench.csv", "time [s],voltage [V],current [A],booster_pressure [kPa]",
                 t, np.full_like(t, 13.5), np.full_like(t, 10.0), np.full_like(t, 90.0))
    extra = {"--steady": ["--steady"], "--transient": ["--transient"], "--resample": ["--resample", "1000"]}[flag]
    code, _, err = run(capsys, command, str(EXAMPLES / "evp_booster.toml"), str(path), *extra)
    assert code == 2 and flag in err and "is for torque data" in err and f"drop {flag}" in err, err


@pytest.mark.parametrize("command", ["identify", "diagnose"])
def test_bench_log_options_on_torque_data_are_refused(capsys, command):
    """A bench log's column option on a file that does not read as a bench log (torque data, or a
    bench log whose columns the options miss) is refused before any work, naming the flag."""
    code, _, err = run(capsys, command, str(EXAMPLES / "test_rig.toml"), str(EXAMPLES / "data" / "test_rig_measurement.csv"),
                       "--current-column", "I_motor")
    assert code == 2 and "--current-column is for a bench log" in err and "check the column names" in err, err


@pytest.mark.parametrize("wrap", [None, 360.0])
def test_an_angle_column_in_degrees_is_refused_and_its_header_unit_reads_it(tmp_path, capsys, wrap):
    t, tq, w = rig_columns()
    deg = np.degrees(0.3 + np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))]))
    deg = deg if wrap is None else np.mod(deg, wrap)
    data = write(tmp_path / "d.csv", "time,torque,speed,angle", t, tq, w, deg)
    code, _, err = run(capsys, "identify", RIG, data, "--params", "mu")
    assert code == 2 and "the angle column looks like degrees" in err and "57.3x the speed" in err, err
    assert "'angle [deg]'" in err, err
    ok = write(tmp_path / "ok.csv", "time,torque,speed,angle [deg]", t, tq, w, deg)
    js = tmp_path / "fit.json"
    code, _, err = run(capsys, "identify", RIG, ok, "--params", "mu", "--json", js)
    assert code == 0, err
    assert abs(json.loads(js.read_text())["params"]["mu"]["value"] - RIG_MU) < RIG_MU_ABS


def test_a_slow_logger_is_told_to_log_faster_not_that_its_time_is_in_ms(tmp_path, capsys):
    t, tq, w = (c[::25] for c in rig_columns())  # 400 Hz: 4.1 samples per revolution at 5800 rpm
    data = write(tmp_path / "d.csv", "time,torque,speed", t, tq, w)
    code, _, err = run(capsys, "identify", RIG, data, "--params", "mu")
    # read in ms the 0.2 s record would last 0.2 ms, an eighth of a revolution
    assert code == 2 and "the log is too slow" in err and "log at 773 Hz or faster" in err, err
    assert "4 vanes" in err and "looks like ms" not in err, err


def test_a_config_speed_in_the_wrong_key_is_named_not_the_right_speed_column(tmp_path, capsys):
    d = example_dict("test_rig")
    d["operation"]["speed_rpm"] = 607.37  # rad/s typed into the rpm key
    cfg = write_toml(tmp_path / "c.toml", d)
    code, _, err = run(capsys, "identify", cfg, RIG_DATA, "--params", "mu")
    assert code == 2 and "operation.speed_rpm = 607.37" in err and "looks wrong" in err, err
    assert "the column looks like rpm" not in err, err
    t, tq, w = rig_columns()  # the other way round: the column in rpm, the config right
    rpm = write(tmp_path / "rpm.csv", "time,torque,speed", t, tq, w * 30 / math.pi)
    code, _, err = run(capsys, "identify", RIG, rpm, "--params", "mu")
    assert code == 2 and "the column looks like rpm" in err and "operation.speed" not in err, err
