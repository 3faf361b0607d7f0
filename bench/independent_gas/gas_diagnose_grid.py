"""A small diagnose grid on logs from the independent pump-down model (model.py): the sensor rivals
and two pump effects, where a wrong name is the failure that looks right.

Conditions: a clean pump; the pressure sensor's span 2 % high and 2 % low; its offset; the current
sensor's gain; the motor's friction grown; a booster leak -- x 2 seeds, one noise level (generate's
`low`), one format's sample rate. The sensor changes are applied to the clean pump's channels, so the
grid costs three integrations of the independent model (kept in OUT/clean) and one diagnosis per log,
in this process (`diagnose_bench`, as `pumpsim diagnose CONFIG LOG` calls it).

Outcomes: right (the truth named alone; for the clean pump, nothing named), confounded (no name, a
confounded pair holding the truth), unexplained (no name, the verdict unexplained), nothing (no
name, consistent with noise), wrong (any other name).

    python bench/independent_gas/gas_diagnose_grid.py [--out out/independent_gas] [--seeds 2] [--json F]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import generate as G  # noqa: E402

sys.path.insert(0, str(G.ROOT))
from pumpsim.benchlog import BenchLog  # noqa: E402
from pumpsim.config import load_config  # noqa: E402
from pumpsim.diagnosis.pump_workflow import diagnose_bench  # noqa: E402

# condition -> (the independent model's case, sensor changes {channel: (gain, offset)}, the truth's
# library name (None: nothing to name))
CONDITIONS = {
    "clean": ("none", {}, None),
    "span_high": ("none", {"booster_pressure": (1.02, 0.0)}, "pressure_gain"),
    "span_low": ("none", {"booster_pressure": (0.98, 0.0)}, "pressure_gain"),
    "pressure_offset": ("none", {"booster_pressure": (1.0, 800.0)}, "pressure_offset"),
    "current_gain": ("none", {"current": (1.03, 0.0)}, "current_gain"),
    "motor_friction": ("motor_friction", {}, "motor_friction"),
    "booster_leak": ("booster_leak", {}, "booster_leak"),
}
OUTCOMES = ("right", "confounded", "unexplained", "nothing", "wrong")
RATE, NOISE = 1000.0, "low"


def bench_log(out: Path, condition: str, seed: int) -> BenchLog:
    """One log of the grid: the case's clean channels sampled, the sensor changes and the noise added."""
    case, sensors, _ = CONDITIONS[condition]
    clean = dict(np.load(G.simulate(case, out)))
    rng = np.random.default_rng([seed, sorted(CONDITIONS).index(condition)])
    ch = G.add_noise(G.sample(clean, RATE, 0.0, rng), G.NOISE[NOISE], rng, sensors)
    return BenchLog(ch["time"], ch["voltage"], ch["current"], ch["booster_pressure"], source=f"{condition}-{seed}")


def outcome(truth, named, confounded, unexplained) -> str:
    if named:
        return "right" if truth is not None and named == [truth] else "wrong"
    if truth is None:
        return "unexplained" if unexplained else "right"
    if any(truth in p for p in confounded):
        return "confounded"
    return "unexplained" if unexplained else "nothing"


def run(out: Path, seeds: int, atmosphere_known: bool = False, only=None, say=print, path=None) -> dict:
    """The grid's cases and rates; `path`: the JSON, rewritten after each case."""
    cfg = load_config(G.CONFIG)
    cases = []
    for condition, (_, _, truth) in CONDITIONS.items():
        if only and condition not in only:
            continue
        for seed in range(1, seeds + 1):
            t0 = time.process_time()
            res = diagnose_bench(cfg, bench_log(out, condition, seed), atmosphere_known=atmosphere_known)
            c = {"condition": condition, "seed": seed, "truth": truth, "named": res.effects,
                 "withdrawn": [s.effect.name for s in res.withdrawn], "confounded": res.confounded,
                 "unexplained": res.unexplained, "verdict": res.verdict,
                 "outcome": outcome(truth, res.effects, res.confounded, res.unexplained),
                 "cpu": time.process_time() - t0, "notes": res.notes, "guard": res.consistency,
                 "baseline_rms": res.baseline["rms"], "final_rms": res.final["rms"],
                 "steps": [s.to_json() for s in res.steps + res.withdrawn]}
            cases.append(c)
            say(f"{condition:<16} seed {seed}: {c['outcome']:<12} named {c['named']} confounded {c['confounded']} "
                f"withdrawn {c['withdrawn']} ({c['cpu']:.0f} CPU s)")
            if path is not None:
                path.write_text(json.dumps({"cases": cases, "atmosphere_known": atmosphere_known,
                                            "rates": rates(cases)}, indent=1))
    return {"cases": cases, "atmosphere_known": atmosphere_known, "rates": rates(cases)}


def rates(cases) -> dict:
    out = {}
    for condition in dict.fromkeys(c["condition"] for c in cases):
        sel = [c for c in cases if c["condition"] == condition]
        out[condition] = {**{o: sum(c["outcome"] == o for c in sel) for o in OUTCOMES}, "of": len(sel)}
    out["all"] = {**{o: sum(c["outcome"] == o for c in cases) for o in OUTCOMES}, "of": len(cases)}
    return out


def table(r: dict) -> str:
    rows = ["| condition | of | " + " | ".join(OUTCOMES) + " |", "|---|---|" + "---|" * len(OUTCOMES)]
    rows += [f"| {k} | {v['of']} | " + " | ".join(str(v[o]) for o in OUTCOMES) + " |" for k, v in r.items()]
    return "\n".join(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(G.ROOT / "out" / "independent_gas"))
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--only", help="comma-separated conditions (default: all)")
    ap.add_argument("--atmosphere-known", action="store_true")
    ap.add_argument("--json", default=str(G.ROOT / "out" / "bench_independent_gas_grid.json"))
    a = ap.parse_args(argv)
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    res = run(Path(a.out), a.seeds, a.atmosphere_known, set(a.only.split(",")) if a.only else None,
              say=lambda m: print(m, flush=True), path=Path(a.json))
    print(table(res["rates"]))


if __name__ == "__main__":
    main()
