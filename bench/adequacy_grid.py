"""Where identification says the model cannot describe the data (`pumpsim.identification.adequacy`):
a generated grid of records -- 6 rigs x (no effect | each library effect at SNR 5 and 20), each
fitted (mu, theta0, speed) with its own config (`right`), with every other rig's config
(`mismatch`: vane count, housing, slot tilt, eccentricity), and with the speed held wrong
(+1, +3, -5 %) or searched from a start whose band misses the truth (-45 %; `local_minimum`).
Prints and writes (JSON) the verdict counts and the rates:

- mismatches flagged (verdict `inadequate`, exit 1),
- local minima flagged,
- right configs with in-library effects flagged, split by whether the fitted COF is still within
  5 % of the truth (a flag on a COF that far off is a right answer).

Records come from bench/diagnose_grid.py's generator (the same rigs, effect sizes and noise).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import diagnose_grid as G  # noqa: E402

from pumpsim.identification import identify  # noqa: E402

HELD = (0.01, 0.03, -0.05)  # relative error of a held (not fitted) speed
START = (-0.45,)  # a speed start whose +-50 % search band misses the truth
COF_OK = 0.05


def cases(rigs, snrs):
    for fam in rigs:
        for eff in ("none",) + G.EFFECTS:
            for snr in (snrs[:1] if eff == "none" else snrs):
                made = G.make_case(fam, eff, snr, 0, False)
                if made is None:
                    continue
                _, data, truth = made
                yield fam, eff, snr, data, truth, "right", G.rig(fam), ["mu", "theta0", "speed"]
                if eff != "none":
                    continue
                for other in rigs:
                    if other != fam:
                        yield fam, eff, snr, data, truth, "mismatch", G.rig(other), ["mu", "theta0", "speed"]
                for rel in HELD + START:
                    cfg = G.rig(fam)
                    cfg = dataclasses.replace(cfg, speed=cfg.speed * (1 + rel))
                    names = ["mu", "theta0"] + (["speed"] if rel in START else [])
                    yield fam, f"speed {rel:+.0%}", snr, data, truth, "local_minimum", cfg, names


def run(rigs, snrs, out=None, quiet=False):
    rows = []
    for fam, eff, snr, data, truth, kind, cfg, names in cases(rigs, snrs):
        t0 = time.perf_counter()
        res = identify(cfg, data, names)
        a = res.adequacy
        mu = res.value("mu")
        rows.append({"rig": fam, "truth": eff, "snr": snr, "kind": kind, "config": cfg.name, "verdict": a.verdict,
                     "order_misfit": a.order_misfit, "systematic_share": a.systematic_share,
                     "fit_percent": a.fit_percent, "mu": mu, "mu_true": truth["mu"],
                     "mu_ok": mu is not None and abs(mu / truth["mu"] - 1) <= COF_OK,
                     "problems": res.problems(), "wall": time.perf_counter() - t0})
        if not quiet:
            r = rows[-1]
            om = "-" if r["order_misfit"] is None else f"{r['order_misfit']:.3f}"
            print(f"{kind:14s} {fam:12s} {eff:22s} snr {snr:<3g} config {cfg.name:16s} {a.verdict:11s} "
                  f"order misfit {om:>6s} share {r['systematic_share']:.3f} mu {mu if mu is None else round(mu, 4)} "
                  f"(true {truth['mu']:.4g})", flush=True)
    return summarise(rows, out)


def summarise(rows, out=None):
    count = Counter((r["kind"], r["verdict"]) for r in rows)

    def rate(sel):
        sel = list(sel)
        return {"flagged": sum(r["verdict"] == "inadequate" for r in sel), "of": len(sel)}

    # a local minimum only where the speed matters: a model with shaft orders
    rates = {"mismatch_flagged": rate(r for r in rows if r["kind"] == "mismatch"),
             "local_minimum_flagged": rate(r for r in rows if r["kind"] == "local_minimum" and not r["mu_ok"]),
             "right_flagged_cof_ok": rate(r for r in rows if r["kind"] == "right" and r["mu_ok"]),
             "right_flagged_cof_off": rate(r for r in rows if r["kind"] == "right" and not r["mu_ok"])}
    print("\nverdicts:", dict(sorted(count.items())))
    for k, v in rates.items():
        print(f"  {k:24s} {v['flagged']}/{v['of']}")
    if out:
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        Path(out).write_text(json.dumps({"rates": rates, "cases": rows}, indent=1, default=str))
    return rates


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rigs", default=",".join(G.RIGS))
    ap.add_argument("--snrs", default="5,20")
    ap.add_argument("--json", default="out/bench_adequacy.json")
    a = ap.parse_args()
    run(a.rigs.split(","), [float(s) for s in a.snrs.split(",")], a.json)


if __name__ == "__main__":
    main()
