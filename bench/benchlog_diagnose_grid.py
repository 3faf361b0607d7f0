"""Robustness benchmark of the bench-log diagnosis (`pumpsim diagnose CONFIG LOG`, spec §10):
twin logs made on the fly with fixed seeds -- every pump-level library effect x 2 noise levels x 2
seeds, plus clean logs and faults outside the library (a larger booster, a pressure sensor
offset) -- diagnosed with the nominal config. Prints each case and the rates; writes them (and
every case) to JSON.

The pump: the EVP example with a 0.4 L booster (a 0.5 s log covers its pump-down from the
atmosphere to ~35 kPa), vane COF 0.17 (the config's 0.15: the baseline fits it). Noise: `noise` x
each channel's range (0.5 % and 1 %), on every channel, voltage included. Fault sizes: a clear
fault of each kind (FAULTS). The model integrator: rtol 1e-4 (the twins are made at 1e-6): a
clean log's residual is the noise to ~1 %.

Right answers: a library effect named alone, or -- supply_resistance and winding_resistance act
identically on a log -- that pair reported `confounded` and neither named. A pair the log cannot
separate (a booster leak and a grown tip clearance on a short log) reported `confounded` with the
truth in it is counted apart (confounded_with_truth): honest, but no name. A clean log: nothing named, not unexplained. An
outside fault: no library effect named (unexplained, or nothing, is right).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pumpsim.bundled import example_table, with_changes  # noqa: E402
from pumpsim.config import config_from_dict  # noqa: E402
from pumpsim.diagnosis.pump_twins import twin_with_fault  # noqa: E402
from pumpsim.diagnosis.pump_workflow import diagnose_bench  # noqa: E402

FAULTS = {"booster_leak": 4e-5, "tip_clearance": 8e-6, "valve_late": 10000.0, "motor_friction": 0.05,
          "supply_resistance": 0.08, "winding_heating": 0.15, "winding_resistance": 0.08}
OUTSIDE = {"booster_volume": 1.3, "pressure_offset": 1500.0}
NOISE = (0.005, 0.01)
SEEDS = (1, 2)
TRUTH = {"mu": 0.17}
RTOL, ATOL = 1e-4, 1e-5
TWINS = {("supply_resistance", "winding_resistance")}  # identical on a log: `confounded` is right


def small_booster():
    table = with_changes(example_table("evp_booster"), {"booster.volume": 4.0e-4, "booster.target": 40000.0})
    return config_from_dict(table, "evp_small_booster")


def outcome(fault, res, resistance_known) -> str:
    """right / confounded_with_truth / false_name / false_unexplained / missed."""
    named = res.effects
    pair = {tuple(sorted(p)) for p in res.confounded}
    if fault is None or fault in OUTSIDE:
        if named:
            return "false_name"
        return "false_unexplained" if fault is None and res.unexplained else "right"
    if named == [fault]:
        return "right"
    if not named and not resistance_known and any(fault in p and p in TWINS for p in pair):
        return "right"
    if not named and any(fault in p for p in pair):  # honest, not a name: the log cannot separate them
        return "confounded_with_truth"
    if any(n != fault for n in named):
        return "false_name"
    return "false_unexplained" if res.unexplained else "missed"


def case(cfg, fault, size, noise, seed, duration, rate, resistance_known=False) -> dict:
    t0 = time.perf_counter()
    log = twin_with_fault(cfg, duration, rate, fault, size, values=TRUTH, noise=noise, seed=seed)
    res = diagnose_bench(cfg, log, resistance_known=resistance_known, rtol=RTOL, atol=ATOL)
    out = {"fault": fault, "size": size, "noise": noise, "seed": seed, "resistance_known": resistance_known,
           "named": res.effects, "confounded": res.confounded, "unexplained": res.unexplained,
           "verdict": res.verdict, "runs": res.runs, "wall_time": time.perf_counter() - t0,
           "steps": [s.to_json() for s in res.steps]}
    out["outcome"] = outcome(fault, res, resistance_known)
    return out


def rates(cases) -> dict:
    def share(sel, what):
        sel = list(sel)
        return {"rate": sum(c["outcome"] == what for c in sel) / len(sel), "of": len(sel)} if sel else None

    lib = [c for c in cases if c["fault"] in FAULTS]
    clean = [c for c in cases if c["fault"] is None]
    outside = [c for c in cases if c["fault"] in OUTSIDE]
    return {"named_right": share(lib, "right"), "confounded_with_truth": share(lib, "confounded_with_truth"),
            "false_names_library": share(lib, "false_name"),
            "false_names_clean": share(clean, "false_name"), "false_unexplained_clean": share(clean, "false_unexplained"),
            "false_names_outside": share(outside, "false_name"),
            "per_effect": {f: share((c for c in lib if c["fault"] == f), "right") for f in FAULTS}}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=str(ROOT / "out" / "benchlog_diagnose_grid.json"))
    ap.add_argument("--duration", type=float, default=0.5)
    ap.add_argument("--rate", type=float, default=500.0)
    ap.add_argument("--only", help="comma-separated faults (and 'clean', or outside faults)")
    ap.add_argument("--seeds", type=int, default=len(SEEDS), help="the first N seeds")
    ap.add_argument("--noise", help=f"comma-separated noise levels (default {','.join(map(str, NOISE))})")
    a = ap.parse_args(argv)
    cfg = small_booster()
    only = set(a.only.split(",")) if a.only else None
    plan = [(f, s) for f, s in {**FAULTS, **OUTSIDE, "clean": 0.0}.items() if only is None or f in only]
    cases = []
    path = Path(a.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    for fault, size in plan:
        for noise in [float(x) for x in a.noise.split(",")] if a.noise else NOISE:
            for seed in SEEDS[:a.seeds]:
                c = case(cfg, None if fault == "clean" else fault, size, noise, seed, a.duration, a.rate,
                         resistance_known=False)
                cases.append(c)
                print(f"{fault:<20} noise {noise:<6g} seed {seed}: {c['outcome']:<18} named {c['named']} "
                      f"confounded {c['confounded']} unexplained {c['unexplained']} ({c['runs']} runs, "
                      f"{c['wall_time']:.0f} s)", flush=True)
                path.write_text(json.dumps({"cases": cases, "rates": rates(cases), "duration": a.duration,
                                            "rate": a.rate, "rtol": RTOL}, indent=1))
    print(json.dumps(rates(cases), indent=1))


if __name__ == "__main__":
    main()
