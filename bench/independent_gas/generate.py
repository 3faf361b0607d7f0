"""Bench logs with hidden changes from the independent pump-down model (model.py).

Each case is one simulation (a hidden change of the pump, or none); the sensor changes, the noise,
the seeds, the sample rates, the formats and the time jitter are applied afterwards to the clean
channels, so a grid costs one integration per case. The manifest (the truth) is written apart from
the logs: logs/ holds only what a bench would hand over.

    python bench/independent_gas/generate.py [--quick] [--out out/independent_gas] [--jobs 2]
"""
from __future__ import annotations

import argparse
import hashlib
import json
import sys
from dataclasses import replace
from multiprocessing import Pool
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import model as M  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
CONFIG = Path(__file__).resolve().parent / "evp_small_booster.toml"
DURATION = 0.5          # s: a short end-of-line run (runtime of the independent model: ~2 min per case)
CLEAN_RATE = 10000.0    # Hz: the clean channels, resampled to the logs' rates and jittered times
SOURCE_RESISTANCE = 0.02  # ohm: the bench supply sags with the current; the logged voltage shows it

# name -> (pumpsim library name or None (outside the library), changes of the pump, truth values
#          in pumpsim's parameter names where they exist)
CASES = {
    "none": (None, {}, {}),
    "booster_leak": ("booster_leak", {"booster_leak": 5.0e-5}, {"booster.leak": 5.0e-5}),
    "tip_clearance": ("tip_clearance", {"tip_gap": 2.0e-5}, {"leak.tip_gap": 2.0e-5}),
    "valve_late": ("valve_late", {"valve_crack": 8000.0}, {"valve.cracking": 8000.0}),
    "motor_friction": ("motor_friction", {"motor_friction": 0.03}, {"motor.friction": 0.03}),
    "supply_resistance": ("supply_resistance", {"supply_resistance": 0.05}, {"supply_resistance": 0.05}),
    "winding_heating": ("winding_heating", {"heating": 0.4}, {"heating_per_s": 0.4}),
    "booster_volume": (None, {"Vb": 4.6e-4}, {"booster.volume": 4.6e-4}),
}
# sensor changes (pumpsim's sensor rivals, the same names): applied to a simulated case's channels
# (the pump itself unchanged)
SENSOR_CASES = {
    "pressure_offset": ("none", {"booster_pressure": (1.0, 800.0)}),
    "pressure_gain": ("none", {"booster_pressure": (1.02, 0.0)}),
    "current_gain": ("none", {"current": (1.03, 0.0)}),
}
NOISE = {"low": 0.002, "high": 0.01}     # sigma as a fraction of each channel's range (voltage: of its mean)
FORMATS = ("csv_kpa", "csv_mbar_ms", "csv_pa", "mat", "tdms", "csv_kpa_jitter")
RATES = {"csv_kpa": 1000.0, "csv_mbar_ms": 500.0, "csv_pa": 1000.0, "mat": 1000.0, "tdms": 1000.0,
         "csv_kpa_jitter": 1000.0}


def simulate(name: str, out: Path, duration: float = DURATION) -> Path:
    """Integrate one case and keep its clean channels (npz)."""
    path = out / "clean" / f"{name}.npz"
    if path.exists():
        return path
    pump = M.load(CONFIG)
    pump = replace(pump, **CASES[name][1])
    pd = M.PumpDown(pump, lambda t: pump.voltage, source_resistance=SOURCE_RESISTANCE)
    t = np.arange(int(round(duration * CLEAN_RATE)) + 1) / CLEAN_RATE
    r = pd.run(t, rtol=1e-5, method="LSODA")  # 1e-6 moves the channels by ~1e-5 of their value
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **{k: r[k] for k in ("time", "voltage", "current", "booster_pressure", "speed")})
    return path


def sample(clean: dict, rate: float, jitter: float, rng) -> dict:
    """The channels at the bench's sample times: a uniform grid at `rate`, each time moved by up
    to +-jitter sample periods (the values taken at the true times; the log's time column shows
    them as the bench's clock did, to the microsecond)."""
    n = int(round(clean["time"][-1] * rate)) + 1
    t = np.arange(n) / rate
    if jitter:
        t[1:-1] += jitter / rate * rng.uniform(-1, 1, n - 2)
    from scipy.interpolate import CubicSpline
    ch = {k: CubicSpline(clean["time"], clean[k])(t) for k in ("voltage", "current", "booster_pressure", "speed")}
    ch["time"] = np.round(t, 6)
    return ch


def add_noise(ch: dict, level: float, rng, sensors: dict) -> dict:
    out = dict(ch)
    for k, (gain, offset) in sensors.items():
        out[k] = gain * out[k] + offset
    for k in ("current", "booster_pressure", "speed"):
        out[k] = out[k] + level * np.ptp(ch[k]) * rng.standard_normal(out[k].size)
    out["voltage"] = out["voltage"] + level * np.mean(ch["voltage"]) * rng.standard_normal(out["voltage"].size)
    return out


def write_log(ch: dict, fmt: str, stem: Path) -> Path:
    """One bench-log file in the format a bench writes (spec §10)."""
    t, v, i, p, w = ch["time"], ch["voltage"], ch["current"], ch["booster_pressure"], ch["speed"]
    if fmt in ("csv_kpa", "csv_kpa_jitter"):
        cols = {"time [s]": (t, "%.6f"), "voltage [V]": (v, "%.4f"), "current [A]": (i, "%.4f"),
                "booster_pressure [kPa abs]": (p / 1e3, "%.4f")}
        return _csv(stem.with_suffix(".csv"), cols, ",", ["# EOL bench 3, EVP, booster 4 L"])
    if fmt == "csv_mbar_ms":
        cols = {"Time [ms]": (t * 1e3, "%.3f"), "Voltage [V]": (v, "%.3f"), "Current [A]": (i, "%.3f"),
                "booster_pressure [mbar abs]": (p / 1e2, "%.2f")}
        return _csv(stem.with_suffix(".csv"), cols, ";", ["# durability bench, channel export"])
    if fmt == "csv_pa":
        cols = {"time": (t, "%.6f"), "voltage": (v, "%.5f"), "current": (i, "%.5f"),
                "booster_pressure": (p, "%.1f"), "speed [rpm]": (w * 60 / (2 * np.pi), "%.2f")}
        return _csv(stem.with_suffix(".csv"), cols, ",", [])
    if fmt == "mat":
        from scipy.io import savemat
        path = stem.with_suffix(".mat")
        savemat(str(path), {"log": {"time": t, "voltage": v, "current": i, "booster_pressure": p}})
        return path
    if fmt == "tdms":
        from nptdms import ChannelObject, TdmsWriter
        path = stem.with_suffix(".tdms")
        units = {"time": "s", "voltage": "V", "current": "A", "booster_pressure": "kPa abs"}
        data = {"time": t, "voltage": v, "current": i, "booster_pressure": p / 1e3}
        with TdmsWriter(str(path)) as wr:
            wr.write_segment([ChannelObject("Bench", k, np.asarray(a, float), properties={"unit_string": units[k]})
                              for k, a in data.items()])
        return path
    raise ValueError(f"unknown format {fmt}")


def _csv(path: Path, cols: dict, sep: str, comments: list) -> Path:
    with open(path, "w") as f:
        for c in comments:
            f.write(c + "\n")
        f.write(sep.join(cols) + "\n")
        arrs = [a for a, _ in cols.values()]
        fmts = [fm for _, fm in cols.values()]
        for row in zip(*arrs):
            f.write(sep.join(fm % x for fm, x in zip(fmts, row)) + "\n")
    return path


def log_grid(quick: bool):
    """(log id, case, noise level, seed, format): the whole product for the pump cases, the sensor
    cases on fewer formats; QUICK: one seed, the low noise, two formats."""
    seeds = (1,) if quick else (1, 2)
    noises = ("low",) if quick else tuple(NOISE)
    fmts = ("csv_kpa", "tdms") if quick else FORMATS
    rows = []
    for case in list(CASES) + list(SENSOR_CASES):
        for noise in noises:
            for seed in seeds:
                for k, fmt in enumerate(fmts):
                    if case in SENSOR_CASES and k % 2:
                        continue
                    rows.append((case, noise, seed, fmt))
    return rows


def base_case(case: str) -> str:
    return SENSOR_CASES[case][0] if case in SENSOR_CASES else case


def generate(out: Path, quick: bool, jobs: int, cases=None) -> list:
    """Simulate what the grid needs (kept in out/clean), write its logs (names carry no hint of the
    truth: a hash of the grid point) and the manifest; `cases`: only these."""
    grid = [g for g in log_grid(quick) if cases is None or g[0] in cases]
    needed = sorted({base_case(c) for c, *_ in grid})
    with Pool(jobs) as pool:
        pool.map(_simulate_star, [(n, out) for n in needed], chunksize=1)
    (out / "logs").mkdir(parents=True, exist_ok=True)
    manifest = []
    for case, noise, seed, fmt in grid:
        base, sensors = base_case(case), (SENSOR_CASES[case][1] if case in SENSOR_CASES else {})
        clean = dict(np.load(out / "clean" / f"{base}.npz"))
        key = hashlib.sha1(f"{case}:{noise}:{seed}:{fmt}".encode()).hexdigest()[:10]
        rng = np.random.default_rng(int(key, 16))
        ch = sample(clean, RATES[fmt], 0.15 if fmt.endswith("jitter") else 0.0, rng)
        ch = add_noise(ch, NOISE[noise], rng, sensors)
        path = write_log(ch, fmt, out / "logs" / f"log_{key}")
        library, _, truth = CASES[base]
        manifest.append({"log": path.name, "case": case, "library": case if case in SENSOR_CASES else library,
                         "truth": truth, "sensors": {k: list(g) for k, g in sensors.items()}, "noise": noise,
                         "noise_sigma": NOISE[noise], "seed": seed, "format": fmt, "rate": RATES[fmt],
                         "duration": float(clean["time"][-1])})
    path = out / "manifest.json"
    known = {e["log"]: e for e in (json.loads(path.read_text()) if path.exists() else [])}
    known.update({e["log"]: e for e in manifest})
    path.write_text(json.dumps(list(known.values()), indent=1))
    return manifest


def _simulate_star(args):
    return simulate(*args)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(ROOT / "out" / "independent_gas"))
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cases", help="comma-separated case names (default: all)")
    a = ap.parse_args(argv)
    m = generate(Path(a.out), a.quick, a.jobs, a.cases.split(",") if a.cases else None)
    print(f"{len(m)} logs in {a.out}/logs, the truth in {a.out}/manifest.json")


if __name__ == "__main__":
    main()
