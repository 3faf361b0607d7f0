"""Coverage of the bench-log fit's 95 % intervals, white-noise against residual-aware (Newey-West):

- twin: logs from pumpsim's own pump-down model (white noise on every channel, several seeds) --
  coverage should stay near 95 % and the residual-aware intervals hardly wider;
- independent: the logs of bench/independent_gas (another implementation of spec §8; the cases
  the fitted parameters describe: none, booster leak, supply resistance, and winding heating whose
  resistance is the run's mean) -- how many intervals cover the truth.

Both from one fit per log (the two covariances share the Jacobian and residual).

    python bench/interval_coverage.py [--seeds 6] [--skip-twin] [--skip-independent] [--cases ...]

Writes out/interval_coverage.json and prints the tables. The independent logs are the quick grid's
(generated into --logs when missing: the independent model takes a few CPU minutes per case).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench" / "independent_gas"))

from pumpsim.benchlog import read_bench_log  # noqa: E402
from pumpsim.config import load_config  # noqa: E402
from pumpsim.identification.pumpdown_fit import identify_bench, twin_log  # noqa: E402

CONFIG = ROOT / "bench" / "independent_gas" / "evp_small_booster.toml"
PARAMS = ("mu", "booster.leak", "motor.resistance")
TWIN_TRUTH = {"mu": 0.165, "booster.leak": 3e-5, "motor.resistance": 0.275}
CASES = ("none", "booster_leak", "supply_resistance", "winding_heating")


def score(fit, truth: dict) -> dict:
    """Per parameter: value, relative error, both standard errors, whether each interval covers
    the truth, and the interval's widening (residual-aware half-width / white half-width)."""
    out = {}
    iv = fit.result.intervals
    for name, t in truth.items():
        e = fit.result.estimates.get(name)
        if e is None or e.value is None:
            continue
        q_white = _t_quantile(fit)
        half_white = q_white * e.stderr_white
        half = (e.upper95 - e.lower95) / 2
        out[name] = {"value": e.value, "truth": t, "rel_error": (e.value - t) / t,
                     "stderr_white": e.stderr_white, "stderr_residual_aware": e.stderr_residual_aware,
                     "error_in_white_se": (e.value - t) / e.stderr_white,
                     "covered_white": abs(e.value - t) <= half_white, "covered": e.lower95 <= t <= e.upper95,
                     "width_ratio": half / half_white, "quantile": iv.quantile.get(name)}
    return out


def _t_quantile(fit) -> float:
    from pumpsim.distributions import t_ppf
    n = sum(c.samples for c in fit.result.intervals.channels)
    return t_ppf(0.975, max(n - len(fit.result.estimates), 1))


def channels_of(fit) -> list:
    return [{"channel": c.channel, "samples": c.samples, "lag1": c.lag1, "durbin_watson": c.durbin_watson,
             "effective_samples": c.effective_samples, "bandwidth": c.bandwidth,
             "systematic_to_noise": c.systematic_rms / max(c.noise_rms, 1e-300),
             "systematic_share": c.systematic_share} for c in fit.result.intervals.channels]


def twin(seeds: int, duration: float, noise: float) -> list:
    cfg = load_config(CONFIG)
    rows = []
    for seed in range(seeds):
        t0 = time.process_time()
        log = twin_log(cfg, duration, 1000, values=TWIN_TRUTH, noise=noise, seed=seed)
        fit = identify_bench(cfg, log, list(PARAMS), ripple=False)
        truth = {**TWIN_TRUTH, "booster.pressure": cfg.pneumatic.booster_start}
        rows.append({"seed": seed, "scores": score(fit, truth), "channels": channels_of(fit),
                     "note": fit.result.intervals.note(), "cpu": time.process_time() - t0})
        print(f"twin seed {seed}: " + _row_text(rows[-1]), flush=True)
    return rows


def independent(out_dir: Path, cases) -> list:
    import generate as G  # bench/independent_gas: the logs (its clean runs are reused when present)
    import run as R  # the truth of a log

    G.generate(out_dir, True, 1, list(cases))
    manifest = json.loads((out_dir / "manifest.json").read_text())
    cfg = load_config(CONFIG)
    rows = []
    for entry in manifest:
        if entry["case"] not in cases:
            continue
        path = out_dir / "logs" / entry["log"]
        if not path.exists():
            continue
        t0 = time.process_time()
        fit = identify_bench(cfg, read_bench_log(path, cfg), list(PARAMS), ripple=False)
        rows.append({"log": entry["log"], "case": entry["case"], "format": entry["format"],
                     "scores": score(fit, R.truth_of(entry)), "channels": channels_of(fit),
                     "note": fit.result.intervals.note(), "cpu": time.process_time() - t0})
        print(f"{entry['case']:18s} {entry['format']:8s}: " + _row_text(rows[-1]), flush=True)
    return rows


def _row_text(row) -> str:
    return "; ".join(f"{n} {100 * s['rel_error']:+.2f} % ({s['error_in_white_se']:+.1f} se) "
                     f"{'Y' if s['covered_white'] else 'n'}->{'Y' if s['covered'] else 'n'} x{s['width_ratio']:.2f}"
                     for n, s in row["scores"].items()) + f"  [{row['cpu']:.0f} CPU s]"


def table(rows, names) -> str:
    lines = [f"  {'parameter':18s} covered white  covered aware  width ratio (median, max)"]
    for n in names:
        s = [r["scores"][n] for r in rows if n in r["scores"]]
        if not s:
            continue
        ratios = sorted(x["width_ratio"] for x in s)
        lines.append(f"  {n:18s} {sum(x['covered_white'] for x in s):5d}/{len(s):<6d}  "
                     f"{sum(x['covered'] for x in s):5d}/{len(s):<6d}  {ratios[len(ratios) // 2]:.2f}, {ratios[-1]:.2f}")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--duration", type=float, default=0.5)
    ap.add_argument("--noise", type=float, default=0.002, help="the independent logs' low noise level")
    ap.add_argument("--logs", default=str(ROOT / "out" / "independent_gas"))
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--skip-twin", action="store_true")
    ap.add_argument("--skip-independent", action="store_true")
    a = ap.parse_args(argv)
    report = {}
    if not a.skip_twin:
        report["twin"] = twin(a.seeds, a.duration, a.noise)
    if not a.skip_independent:
        report["independent"] = independent(Path(a.logs), a.cases.split(","))
    path = ROOT / "out" / "interval_coverage.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(report, indent=1, default=str))
    names = list(PARAMS) + ["booster.pressure"]
    for kind, rows in report.items():
        print(f"{kind}: {len(rows)} logs")
        print(table(rows, names))
    print(f"-> {path}")


if __name__ == "__main__":
    main()
