"""`pumpsim simulate` writes the spec §7 columns and the figure set."""
import subprocess
import sys

import numpy as np

from tests.conftest import ROOT


def test_simulate_writes_spec_columns_and_plot(tmp_path):
    out, png = tmp_path / "o.csv", tmp_path / "o.png"
    r = subprocess.run([sys.executable, "-m", "pumpsim", "simulate",
                        str(ROOT / "examples" / "ellipse_4vanes.toml"), "--duration", "0.01",
                        "--rate", "5000", "--out", str(out), "--plot", str(png)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    header = out.read_text().splitlines()[0].split(",")
    expected = ["time", "angle", "speed", "torque"]
    for i in range(4):
        expected += [f"{c}_{i}" for c in ("s", "sdot", "normal", "slot1", "slot2")]
    assert header == expected
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert data.shape == (51, len(expected))
    np.testing.assert_allclose(data[:, 2], 471.0)
    assert png.stat().st_size > 10000 and png.read_bytes()[:4] == b"\x89PNG"
    assert "torque: mean" in r.stdout
