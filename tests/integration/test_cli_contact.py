"""`pumpsim simulate --model contact`, failures with partial output, and the solver study."""
import json
import subprocess
import sys

import numpy as np

from tests.conftest import ROOT
from tests.tolerances import SOLVER_STUDY_DEVIATION_MAX


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "pumpsim", *args], capture_output=True, text=True,
                          cwd=ROOT)


def test_contact_simulation_writes_penetration_columns_and_plot(tmp_path):
    out, png = tmp_path / "c.csv", tmp_path / "c.png"
    r = _cli("simulate", "examples/ellipse_4vanes.toml", "--model", "contact", "--duration", "0.01",
             "--rate", "5000", "--initial", "housing", "--out", str(out), "--plot", str(png))
    assert r.returncode == 0, r.stderr
    header = out.read_text().splitlines()[0].split(",")
    for i in range(4):
        assert f"penetration_{i}" in header and f"s_{i}" in header
    assert header.index("penetration_0") == header.index("slot2_0") + 1
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert data.shape[0] == 51 and np.all(data[:, header.index("normal_0")] >= 0)
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert "nsteps" in r.stdout  # solver statistics in the summary
    assert "simulated" not in r.stderr  # no progress bar in a pipe


def test_integrator_failure_exits_1_names_time_state_contacts_and_keeps_samples(tmp_path):
    out = tmp_path / "c.csv"
    args = ("simulate", "examples/startup_ellipse.toml", "--model", "contact", "--duration", "0.5",
            "--rate", "1000", "--max-steps", "40", "--out", str(out))
    r = _cli(*args)
    assert r.returncode == 1
    assert "integrator failed between t =" in r.stderr and "starting from state" in r.stderr
    assert "contact states at t =" in r.stderr and "vane 0" in r.stderr
    assert "Traceback" not in r.stderr
    assert not out.exists()  # no partial output unless asked for
    r = _cli(*args, "--keep-partial")
    assert r.returncode == 1 and "computed before the failure are in" in r.stderr
    rows = out.read_text().splitlines()
    assert 2 <= len(rows) < 502  # the samples before the failure, not the whole run
    out.unlink()
    r = _cli(*args[:-4], "--max-steps", "2", "--out", str(out), "--keep-partial")  # fails before a sample
    assert r.returncode == 1 and "fewer than 2: nothing kept" in r.stderr and not out.exists(), r.stderr


def test_solver_study_prints_table_and_writes_json(tmp_path):
    js = tmp_path / "study.json"
    r = _cli("study", "examples/ellipse_4vanes.toml", "--revolutions", "2", "--json", str(js))
    assert r.returncode == 0, r.stderr
    assert "explicit RK4" in r.stdout and "report nonlinear" in r.stdout
    rows = json.loads(js.read_text())["rows"]
    assert len(rows) == 8
    for row in rows:
        assert row["steps"] > 0 and row["rhs_evaluations"] >= row["steps"] and row["wall_time"] > 0
        assert 0 <= row["torque_deviation"] < SOLVER_STUDY_DEVIATION_MAX
