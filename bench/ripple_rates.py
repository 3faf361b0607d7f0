"""From what sample rate the current's vane-passing ripple tells vane friction
(docs/explanation/bench-log.md, "The current's vane-passing ripple"): twin logs of the EVP example
with a 0.4 L booster (1 s, a third of its pump-down), the truth mu 0.165 and motor.friction
0.015 N m (config 0.15 and 0.01), white noise of `noise` x each channel's range (the voltage:
of its mean), over sample rates x noise x seeds. For each: the ripple's mu, its standard error,
whether the truth is inside its 95 % interval, and the motor.friction it implies (the mean-current
fit taken as exact, so the friction's error is the ripple's alone).

    python bench/ripple_rates.py [--quick] [--json out.json]
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
from pumpsim.identification.current_ripple import Z95, ripple_mu  # noqa: E402
from pumpsim.identification.pumpdown_fit import twin_log, values_vector  # noqa: E402

RATES = (500.0, 1000.0, 2000.0, 5000.0, 10000.0, 20000.0)
NOISES = (0.0005, 0.005)
SEEDS = (0, 1)
DURATION = 1.0
TRUTH = {"mu": 0.165, "motor.friction": 0.015}
RIG = {"booster.volume": 4.0e-4, "booster.target": 40000.0}
# mu and motor.friction count as separated when the friction's 95 % half-width is below half of it
SEPARATED_SHARE = 0.5


def case(cfg, rate, noise, seed) -> dict:
    log = twin_log(cfg, DURATION, rate, values=TRUTH, noise=noise, seed=seed, rtol=1e-7, atol=1e-9)
    t0 = time.perf_counter()
    r = ripple_mu(cfg, log, lambda v: values_vector(cfg, v), dict(TRUTH))
    row = {"rate": rate, "noise": noise, "seed": seed, "resolved": r.resolved, "orders": r.orders,
           "threshold": r.threshold, "seconds": time.perf_counter() - t0}
    if r.resolved:
        row.update(mu=r.mu, stderr=r.stderr, error=r.mu / TRUTH["mu"] - 1,
                   inside=bool(abs(r.mu - TRUTH["mu"]) <= Z95 * r.stderr),
                   friction=r.friction, friction_stderr=r.friction_stderr,
                   separated=bool(Z95 * r.friction_stderr < SEPARATED_SHARE * TRUTH["motor.friction"]))
    else:
        row["reason"] = r.reason
    print(json.dumps(row), flush=True)
    return row


def table(rows) -> str:
    out = ["| rate | noise | orders | mu error (per seed) | stderr | truth in 95 % | motor.friction [mN m] "
           "| separated |",
           "|---|---|---|---|---|---|---|---|"]
    for rate in sorted({r["rate"] for r in rows}):
        for noise in sorted({r["noise"] for r in rows}):
            rs = [r for r in rows if r["rate"] == rate and r["noise"] == noise]
            if not rs:
                continue
            head = f"| {rate / 1000:g} kHz | {100 * noise:g} % | {', '.join(map(str, rs[0]['orders'])) or '-'} |"
            if not any(r["resolved"] for r in rs):
                out.append(head + " not resolved (no number) | | | | |")
                continue

            def each(fmt, r):
                return fmt(r) if r["resolved"] else "no number"
            err = ", ".join(each(lambda r: f"{100 * r['error']:+.1f} %", r) for r in rs)
            se = ", ".join(each(lambda r: f"{100 * r['stderr'] / TRUTH['mu']:.1f} %", r) for r in rs)
            fr = ", ".join(each(lambda r: f"{1e3 * r['friction']:.1f} ± {1e3 * r['friction_stderr']:.1f}", r) for r in rs)
            ok = [r for r in rs if r["resolved"]]
            out.append(f"{head} {err} | {se} | {sum(r['inside'] for r in ok)}/{len(ok)} | {fr} | "
                       f"{sum(r['separated'] for r in ok)}/{len(ok)} |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="one seed, 2 and 0.5 kHz only")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    cfg = config_from_dict(with_changes(example_table("evp_booster"), RIG))
    rates, seeds = ((500.0, 2000.0), SEEDS[:1]) if a.quick else (RATES, SEEDS)
    rows = [case(cfg, rate, noise, seed) for rate in rates for noise in NOISES for seed in seeds]
    print(table(rows))
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
