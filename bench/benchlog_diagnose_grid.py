"""Robustness benchmark of the bench-log diagnosis (`pumpsim diagnose CONFIG LOG`, spec §10):
twin logs made on the fly with fixed seeds -- every pump-level library effect, clean logs and
changes outside the library that an independent rig plausibly has (another booster volume, a
pressure sensor's offset and span error, a current shunt's gain error, a supply ripple the logger
filters out) x 2 noise levels x 2 seeds -- diagnosed with the nominal config. The sensor faults
(a pressure sensor's offset and span, a current shunt's gain) are the library's sensor rivals. Prints each case;
writes every case and the rates, before the misspecification guard (pump_guard) and after it, to
JSON. --quick: one seed at the lower noise (~13 diagnoses).

The pump: the EVP example with a 0.4 L booster (a 0.5 s log covers its pump-down from the
atmosphere to ~35 kPa), vane COF 0.17 (the config's 0.15: the baseline fits it). Noise: `noise` x
each channel's range (0.5 % and 1 %), on every channel, voltage included. Fault sizes: a clear
fault of each kind (FAULTS, OUTSIDE). The model integrator: rtol 1e-4 (the twins are made at 1e-6).

Each case's outcome is one of: named_right (the library effect alone), confounded_with_truth (no
name; a pair holding the truth reported confounded), wrong_name (any name that is not the truth
alone: the rate that must be ~0), unexplained (nothing named, unexplained), nothing (nothing named,
consistent with noise). Right answers: a pump effect named_right -- or, for supply_resistance
and winding_resistance, which act identically on a log, their pair confounded; a sensor fault
named_right or confounded_with_truth (the log cannot always tell a sensor from the pump: the pair
is reported with the check that separates them); a clean log nothing; an outside change
unexplained (nothing is not wrong by name, but silent). Rates per kind: library (the pump's
effects), sensor, clean, outside.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pumpsim.bundled import example_table, with_changes  # noqa: E402
from pumpsim.config import config_from_dict  # noqa: E402
from pumpsim.diagnosis.pump_twins import twin_with_fault  # noqa: E402
from pumpsim.diagnosis.pump_workflow import diagnose_bench  # noqa: E402

FAULTS = {"booster_leak": 4e-5, "tip_clearance": 8e-6, "valve_late": 10000.0, "motor_friction": 0.05,
          "supply_resistance": 0.08, "winding_heating": 0.15, "winding_resistance": 0.08}
# the bench's sensors (changes from a calibrated sensor: gain - 1, offset in Pa)
SENSOR_FAULTS = {"pressure_offset": 1500.0, "pressure_gain": 0.03, "current_gain": 0.05}
OUTSIDE = {"booster_volume": 1.3, "voltage_ripple": 0.5}
LIBRARY = {**FAULTS, **SENSOR_FAULTS}
NOISE = (0.005, 0.01)
SEEDS = (1, 2)
TRUTH = {"mu": 0.17}
RTOL, ATOL = 1e-4, 1e-5
TWINS = {("supply_resistance", "winding_resistance")}  # identical on a log: `confounded` is right


def small_booster():
    table = with_changes(example_table("evp_booster"), {"booster.volume": 4.0e-4, "booster.target": 40000.0})
    return config_from_dict(table, "evp_small_booster")


OUTCOMES = ("named_right", "confounded_with_truth", "wrong_name", "unexplained", "nothing")


def outcome(fault, named, confounded, unexplained) -> str:
    """One of OUTCOMES (module doc)."""
    if named:
        return "named_right" if named == [fault] else "wrong_name"
    if fault in LIBRARY and any(fault in p for p in confounded):
        return "confounded_with_truth"
    return "unexplained" if unexplained else "nothing"


def is_right(fault, out, confounded, resistance_known) -> bool:
    if fault is None:
        return out == "nothing"
    if fault in OUTSIDE:
        return out == "unexplained"
    if fault in SENSOR_FAULTS:
        return out in ("named_right", "confounded_with_truth")
    twins = not resistance_known and any(tuple(sorted(p)) in TWINS and fault in p for p in confounded)
    return out == "named_right" or (out == "confounded_with_truth" and twins)


def case(cfg, fault, size, noise, seed, duration, rate, resistance_known=False, atmosphere_known=False) -> dict:
    t0 = time.perf_counter()
    log = twin_with_fault(cfg, duration, rate, fault, size, values=TRUTH, noise=noise, seed=seed)
    res = diagnose_bench(cfg, log, resistance_known=resistance_known, rtol=RTOL, atol=ATOL,
                         atmosphere_known=atmosphere_known)
    # before the guard: what the search named and whether its final residual was noise
    before = [s.effect.name for s in (res.withdrawn or res.steps)]
    out = {"fault": fault or "clean", "size": size, "noise": noise, "seed": seed, "resistance_known": resistance_known,
           "atmosphere_known": atmosphere_known,
           "named": res.effects, "named_before_guard": before, "confounded": res.confounded,
           "unexplained": res.unexplained, "unexplained_before_guard": not res.final["residual_white"],
           "guard": res.consistency, "verdict": res.verdict, "notes": res.notes, "runs": res.runs,
           "wall_time": time.perf_counter() - t0,
           "steps": [s.to_json() for s in res.steps + res.withdrawn]}
    for tag, named, unexp in (("", res.effects, res.unexplained),
                              ("_before_guard", before, out["unexplained_before_guard"])):
        out["outcome" + tag] = o = outcome(fault, named, res.confounded, unexp)
        out["right" + tag] = is_right(fault, o, res.confounded, resistance_known)
    return out


def shares(sel, key) -> dict | None:
    """{outcome: rate, "right": rate, "of": n} of the cases `sel` by their `key` outcome."""
    sel = list(sel)
    if not sel:
        return None
    tag = key[len("outcome"):]
    out = {o: sum(c[key] == o for c in sel) / len(sel) for o in OUTCOMES}
    return {**out, "right": sum(c["right" + tag] for c in sel) / len(sel), "of": len(sel)}


def fires(sel) -> dict | None:
    sel = list(sel)
    return {"rate": sum(c["guard"]["fires"] for c in sel) / len(sel), "of": len(sel)} if sel else None


def rates(cases) -> dict:
    kinds = {"library": FAULTS, "sensor": SENSOR_FAULTS, "clean": {"clean": 0}, "outside": OUTSIDE}
    out = {}
    for key in ("outcome_before_guard", "outcome"):
        out["before_guard" if key.endswith("guard") else "after_guard"] = {
            "overall": {k: shares((c for c in cases if c["fault"] in names), key) for k, names in kinds.items()},
            "per_effect": {f: shares((c for c in cases if c["fault"] == f), key)
                           for f in [*LIBRARY, "clean", *OUTSIDE]}}
    # the guard's false alarms (clean logs; a library fault the search named right) and its catches
    out["guard_fires"] = {
        "clean": fires(c for c in cases if c["fault"] == "clean"),
        "named_right_single": fires(c for c in cases if c["outcome_before_guard"] == "named_right"),
        "wrong_name": fires(c for c in cases if c["outcome_before_guard"] == "wrong_name"),
        "sensor": fires(c for c in cases if c["fault"] in SENSOR_FAULTS),
        "outside": fires(c for c in cases if c["fault"] in OUTSIDE)}
    return out


def table(r) -> str:
    """The rates as a Markdown table: per effect and kind, each outcome's rate after the guard (and
    before it, where they differ)."""
    def cell(a, b, o):
        x, y = (round(100 * v[o]) for v in (b, a))
        return f"{y} %" if x == y else f"{x} → {y} %"

    cols = ("right",) + OUTCOMES
    rows = ["| case | of | " + " | ".join(o.replace("_", " ") for o in cols) + " |",
            "|---|---|" + "---|" * len(cols)]
    after, before = r["after_guard"], r["before_guard"]
    for group in ("per_effect", "overall"):
        for name, a in after[group].items():
            if a is not None:
                b = before[group][name]
                label = f"**{name}** (all)" if group == "overall" else f"`{name}`"
                rows.append(f"| {label} | {a['of']} | " + " | ".join(cell(a, b, o) for o in cols) + " |")
    return "\n".join(rows)


def _one(args):
    cfg = small_booster()
    fault, size, noise, seed, duration, rate, atmosphere_known = args
    return case(cfg, None if fault == "clean" else fault, size, noise, seed, duration, rate,
                atmosphere_known=atmosphere_known)


def run(quick=False, only=None, seeds=None, noise=None, duration=0.5, rate=500.0, jobs=1, path=None, say=print,
        atmosphere_known=False) -> dict:
    """The grid's cases and rates ({"cases", "rates", ...}); `path`: rewritten after each case.
    atmosphere_known: every diagnosis is told the booster starts at the config's atmosphere."""
    kinds = {**LIBRARY, "clean": 0.0, **OUTSIDE}
    plan = [(f, s, n, seed, duration, rate, atmosphere_known) for f, s in kinds.items() if only is None or f in only
            for n in (noise or (NOISE[:1] if quick else NOISE)) for seed in SEEDS[:seeds or (1 if quick else len(SEEDS))]]
    t0, cases = time.perf_counter(), []
    result = {}
    with ProcessPoolExecutor(jobs) if jobs > 1 else _Serial() as pool:
        for c in pool.map(_one, plan):
            cases.append(c)
            say(f"{c['fault']:<20} noise {c['noise']:<6g} seed {c['seed']}: {c['outcome']:<22} named {c['named']} "
                f"(before the guard {c['named_before_guard']}) guard p {c['guard']['p_value']:.2g} confounded "
                f"{c['confounded']} unexplained {c['unexplained']} ({c['runs']} runs, {c['wall_time']:.0f} s)")
            result = {"cases": cases, "rates": rates(cases), "duration": duration, "rate": rate, "rtol": RTOL,
                      "quick": quick, "jobs": jobs, "atmosphere_known": atmosphere_known,
                      "wall_time": time.perf_counter() - t0,
                      "wall_time_cases": sum(c["wall_time"] for c in cases)}
            if path is not None:
                path.write_text(json.dumps(result, indent=1))
    return result


class _Serial:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    @staticmethod
    def map(f, items):
        return map(f, items)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=str(ROOT / "out" / "bench_benchlog_diagnose.json"))
    ap.add_argument("--quick", action="store_true", help="one seed at the lower noise level")
    ap.add_argument("--duration", type=float, default=0.5)
    ap.add_argument("--rate", type=float, default=500.0)
    ap.add_argument("--only", help="comma-separated faults (and 'clean', or outside faults)")
    ap.add_argument("--seeds", type=int, help=f"the first N seeds (default {len(SEEDS)}, --quick 1)")
    ap.add_argument("--noise", help=f"comma-separated noise levels (default {','.join(map(str, NOISE))})")
    ap.add_argument("--jobs", type=int, default=1, help="diagnoses run at once (processes)")
    ap.add_argument("--atmosphere-known", action="store_true", help="diagnose with the booster's start known "
                    "(the config's atmosphere: diagnose --atmosphere-known)")
    a = ap.parse_args(argv)
    path = Path(a.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    res = run(a.quick, set(a.only.split(",")) if a.only else None, a.seeds,
              [float(x) for x in a.noise.split(",")] if a.noise else None, a.duration, a.rate, a.jobs, path,
              say=lambda m: print(m, flush=True), atmosphere_known=a.atmosphere_known)
    print(json.dumps(res["rates"]["guard_fires"], indent=1))
    print(table(res["rates"]))
    print(f"{len(res['cases'])} diagnoses in {res['wall_time']:.0f} s wall")


if __name__ == "__main__":
    main()
