"""Diagnose on independent measurements: a seeded grid of rigs x effects x SNR x seeds x formats.

Every record is made by bench/independent (own Model 2, own effect forms, own noise and file
formats); `pumpsim diagnose CONFIG DATA --json` runs on it as a black box with the nominal config
(effect hidden). Prints the confusion matrix and the rates; writes out/bench_independent.json.

  python bench/independent/run.py [--quick] [--rigs a,b] [--effects a,b] [--snrs 3,5,10] [--seeds 1]
  python bench/independent/run.py --case RIG:EFFECT:SNR:SEED:FORMAT:RATE:DURATION   (one case, kept)
"""
from __future__ import annotations

import argparse
import collections
import json
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent.parent))

from bench.independent.formats import FORMATS, write  # noqa: E402
from bench.independent.records import EFFECTS, LIBRARY, NO_EFFECT, OUT_OF_LIBRARY, make_record  # noqa: E402
from bench.independent.rig import RIGS, to_toml  # noqa: E402

# (rate Hz, duration s) cycled over the grid: 10-20 kHz, 0.5-2 s
SAMPLINGS = ((10000.0, 0.5), (20000.0, 0.5), (12500.0, 1.0), (16000.0, 0.5), (10000.0, 2.0))
QUICK = [("concentric4", "none"), ("concentric4", "rotor_eccentricity"), ("concentric4", "hum"),
         ("concentric4", "speed_ripple"), ("eccentric5", "housing_out_of_round"), ("eccentric5", "none"),
         ("ellipse1", "rotor_eccentricity"), ("ellipse3", "sensor_lag"), ("ellipse3", "drift"),
         ("ellipse4", "vane_friction_spread"), ("ellipse4", "none"), ("ellipse4", "impulse"),
         ("ellipse4", "torque_offset"), ("tilted3", "viscous_tip_friction"), ("tilted3", "speed_ripple"),
         ("tilted3", "ar1_noise"), ("ellipse4", "rotor_eccentricity"), ("eccentric5", "vane_friction_spread"),
         ("ellipse1", "housing_out_of_round"), ("concentric4", "torque_offset"),
         ("concentric4", "off_speed")]


def grid(rigs, effects, snrs, seeds, quick, full=False):
    if quick:
        pairs = [(r, e, 5.0) for r, e in QUICK]
    elif full:
        pairs = [(r, e, snr) for r in rigs for e in effects for snr in snrs]
    else:   # balanced: every effect at every SNR, the rig turning so each rig meets each SNR
        pairs = [(rigs[(i * len(snrs) + j) % len(rigs)], e, snr)
                 for i, e in enumerate(effects) for j, snr in enumerate(snrs)]
    cases = []
    for n, (r, e, snr) in enumerate(pairs):
        for seed in range(seeds):
            k = n * 7 + int(snr) * 3 + seed
            rate, dur = SAMPLINGS[k % len(SAMPLINGS)]
            if dur > 1.0 and k % 3:                  # 2 s records on a third of their turns
                dur = 1.0
            cases.append((r, e, float(snr), 1000 * n + 10 * int(snr) + seed, FORMATS[k % len(FORMATS)], rate, dur))
    return cases


def case_id(c):
    return ":".join(str(x) for x in c)


def score(truth_effect, truth, out):
    """Verdict class of one diagnosis against the hidden truth."""
    named = list(out.get("effects", []))
    unexpl = bool(out.get("unexplained"))
    absorbed = truth_effect in LIBRARY and truth.get("absorbed", False)
    if truth_effect in NO_EFFECT:
        right = not named and not unexpl
    elif truth_effect in OUT_OF_LIBRARY:
        right = not named and unexpl
    elif absorbed:
        right = set(named) <= {truth_effect} and not unexpl
    else:
        right = named == [truth_effect]
    verdict = "+".join(named) if named else "nothing"
    return dict(named=named, unexplained=unexpl, right=right, absorbed=absorbed,
                verdict=verdict + (" +U" if unexpl else ""),
                false_name=any(n != truth_effect for n in named))


def run_case(c, workdir, pumpsim, timeout):
    rig, effect, snr, seed, fmt, rate, dur = c
    rec = make_record(rig, effect, snr, seed, rate, dur)
    n = len(rec.t)
    if effect in LIBRARY:   # the part no mu/theta0 change can mimic, against the noise over the record
        rec.truth["absorbed"] = rec.truth["observable"] * snr * n ** 0.5 < 5.0
    cfg = Path(workdir) / f"{rig}.toml"
    cfg.write_text(to_toml(RIGS[rig]))
    data = write(rec, fmt, Path(workdir) / "data")
    js = Path(workdir) / "diag.json"
    t0 = time.perf_counter()
    p = subprocess.run([pumpsim, "diagnose", str(cfg), data, "--json", str(js)], capture_output=True,
                       text=True, timeout=timeout)
    wall = time.perf_counter() - t0
    res = dict(case=case_id(c), rig=rig, effect=effect, snr=snr, seed=seed, format=fmt, rate=rate,
               duration=dur, samples=n, wall=wall, exit=p.returncode, truth=rec.truth)
    if p.returncode != 0 or not js.exists():
        res.update(right=False, verdict=f"exit {p.returncode}", named=[], unexplained=None,
                   false_name=False, absorbed=False, stderr=p.stderr.strip()[-400:])
        return res
    out = json.loads(js.read_text())
    res.update(score(effect, rec.truth, out))
    mu = out.get("final", {}).get("params", {}).get("mu")
    mu = mu.get("value") if isinstance(mu, dict) else mu
    res["mu"] = mu
    res["mu_err"] = abs(mu - rec.truth["mu"]) / rec.truth["mu"] if isinstance(mu, (int, float)) else None
    res["final"] = {k: out.get("final", {}).get(k) for k in ("rms", "residual_white")}
    res["noise_rms"] = rec.noise_rms
    res["steps"] = [[st.get("effect"), st.get("params", {}).get("order"), st.get("p_value")] for st in out.get("steps", [])]
    res["baseline_rms"] = out.get("baseline", {}).get("rms")
    res["notes"] = out.get("notes")
    return res


def summarise(results):
    def rate(sel, key):
        sel = list(sel)
        return (sum(bool(r[key]) for r in sel) / len(sel), len(sel)) if sel else (None, 0)
    lib = [r for r in results if r["effect"] in LIBRARY and not r["absorbed"]]
    none = [r for r in results if r["effect"] in NO_EFFECT]
    ool = [r for r in results if r["effect"] in OUT_OF_LIBRARY]
    mu_err = sorted(r["mu_err"] for r in results if r.get("mu_err") is not None
                    and r["effect"] not in ("vane_friction_spread", "viscous_tip_friction"))
    confusion = collections.defaultdict(collections.Counter)
    for r in results:
        confusion[r["effect"] + (" (absorbed)" if r["absorbed"] else "")][r["verdict"]] += 1
    return {
        "cases": len(results),
        "right": rate(results, "right"),
        "named_right_library": rate(lib, "right"),
        "named_right_library_snr_ge5": rate([r for r in lib if r["snr"] >= 5], "right"),
        "right_no_effect": rate(none, "right"),
        "false_name_no_effect": rate(none, "false_name"),
        "false_name_out_of_library": rate(ool, "false_name"),
        "right_out_of_library": rate(ool, "right"),
        "false_unexplained": rate(lib + none, "unexplained"),
        "mu_err_median": mu_err[len(mu_err) // 2] if mu_err else None,
        "mu_err_max": mu_err[-1] if mu_err else None,
        "wall_median": sorted(r["wall"] for r in results)[len(results) // 2] if results else None,
        "wall_max": max((r["wall"] for r in results), default=None),
        "errors": sum(r["exit"] != 0 for r in results),
        "confusion": {k: dict(v) for k, v in confusion.items()},
    }


def print_summary(s):
    print(f"\n{s['cases']} cases; {s['errors']} exited non-zero")
    for k in ("right", "named_right_library", "named_right_library_snr_ge5", "right_no_effect",
              "false_name_no_effect", "false_name_out_of_library", "right_out_of_library", "false_unexplained"):
        v, n = s[k]
        print(f"  {k:32s} {'-' if v is None else f'{100 * v:5.1f} %'}  (n={n})")
    print(f"  mu error median {s['mu_err_median']}, max {s['mu_err_max']}")
    print(f"  wall per case median {s['wall_median']:.1f} s, max {s['wall_max']:.1f} s")
    print("\nconfusion (true effect -> verdict: count)")
    for k, v in sorted(s["confusion"].items()):
        print(f"  {k:34s} " + ", ".join(f"{a}: {b}" for a, b in sorted(v.items(), key=lambda x: -x[1])))


def findings_markdown(results, summary, source):
    """The failing cases, each with the command that regenerates it and what diagnose said."""
    out = [f"# diagnose on independent records: failing cases ({source})", "",
           f"{summary['cases']} cases, {sum(r['right'] for r in results)} right. Regenerate one case (config, data "
           "and diag.json kept in out/independent/<case>/):", "",
           "    .venv/bin/python bench/independent/run.py --case RIG:EFFECT:SNR:SEED:FORMAT:RATE:DURATION", "",
           "| case (rig:effect:SNR:seed:format:rate:duration) | truth | diagnose said | steps (effect, order, p) | "
           "final RMS / noise | wall s |", "|---|---|---|---|---|---|"]
    for r in results:
        if r["right"]:
            continue
        truth = dict(r.get("truth", {}).get("params", {}))
        if r.get("absorbed"):
            truth["absorbed"] = True
        fin = (r.get("final") or {}).get("rms")
        ratio = f"{fin / r['noise_rms']:.2f}" if fin and r.get("noise_rms") else "-"
        steps = "; ".join(f"{e} {o if o is not None else ''} p={p:.2g}" if isinstance(p, float) else str(e)
                          for e, o, p in r.get("steps", []))
        out.append(f"| `{r['case']}` | {json.dumps(truth, default=str)} | {r['verdict']}"
                   f"{' ' + r['stderr'][-160:] if r.get('stderr') else ''} | {steps} | {ratio} | {r['wall']:.0f} |")
    return "\n".join(out) + "\n"


def _write_json(path, obj):
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    with open(path + ".tmp", "w") as f:
        json.dump(obj, f, indent=1, default=str)
    os.replace(path + ".tmp", path)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="20 hand-spread cases at SNR 5")
    ap.add_argument("--full", action="store_true", help="every rig x effect x SNR (default: balanced, 39 cases)")
    ap.add_argument("--rigs", default=",".join(RIGS))
    ap.add_argument("--effects", default=",".join(EFFECTS))
    ap.add_argument("--snrs", default="3,5,10")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--case", help="one case RIG:EFFECT:SNR:SEED:FORMAT:RATE:DURATION; files kept in out/independent/")
    ap.add_argument("--pumpsim", default=str(Path(sys.executable).with_name("pumpsim")))
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--skip", type=int, default=0, help="leave out the first SKIP cases of the grid (resume)")
    ap.add_argument("--jobs", type=int, default=1, help="cases run at once (default 1: one core)")
    ap.add_argument("--json", default="out/bench_independent.json")
    ap.add_argument("--findings", help="also write the failing cases as markdown to this file")
    a = ap.parse_args(argv)
    if a.case:
        r, e, snr, seed, fmt, rate, dur = a.case.split(":")
        cases = [(r, e, float(snr), int(seed), fmt, float(rate), float(dur))]
    else:
        cases = grid(a.rigs.split(","), a.effects.split(","), [float(x) for x in a.snrs.split(",")], a.seeds, a.quick, a.full)
    cases = cases[a.skip:]
    results, t_all = [], time.perf_counter()

    def one(c):
        keep = Path("out/independent") / case_id(c).replace(":", "_") if a.case else None
        if keep:
            keep.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory() as tmp:
            try:
                return run_case(c, keep or tmp, a.pumpsim, a.timeout)
            except ValueError as err:        # a drawn effect the rig's geometry cannot take
                return dict(case=case_id(c), rig=c[0], effect=c[1], snr=c[2], format=c[4], wall=0.0, exit=-2,
                            right=False, verdict=f"generator: {err}", named=[], unexplained=None,
                            false_name=False, absorbed=False)
            except subprocess.TimeoutExpired:
                return dict(case=case_id(c), rig=c[0], effect=c[1], snr=c[2], format=c[4], wall=a.timeout, exit=-1,
                            right=False, verdict="timeout", named=[], unexplained=None, false_name=False,
                            absorbed=False)

    with ThreadPoolExecutor(max_workers=a.jobs) as pool:   # each case is its own pumpsim process
        for r in pool.map(one, cases):
            results.append(r)
            print(f"{'ok ' if r['right'] else 'BAD'} {r['case']:62s} {r['verdict']:44s} {r['wall']:6.1f} s",
                  flush=True)
            s = summarise(results)
            s["wall_total"] = time.perf_counter() - t_all
            if a.json and not a.case:          # rewritten after every case: a partial run is readable
                _write_json(a.json, {"summary": s, "cases": results})
    print_summary(s)
    if a.findings:
        with open(a.findings + ".tmp", "w") as f:
            f.write(findings_markdown(results, s, " ".join(sys.argv[1:])))
        os.replace(a.findings + ".tmp", a.findings)
    return s


if __name__ == "__main__":
    main()
