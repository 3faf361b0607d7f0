"""The independent model against pumpsim's pump-down on the EVP example, no hidden change, constant
supply voltage: booster pressure, current and speed over the first 0.15 s (~1 CPU min).

    python bench/independent_gas/compare.py [--duration 0.15] [--config TOML]
        [--json out/independent_gas/compare.json]

The differences are also given in the bench-log grid's noise sigmas (0.2 % of each channel's range,
generate.NOISE["low"]): the current's RMS after the inrush (INRUSH) and its mean per third of the
log, the booster pressure's RMS and last sample (as in docs/explanation/gas-model.md's table, with
--config bench/independent_gas/evp_small_booster.toml --duration 0.5).

pumpsim is run through its command line (`pumpsim pumpdown --out CSV`, rtol 1e-6); the independent
model with LSODA at rtol 1e-6 (1e-7 moves its channels by < 1e-5 relative over 0.05 s).
"""
from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import model as M  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "examples" / "evp_booster.toml"
RATE = 2000.0
SIGMA = 0.002  # of a channel's range: the grid's low noise (generate.NOISE["low"])
INRUSH = 0.005  # s


def pumpsim_curves(duration, config=CONFIG):
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "pd.csv"
        # --until 1 Pa: the whole duration, as the independent model runs it (not stopping at booster.target)
        subprocess.run([sys.executable, "-m", "pumpsim", "pumpdown", str(config), "--duration", str(duration),
                        "--until", "1", "--rtol", "1e-6", "--rate", str(RATE), "--out", str(out), "-q"], check=True, cwd=ROOT)
        with open(out) as f:
            rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in ("time", "speed", "booster_pressure", "current")}


def independent_curves(duration, config=CONFIG, **changes):
    pump = M.load(config)
    if changes:
        from dataclasses import replace
        pump = replace(pump, **changes)
    t = np.arange(int(round(duration * RATE)) + 1) / RATE
    return M.PumpDown(pump, lambda _t: pump.voltage).run(t, rtol=1e-6, method="LSODA")


def agreement(a, b):
    """Figures a reader compares: pressure drop at the end, mean and peak current, mean speed over
    the second half, and the largest channel differences relative to the channel's range."""
    n = min(len(a["time"]), len(b["time"]))
    half = slice(n // 2, n)
    rows = {}
    for name, f in {
        "pressure_drop_end_Pa": lambda c: c["booster_pressure"][0] - c["booster_pressure"][n - 1],
        "mean_current_A": lambda c: float(np.mean(c["current"][:n])),
        "peak_current_A": lambda c: float(np.max(c["current"][:n])),
        "mean_current_2nd_half_A": lambda c: float(np.mean(c["current"][half])),
        "mean_speed_2nd_half_rad_s": lambda c: float(np.mean(c["speed"][half])),
    }.items():
        x, y = float(f(a)), float(f(b))
        rows[name] = {"independent": x, "pumpsim": y, "rel_diff": (x - y) / y}
    for ch in ("booster_pressure", "current", "speed"):
        d = a[ch][:n] - b[ch][:n]
        rows[f"max_abs_diff_{ch}_over_range"] = float(np.max(np.abs(d)) / np.ptp(b[ch][:n]))
        rows[f"rms_diff_{ch}_over_range"] = float(np.sqrt(np.mean(d * d)) / np.ptp(b[ch][:n]))
    return rows


def sigmas(a, b) -> dict:
    """Independent minus pumpsim in noise sigmas (module doc)."""
    n = min(len(a["time"]), len(b["time"]))
    t = b["time"][:n]
    di = a["current"][:n] - b["current"][:n]
    db = a["booster_pressure"][:n] - b["booster_pressure"][:n]
    s_i, s_b = SIGMA * np.ptp(b["current"][:n]), SIGMA * np.ptp(b["booster_pressure"][:n])
    after = t >= t[0] + INRUSH
    thirds = np.array_split(np.flatnonzero(after), 3)
    return {"current_rms_sigmas": float(np.sqrt(np.mean(di[after] ** 2)) / s_i),
            "current_thirds_sigmas": [float(np.mean(di[k]) / s_i) for k in thirds],
            "booster_rms_sigmas": float(np.sqrt(np.mean(db * db)) / s_b),
            "booster_end_sigmas": float(db[-1] / s_b)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--duration", type=float, default=0.15)
    ap.add_argument("--config", default=str(CONFIG))
    ap.add_argument("--json", default=str(ROOT / "out" / "independent_gas" / "compare.json"))
    a = ap.parse_args(argv)
    ind, ps = independent_curves(a.duration, a.config), pumpsim_curves(a.duration, a.config)
    rows = agreement(ind, ps)
    for k, v in rows.items():
        if isinstance(v, dict):
            print(f"{k:32s} independent {v['independent']:12.6g}  pumpsim {v['pumpsim']:12.6g}  "
                  f"diff {100 * v['rel_diff']:+.3f} %")
        else:
            print(f"{k:32s} {100 * v:.3f} % of the range")
    rows["sigmas"] = sigmas(ind, ps)
    print("in noise sigmas:", json.dumps(rows["sigmas"]))
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    Path(a.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
