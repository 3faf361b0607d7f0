"""Data a fit must not read as measured, and what it must say it assumed: samples resampled
inside a gap in time, the speed taken from the config; and the commands' small wording: the
lift-off warning's flag, the data formats of identify --help."""
from __future__ import annotations

import json
import math

from tests.conftest import EXAMPLES, example_dict, toml_text
from tests.integration.test_bad_input import _debug, rig_columns, run, write  # noqa: F401  (_debug: the autouse fixture)

RIG = EXAMPLES / "test_rig.toml"


def _fit_mu(capsys, tmp_path, data, *flags):
    js = tmp_path / f"{data.stem}.json"
    code, _, err = run(capsys, "identify", RIG, data, "--params", "mu", "--json", js, *flags)
    assert code == 0, err
    mu = json.loads(js.read_text())["params"]["mu"]
    return mu["value"], mu["stderr"], err


def test_resampling_across_a_gap_leaves_the_interpolated_samples_out_of_the_fit(tmp_path, capsys):
    t, tq, w = rig_columns()
    cut = (t > 0.06) & (t < 0.12)  # 0.06 s of the 0.2 s record missing
    full = write(tmp_path / "full.csv", "time,torque,speed", t, tq, w)
    gap = write(tmp_path / "gap.csv", "time,torque,speed", t[~cut], tq[~cut], w[~cut])
    mu_full, _, _ = _fit_mu(capsys, tmp_path, full)
    mu_gap, se_gap, err = _fit_mu(capsys, tmp_path, gap, "--resample", "auto")
    # the 599 samples inside the gap (strictly between 0.0599 and 0.12 s) are left out, and said so
    assert "599 of the 2001 resampled samples lie inside the gaps" in err and "left out of the fit" in err, err
    # the measured part's fit agrees with the whole record's to within its noise; the straight line
    # across the gap fitted as data moved it 7 standard errors (0.20183 against 0.20295)
    assert abs(mu_gap - mu_full) < 3 * se_gap, (mu_gap, mu_full, se_gap)
    code, _, err = run(capsys, "diagnose", RIG, gap, "--resample", "auto")
    assert code == 2 and "599 resampled samples lie inside a gap" in err and "cut the record" in err, err


def test_a_fit_on_the_configured_speed_says_so_and_what_a_speed_error_does_to_mu(tmp_path, capsys):
    t, tq, w = rig_columns()  # measured at 5800 rpm
    d = example_dict("test_rig")
    d["operation"]["speed_rpm"] = 5500
    slow = tmp_path / "slow.toml"
    slow.write_text(toml_text(d))
    bare = write(tmp_path / "bare.csv", "time,torque", t, tq)
    js = tmp_path / "slow.json"
    code, out, err = run(capsys, "identify", slow, bare, "--params", "mu", "--json", js)
    assert code == 0, err
    note = out.split("note: speed: ", 1)[1]
    assert "no speed column" in note and "operation.speed" in note and "5500 rpm" in note, out
    assert json.loads(js.read_text())["notes"][0].startswith("speed: the data has no speed column")
    # concentric: the torque is mu times the vanes' centrifugal load, mu ~ 1/omega^2
    per_percent = float(note.split("moves mu by ", 1)[1].split(" %")[0])
    assert math.isclose(per_percent, -2.0, abs_tol=0.05), note
    assert "a speed column removes it" in note, note  # and the data cannot tell the speed from mu
    # the fits bear it out: the config's 5 % slow speed moved mu by (5800/5500)^2
    mu_slow = json.loads(js.read_text())["params"]["mu"]["value"]
    mu_right, _, _ = _fit_mu(capsys, tmp_path, bare)
    assert math.isclose(mu_slow / mu_right, (5800 / 5500) ** 2, rel_tol=2e-3), (mu_slow, mu_right)
    code, out, _ = run(capsys, "identify", RIG, write(tmp_path / "w.csv", "time,torque,speed", t, tq, w), "--params", "mu")
    assert code == 0 and "note: speed:" not in out


def test_the_simulate_lift_off_warning_names_the_flag_not_the_keyword(tmp_path, capsys):
    d = example_dict("test_rig")  # an ellipse so flat that the vanes must be pulled in: they lift off
    d["housing"] = {"shape": "ellipse", "a": 0.031, "b": 0.0203, "center": [0.0, 0.0], "angle": 0.0}
    d["vane"]["length"], d["rotor"]["slot_radius"] = 0.0135, 0.005
    cfg = tmp_path / "flat.toml"
    cfg.write_text(toml_text(d))
    code, _, err = run(capsys, "simulate", cfg, "--duration", "0.02")
    assert code == 0 and "would lift off" in err and "use --model contact" in err, err
    assert "model='contact'" not in err, err


def test_identify_help_names_every_data_format(capsys):
    from pumpsim.cli import main

    assert main(["identify", "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())  # argparse wraps the lines
    assert all(f in out for f in ("CSV", ".mat", ".tdms", "Parquet")), out
