"""Diagnose wall time against the record length (issue 11 item 7: 40,000 samples in <= 30 s, cost no
worse than linear): a no-effect record and a k = 4 out-of-round record (the `make bench` diagnose
case) on the 4-vane ellipse at 20 kHz, 5 % noise, each at several lengths, in one process.

    .venv/bin/python bench/diagnose_scale.py [--samples 10000 20000 40000] [--case none oval4]
        [--kernel simd scalar] [--profile out/diagnose.prof] [--json out/bench_diagnose_scale.json]

Prints, per case, length and kernel: wall time, the process's CPU time (all threads; on a shared
machine the less load-dependent number), the effects named and the verdict. `--kernel scalar`
sets PUMPSIM_FIT_KERNEL=scalar (model torques on the CasADi map, as before the SIMD path); with
both kernels each record runs back to back under the same load. Not a test: the machine is
shared; compare within one run and quote the load with the numbers."""
from __future__ import annotations

import argparse
import cProfile
import dataclasses
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pumpsim.config import load_config  # noqa: E402
from pumpsim.data import Dataset  # noqa: E402
from pumpsim.diagnosis import diagnose  # noqa: E402
from pumpsim.simulate import simulate  # noqa: E402

RATE = 20000.0
CASES = {"none": [], "oval4": [[4, 2e-5, 0.3]]}


def record(case: str, samples: int, seed: int = 0):
    """The base config and a simulated record with the case's hidden harmonics and 5 % noise."""
    base = load_config(ROOT / "examples" / "ellipse_4vanes.toml")
    truth = dataclasses.replace(base, angle=0.4)
    if CASES[case]:
        truth = truth.with_harmonics(CASES[case])
    sim = simulate(truth, duration=(samples - 0.5) / RATE, rate=RATE)
    y = sim.torque + np.random.default_rng(seed).normal(0, 0.05 * np.std(sim.torque), sim.time.size)
    return base, Dataset(sim.time, y)


def run_one(case: str, samples: int, kernel: str = "simd", profile=None) -> dict:
    base, data = record(case, samples)
    os.environ["PUMPSIM_FIT_KERNEL"] = kernel
    t0, c0 = time.perf_counter(), time.process_time()
    if profile:
        pr = cProfile.Profile()
        out = pr.runcall(diagnose, base, data)
        pr.dump_stats(profile)
    else:
        out = diagnose(base, data)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    js = out.to_json() if hasattr(out, "to_json") else dict(out)
    return {"case": case, "samples": int(data.n), "kernel": kernel, "seconds": wall, "cpu_seconds": cpu,
            "load": os.getloadavg()[0], "effects": list(js["effects"]),
            "verdict": js["verdict"], "unexplained": js.get("unexplained"), "final_rms": js["final"]["rms"]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, nargs="*", default=[10000, 20000, 40000])
    ap.add_argument("--case", nargs="*", choices=list(CASES), default=list(CASES))
    ap.add_argument("--kernel", nargs="*", choices=["simd", "scalar"], default=["simd"])
    ap.add_argument("--profile", help="cProfile output (one case and length only)")
    ap.add_argument("--json")
    a = ap.parse_args()
    load = os.getloadavg()
    print(f"load average at start: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    diagnose(*record("none", 2000))  # kernels loaded and maps built outside the timings
    rows = []
    for case in a.case:
        for n in a.samples:
            for kernel in a.kernel:
                r = run_one(case, n, kernel, a.profile)
                rows.append(r)
                print(f"{case:6s} {r['samples']:6d} samples  {kernel:6s} {r['seconds']:6.1f} s wall  "
                      f"{r['cpu_seconds']:6.1f} s CPU  load {r['load']:.1f}  effects {r['effects']}  "
                      f"verdict {r['verdict']}", flush=True)
    print(f"load average at end: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    if a.json:
        Path(a.json).parent.mkdir(parents=True, exist_ok=True)
        Path(a.json).write_text(json.dumps({"load_start": load, "load_end": os.getloadavg(), "rows": rows},
                                           indent=1))


if __name__ == "__main__":
    main()
