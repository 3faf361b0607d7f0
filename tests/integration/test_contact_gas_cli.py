"""`pumpsim simulate --model contact` and `pumpsim pumpdown --model contact` on a config with the
spec §8 tables: the spec's columns, per-vane lift-off in the summary and the JSON, bad input."""
import json
import subprocess
import sys

import numpy as np

from tests.conftest import ROOT

EVP = "examples/evp_booster.toml"  # motor drive from rest: the vanes lift off while it runs up


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "pumpsim", *args], capture_output=True, text=True,
                          cwd=ROOT)


def test_simulate_contact_with_gas_writes_vane_and_cell_columns(tmp_path):
    out = tmp_path / "m1.csv"
    r = _cli("simulate", EVP, "--model", "contact", "--duration", "0.01", "--rate", "4000", "--out", str(out))
    assert r.returncode == 0, r.stderr
    header = out.read_text().splitlines()[0].split(",")
    assert header[:4] == ["time", "angle", "speed", "torque"]
    for i in range(4):
        for c in ("s", "sdot", "normal", "slot1", "slot2", "penetration", "pressure", "volume", "temperature"):
            assert f"{c}_{i}" in header
    assert "booster_pressure" in header and "current" in header
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert data.shape[0] == 41 and np.all(data[:, header.index("normal_0")] >= 0)
    assert "motor drive" in r.stdout and "work: shaft" in r.stdout
    assert sum(f"vane {i}:" in r.stdout for i in range(4)) == 4  # lift-off line per vane


def test_pumpdown_contact_reports_lift_off_in_json_and_columns(tmp_path):
    out, js = tmp_path / "pd.csv", tmp_path / "pd.json"
    r = _cli("pumpdown", EVP, "--model", "contact", "--duration", "0.02", "--out", str(out), "--json", str(js))
    assert r.returncode == 0, r.stderr
    doc = json.loads(js.read_text())
    assert doc["model"] == "contact" and isinstance(doc["lift_off"], list) and doc["lift_off"]
    first = doc["lift_off"][0]
    assert set(first) == {"vane", "start", "end", "angle_start_deg", "angle_end_deg", "max_gap"}
    header = out.read_text().splitlines()[0].split(",")
    for c in ("booster_pressure", "current", "pressure_0", "s_0", "sdot_0", "normal_0", "penetration_0"):
        assert c in header
    assert "lifts off" in r.stdout


def test_contact_with_gas_bad_input_exits_2_and_writes_nothing(tmp_path):
    png = tmp_path / "x.png"
    r = _cli("pumpdown", EVP, "--model", "contact", "--duration", "0.01", "--plot", str(png))
    assert r.returncode == 2 and "without --model contact" in r.stderr and not png.exists()
    cfg = tmp_path / "no_contact.toml"
    text = (ROOT / EVP).read_text()
    cfg.write_text(text[:text.index("[contact.housing]")] + text[text.index("[operation]"):])
    out = tmp_path / "y.csv"
    r = _cli("simulate", str(cfg), "--model", "contact", "--duration", "0.01", "--out", str(out))
    assert r.returncode == 2 and "[contact.housing]" in r.stderr and not out.exists()
    r = _cli("simulate", EVP, "--model", "contact", "--method", "rk", "--duration", "0.01")
    assert r.returncode == 2 and "cvodes" in r.stderr
