"""What the command line says: results on stdout; notes, progress and warnings through the
`pumpsim` logger on stderr (-q quieter, -v more); round-off printed as 0; no Python reprs."""

import pandas as pd
import pytest

from pumpsim.cli import main
from pumpsim.cli.common import LOG, messages
from pumpsim.cli.design import optimize_text
from pumpsim.design.summary import summary_text
from pumpsim.presentation import resolved
from tests.conftest import ROOT

CFG = str(ROOT / "examples" / "test_rig.toml")
DATA = str(ROOT / "examples" / "data" / "test_rig_measurement.csv")
FIT = ["identify", CFG, DATA, "--params", "mu", "--resample", "auto"]


def test_quiet_keeps_results_and_drops_notes(capsys):
    assert main(FIT) == 0
    said = capsys.readouterr()
    assert "pumpsim: test_rig_measurement.csv: resampled to" in said.err
    for argv in (["-q", *FIT], [*FIT, "--quiet"]):  # before or after the command's name
        assert main(argv) == 0
        quiet = capsys.readouterr()
        assert quiet.err == ""
        assert quiet.out == said.out and "mu" in quiet.out


def test_verbose_says_more(capsys):
    assert main([*FIT, "-v"]) == 0
    err = capsys.readouterr().err
    assert "pumpsim: config " in err and "pumpsim: identify took " in err
    assert "resampled to" in err


def test_bad_input_is_reported_also_when_quiet(capsys):
    assert main(["-qq", "identify", CFG, str(ROOT / "no-such.csv")]) == 2
    assert "pumpsim: error:" in capsys.readouterr().err


def test_logger_levels_prefixes_and_restore(capsys):
    before = LOG.level, LOG.propagate, LOG.handlers[:]
    for quiet, shown in ((0, ["info", "warning", "error"]), (1, ["warning", "error"]), (2, ["error"])):
        with messages(quiet=quiet):
            LOG.debug("d")
            LOG.info("i")
            LOG.warning("w")
            LOG.error("e")
        err = capsys.readouterr().err.splitlines()
        expect = {"info": "pumpsim: i", "warning": "pumpsim: warning: w", "error": "pumpsim: error: e"}
        assert err == [expect[k] for k in shown]
    with messages(verbose=1):
        LOG.debug("d %s", 1)
    assert capsys.readouterr().err == "pumpsim: d 1\n"
    assert (LOG.level, LOG.propagate, LOG.handlers) == before


def test_round_off_is_zero():
    assert resolved(2.6e-13, "N·m") == 0.0 and resolved(6.4e-27, "W") == 0.0
    assert resolved(-3e-13, "N·m") == 0.0
    assert resolved(2e-6, "N·m") == 2e-6 and resolved(0.13, "N·m") == 0.13
    assert resolved(1e-13, "") == 1e-13  # no stated resolution: shown as is
    assert resolved(1e-11, "N·m", scale=0.13) == 0.0  # a spread below 1e-9 of its size
    assert resolved(1e-9, "N·m", scale=0.13) == 1e-9
    assert resolved(None, "N·m") is None


def test_sweep_summary_prints_round_off_as_zero():
    df = pd.DataFrame({"design": [0, 1, 2, 3], "status": ["ok"] * 4,
                       "ptp_torque": [2.6e-13, 1.9e-13, 3.1e-13, 2.2e-13],
                       "slot_friction_power": [6.4e-27, 0.0, 1e-27, 3e-27],
                       "mean_torque": [0.1312, 0.1315, 0.1320, 0.1318]})
    text = summary_text(df, ["mean_torque", "ptp_torque", "slot_friction_power"], {})
    rows = {line.split()[0]: line.split() for line in text.splitlines()}
    assert rows["ptp_torque"][3:7] == ["0", "0", "0", "0"]  # mean, sd, min, max
    assert rows["slot_friction_power"][3:7] == ["0", "0", "0", "0"]
    assert rows["mean_torque"][3] == "0.13163" and rows["mean_torque"][5] == "0.1312"
    assert "e-1" not in text and "e-2" not in text


@pytest.mark.parametrize("lower, upper", [(None, 7.0), (6.8, None)])
def test_optimize_text_has_no_python_reprs(lower, upper):
    res = {"method": "slsqp", "message": "Optimization terminated successfully", "iterations": [{}, {}, {}],
           "evaluations": 12, "seconds": 0.5, "success": True,
           "objective": {"minimize": "ptp_torque", "start": 3e-13, "value": 1.2e-13},
           "design": {"housing.b": 0.0205}, "start": {"housing.b": 0.02},
           "bounds": {"housing.b": [0.019, 0.021]},
           "constraints": {"min_normal_force": {"value": 7.1, "lower": lower, "upper": upper, "satisfied": True}}}
    text = optimize_text(res)
    assert "None" not in text and "[" not in text
    assert ("lower none" in text) == (lower is None) and ("upper none" in text) == (upper is None)
    assert "bounds 0.019 .. 0.021" in text
    assert "minimize ptp_torque: 0 (start) -> 0 N·m" in text


@pytest.mark.parametrize("quiet,shown", [(0, True), (1, False)])
def test_kernel_build_messages_follow_the_commands_verbosity(capsys, quiet, shown):
    """A kernel build is announced at the command line's info level (-q hides it), and to a Python
    caller that set no logging up, always."""
    from pumpsim.cli.common import messages
    from pumpsim.kernels.cache import log_build

    with messages(0, quiet):
        log_build("building the kernel x (test)")
    assert ("building the kernel x (test)" in capsys.readouterr().err) == shown
    log_build("building the kernel y (test)")
    assert "pumpsim: building the kernel y (test)" in capsys.readouterr().err


def test_a_reader_that_leaves_early_does_not_cost_the_files(tmp_path):
    """`pumpsim identify ... --json F | head -1`: the pipe closes before the command prints; the
    command still finishes, writes its file and exits 0 (its printed text goes nowhere)."""
    import json
    import os
    import subprocess
    import sys

    js = tmp_path / "fit.json"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p = subprocess.Popen([sys.executable, "-m", "pumpsim", "identify", CFG, DATA, "--params", "mu",
                          "--json", str(js)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    p.stdout.close()  # the reader is gone before the first line
    _, err = p.communicate(timeout=300)
    assert p.returncode == 0, err.decode()
    assert json.loads(js.read_text())["params"]["mu"]["value"] == pytest.approx(0.203, rel=0.01)
    assert b"Traceback" not in err and b"BrokenPipe" not in err
