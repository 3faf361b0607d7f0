"""Diagnose on independent measurements: a seeded grid of rigs x effects x SNR x seeds x formats.

Every record is made by bench/independent (own Model 2, own effect forms, own noise and file
formats); `pumpsim diagnose CONFIG DATA --json` runs on it as a black box with the nominal config
(effect hidden). Prints the confusion matrix and the rates; writes out/bench_independent.json.

  python bench/independent/run.py [--quick] [--rigs a,b] [--effects a,b] [--snrs 3,5,10] [--seeds 1]
  python bench/independent/run.py --artefacts   (sensor/logger/run-up artefacts and file forms, artefacts.py)
  python bench/independent/run.py --case RIG:EFFECT:SNR:SEED:FORMAT:RATE:DURATION   (one case, kept)
  python bench/independent/run.py --case ... --generate      (config and data only, into out/independent/)
  python bench/independent/run.py --summarise out/bench_independent.json   (rescore a finished run, README table)
Every case's diagnose JSON is kept in out/independent/diag/.
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

from bench.independent.artefacts import ARTEFACTS, MEASURED_SPEED  # noqa: E402
from bench.independent.formats import BAD_FORMATS, EXTRA_FORMATS, FORMATS, write  # noqa: E402
from bench.independent.records import COMBINED, EFFECTS, LIBRARY, NO_EFFECT, OUT_OF_LIBRARY, make_record  # noqa: E402
from bench.independent.rig import RIGS, to_toml  # noqa: E402

# library names that are also right for a true effect: at one speed a tip COF rising with slip speed
# (mu(v) + c v) is a tip COF above the configured slot/tip proportion, i.e. the slot COF is off
ALSO_RIGHT = {"viscous_tip_friction": ("slot_friction",)}
DIAG_DIR = Path("out/independent/diag")   # diagnose's JSON of every case run
# (rate Hz, duration s) cycled over the grid: 5-25 kHz, 0.4-2 s (2 s on a third of their turns)
SAMPLINGS = ((10000.0, 0.5), (20000.0, 0.5), (12500.0, 1.0), (16000.0, 0.5), (10000.0, 2.0), (5000.0, 1.0),
             (25000.0, 0.4), (20000.0, 2.0))
SPEED_FORMATS = ("csv_speed", "csv_speed_noisy", "csv_semicolon", "mat")   # formats with a speed column
QUICK = [("concentric4", "none"), ("concentric4", "rotor_eccentricity"), ("concentric4", "hum"),
         ("concentric4", "speed_ripple"), ("eccentric5", "housing_out_of_round"), ("eccentric5", "none"),
         ("ellipse1", "rotor_eccentricity"), ("ellipse3", "sensor_lag"), ("ellipse3", "drift"),
         ("ellipse4", "vane_friction_spread"), ("ellipse4", "none"), ("ellipse4", "impulse"),
         ("ellipse4", "torque_offset"), ("tilted3", "viscous_tip_friction"), ("tilted3", "speed_ripple"),
         ("tilted3", "ar1_noise"), ("ellipse4", "rotor_eccentricity"), ("eccentric5", "vane_friction_spread"),
         ("ellipse1", "housing_out_of_round"), ("concentric4", "torque_offset"),
         ("concentric4", "off_speed"), ("concentric4", "two_effects"), ("ellipse4", "speed_drift")]


def grid(rigs, effects, snrs, seeds, quick, full=False, seed_offset=0):
    if quick:
        pairs = [(r, e, 5.0) for r, e in QUICK]
    elif full:
        pairs = [(r, e, snr) for r in rigs for e in effects for snr in snrs]
    else:   # balanced: every effect at every SNR on three different rigs; over the effects every rig meets every SNR
        stride = max(1, len(rigs) // len(snrs))
        pairs = [(rigs[(i + j * stride) % len(rigs)], e, snr)
                 for i, e in enumerate(effects) for j, snr in enumerate(snrs)]
    cases = []
    for n, (r, e, snr) in enumerate(pairs):
        for seed in range(seeds):
            k = n * 7 + int(snr) * 3 + seed
            rate, dur = SAMPLINGS[k % len(SAMPLINGS)]
            if dur > 1.0 and k % 3:                  # 2 s records on a third of their turns
                dur = 1.0
            fmt = FORMATS[k % len(FORMATS)]
            if e == "speed_drift" and fmt not in SPEED_FORMATS:   # the drift is measured: the file shows it
                fmt = SPEED_FORMATS[k % len(SPEED_FORMATS)]
            cases.append((r, e, float(snr), 1000 * n + 10 * int(snr) + seed + seed_offset, fmt, rate, dur))
    return cases


def artefact_grid(rigs, snrs=(3.0, 5.0, 10.0)):
    """Every artefact kind at every SNR, each on another rig (balanced as grid()), then a no-effect
    record in each of the EXTRA_FORMATS (read right: nothing, consistent) and BAD_FORMATS (refused:
    exit 2)."""
    stride = max(1, len(rigs) // len(snrs))
    kinds = [(rigs[(i + j * stride) % len(rigs)], e, snr, None) for i, e in enumerate(ARTEFACTS)
             for j, snr in enumerate(snrs)]
    kinds += [(rigs[n % len(rigs)], "none", 5.0, f) for n, f in enumerate(EXTRA_FORMATS + BAD_FORMATS)]
    cases = []
    for n, (rig, e, snr, fmt) in enumerate(kinds):
        rate, dur = SAMPLINGS[n % len(SAMPLINGS)]
        if fmt is None:
            fmt = SPEED_FORMATS[n % len(SPEED_FORMATS)] if e in MEASURED_SPEED else FORMATS[n % len(FORMATS)]
        cases.append((rig, e, snr, 70000 + 10 * n, fmt, rate, min(dur, 1.0)))
    return cases


def case_id(c):
    return ":".join(str(x) for x in c)


def score(truth_effect, truth, out):
    """Verdict class of one diagnosis against the hidden truth. `required`: the record's library
    effects a fit of mu and theta0 cannot absorb; naming an absorbed one that is present is no error.
    right: exactly the required effects named (a single one reported only as `confounded`, nothing
    named, counts too, as in bench/diagnose_grid.py), or for no effect / absorbed ones nothing named and
    no `unexplained`, or for out-of-library nothing named and `unexplained`. clean: right and (for
    library effects) the required effects named, not only `confounded`, and no `unexplained`. A name in
    ALSO_RIGHT of a present effect counts as present (allowed, never required)."""
    named = list(out.get("effects", []))
    unexpl = bool(out.get("unexplained"))
    if "expected" in truth:
        return _score_expected(truth["expected"], named, unexpl)
    present = list(truth.get("effects", []))
    present += [a for e in present for a in ALSO_RIGHT.get(e, ())]
    required = [e for e in truth.get("effects", []) if e not in truth.get("absorbed_effects", [])]
    conf = {e for pair in out.get("confounded", []) for e in pair}
    if truth_effect in NO_EFFECT:
        right = not named and not unexpl
    elif truth_effect in OUT_OF_LIBRARY:
        right = not named and unexpl
    elif not required:
        right = set(named) <= set(present) and not unexpl
    else:
        right = (len(set(named)) == len(named) and set(required) <= set(named) <= set(present)) or (
            not named and len(required) == 1 and required[0] in conf)
    verdict = "+".join(named) if named else "nothing"
    return dict(named=named, unexplained=unexpl, right=right, absorbed=bool(present) and not required,
                clean=right and not (required and (unexpl or not set(required) <= set(named))),
                verdict=verdict + (" +U" if unexpl else ""),
                false_name=any(n not in present for n in named))


def _score_expected(expected, named, unexpl):
    """An artefact record against its stated right answer (bench/independent/artefacts.py EXPECTED)."""
    if isinstance(expected, list):
        right = sorted(named) == sorted(expected)
    else:
        right = not named and {"quiet": not unexpl, "unexplained": unexpl, "no_name": True}[expected]
    verdict = ("+".join(named) if named else "nothing") + (" +U" if unexpl else "")
    return dict(named=named, unexplained=unexpl, right=right, absorbed=False, verdict=verdict,
                clean=right and not unexpl,
                false_name=any(n not in (expected if isinstance(expected, list) else []) for n in named))


def _score_refusal(res, stderr, written):
    """A unit mistake in the file (BAD_FORMATS): right is exit 2 with a message and nothing written."""
    right = res["exit"] == 2 and "Traceback" not in stderr and bool(stderr.strip()) and not written
    res.update(right=right, clean=right, verdict=f"exit {res['exit']}: {stderr.strip()[-160:]}", named=[],
               unexplained=None, false_name=False, absorbed=False)
    return res


def rescored(r):
    """A stored case scored again by today's score() from its kept diagnose JSON (if any)."""
    kept = DIAG_DIR / (r["case"].replace(":", "_") + ".json")
    if r.get("exit") == 0 and kept.exists():
        r = {**r, **score(r["effect"], r["truth"], json.loads(kept.read_text()))}
    return r


def write_case(c, workdir):
    """The nominal config and the measured record of one case, as files in workdir."""
    rig, effect, snr, seed, fmt, rate, dur = c
    rec = make_record(rig, effect, snr, seed, rate, dur)
    cfg = Path(workdir) / f"{rig}.toml"
    cfg.write_text(to_toml(RIGS[rig]))
    return rec, cfg, write(rec, fmt, Path(workdir) / "data")


def run_case(c, workdir, pumpsim, timeout):
    rig, effect, snr, seed, fmt, rate, dur = c
    rec, cfg, data = write_case(c, workdir)
    n = len(rec.t)
    js = Path(workdir) / "diag.json"
    t0 = time.perf_counter()
    p = subprocess.run([pumpsim, "diagnose", str(cfg), data, "--json", str(js)], capture_output=True,
                       text=True, timeout=timeout)
    wall = time.perf_counter() - t0
    res = dict(case=case_id(c), rig=rig, effect=effect, snr=snr, seed=seed, format=fmt, rate=rate,
               duration=dur, samples=n, wall=wall, exit=p.returncode, truth=rec.truth)
    if fmt in BAD_FORMATS:
        return _score_refusal(res, p.stderr, js.exists())
    if p.returncode != 0 or not js.exists():
        res.update(right=False, clean=False, verdict=f"exit {p.returncode}", named=[], unexplained=None,
                   false_name=False, absorbed=False, stderr=p.stderr.strip()[-400:])
        return res
    out = json.loads(js.read_text())
    DIAG_DIR.mkdir(parents=True, exist_ok=True)        # every diagnosis kept: the steps, screens and notes
    (DIAG_DIR / (case_id(c).replace(":", "_") + ".json")).write_text(js.read_text())
    res.update(score(effect, rec.truth, out))
    mu = out.get("final", {}).get("params", {}).get("mu")
    mu = mu.get("value") if isinstance(mu, dict) else mu
    res["mu"] = mu
    res["mu_err"] = abs(mu - rec.truth["mu"]) / rec.truth["mu"] if isinstance(mu, (int, float)) else None
    res["final"] = {k: out.get("final", {}).get(k) for k in ("rms", "residual_white")}
    res["noise_rms"] = rec.noise_rms
    res["steps"] = [[st.get("effect"), st.get("params", {}).get("order"), st.get("p_value")] for st in out.get("steps", [])]
    res["step_params"] = [st.get("params") for st in out.get("steps", [])]
    res["baseline_rms"] = out.get("baseline", {}).get("rms")
    res["notes"] = out.get("notes")
    return res


def _rate(sel, key):
    sel = list(sel)
    return (sum(bool(r[key]) for r in sel) / len(sel), len(sel)) if sel else (None, 0)


def summarise(results):
    """Rates (value, count) as in bench/diagnose_grid.py: named right over observable library records
    (single effects and pairs), clean verdicts, false names over records with nothing to name (no
    effect, absorbed effects, out-of-library disturbances), false `unexplained` over no-effect,
    absorbed and named-right records; per rig; wall per case."""
    art = [r for r in results if r["effect"] in ARTEFACTS or r.get("format") in EXTRA_FORMATS + BAD_FORMATS]
    results = [r for r in results if r not in art]
    lib = [r for r in results if (r["effect"] in LIBRARY or r["effect"] in COMBINED) and not r["absorbed"]]
    single = [r for r in lib if r["effect"] in LIBRARY]
    none = [r for r in results if r["effect"] in NO_EFFECT]
    quiet = none + [r for r in results if r["absorbed"]]
    ool = [r for r in results if r["effect"] in OUT_OF_LIBRARY]
    judged = quiet + [r for r in lib if r["right"]]
    mu_err = sorted(r["mu_err"] for r in results if r.get("mu_err") is not None
                    and r["effect"] not in ("vane_friction_spread", "viscous_tip_friction", "two_effects"))
    confusion = collections.defaultdict(collections.Counter)
    for r in results:
        confusion[r["effect"] + (" (absorbed)" if r["absorbed"] else "")][r["verdict"]] += 1
    for r in art:
        confusion[r["effect"] + (f" ({r['format']})" if r["effect"] == "none" else "")][r["verdict"]] += 1
    walls = sorted(r["wall"] for r in results + art)
    return {
        "right_artefacts": _rate(art, "right"),
        "false_name_artefacts": _rate(art, "false_name"),
        "cases": len(results) + len(art),
        "right": _rate(results, "right"),
        "clean": _rate(results, "clean"),
        "named_right_library": _rate(single, "right"),
        "named_right_library_snr_ge5": _rate([r for r in single if r["snr"] >= 5], "right"),
        "clean_library": _rate(single, "clean"),
        "named_right_two_effects": _rate([r for r in lib if r["effect"] in COMBINED], "right"),
        "right_no_effect": _rate(none, "right"),
        "false_name_no_effect": _rate(quiet, "false_name"),
        "false_name_out_of_library": _rate(ool, "false_name"),
        "right_out_of_library": _rate(ool, "right"),
        "false_unexplained": _rate(judged, "unexplained"),
        "per_rig": {rig: {"right": _rate([r for r in results if r["rig"] == rig], "right"),
                          "clean": _rate([r for r in results if r["rig"] == rig], "clean")}
                    for rig in sorted({r["rig"] for r in results})},
        "mu_err_median": mu_err[len(mu_err) // 2] if mu_err else None,
        "mu_err_max": mu_err[-1] if mu_err else None,
        "wall_median": walls[len(walls) // 2] if walls else None,
        "wall_max": walls[-1] if walls else None,
        "errors": sum(r["exit"] != 0 for r in results),
        "confusion": {k: dict(v) for k, v in confusion.items()},
    }


RATE_KEYS = ("right", "clean", "named_right_library", "named_right_library_snr_ge5", "clean_library",
             "named_right_two_effects", "right_no_effect", "false_name_no_effect", "false_name_out_of_library",
             "right_out_of_library", "false_unexplained", "right_artefacts", "false_name_artefacts")


def _pct(v):
    return "-" if v[0] is None else f"{100 * v[0]:5.1f} % of {v[1]}"


def print_summary(s):
    print(f"\n{s['cases']} cases; {s['errors']} exited non-zero")
    for k in RATE_KEYS:
        print(f"  {k:32s} {_pct(s[k])}")
    for rig, v in s["per_rig"].items():
        print(f"  {rig:32s} right {_pct(v['right'])}, clean {_pct(v['clean'])}")
    print(f"  mu error median {s['mu_err_median']}, max {s['mu_err_max']}")
    if s["wall_median"] is not None:
        print(f"  wall per case median {s['wall_median']:.1f} s, max {s['wall_max']:.1f} s")
    print("\nconfusion (true effect -> verdict: count)")
    for k, v in sorted(s["confusion"].items()):
        print(f"  {k:34s} " + ", ".join(f"{a}: {b}" for a, b in sorted(v.items(), key=lambda x: -x[1])))


def rates_markdown(s):
    """The README's table of one run's rates (value and count per class; per rig)."""
    names = {"right": "right verdict, all records", "clean": "clean verdict, all records",
             "named_right_library": "library effect named right (exactly it)",
             "named_right_library_snr_ge5": "... at SNR >= 5", "clean_library": "... and no `unexplained`",
             "named_right_two_effects": "two effects: both named, nothing else",
             "right_no_effect": "no effect: nothing named, no `unexplained`",
             "false_name_no_effect": "false names (no effect + absorbed)",
             "false_name_out_of_library": "false names (out-of-library)",
             "right_out_of_library": "out-of-library: nothing named, `unexplained`",
             "false_unexplained": "false `unexplained` (no effect, absorbed, named right)",
             "right_artefacts": "sensor/logger/run artefacts and file forms: the stated right answer",
             "false_name_artefacts": "false names (artefacts and file forms)"}
    rows = ["| rate | value | of |", "|---|---|---|"]
    rows += [f"| {names[k]} | {'-' if s[k][0] is None else f'{100 * s[k][0]:.0f} %'} | {s[k][1]} |" for k in RATE_KEYS]
    rows += [f"| rig {rig}: right / clean | {v['right'][0] * 100:.0f} % / {v['clean'][0] * 100:.0f} % | {v['right'][1]} |"
             for rig, v in s["per_rig"].items() if v["right"][1]]
    if s["wall_median"] is not None:
        rows.append(f"| wall per case, median / max | {s['wall_median']:.0f} s / {s['wall_max']:.0f} s | {s['cases']} |")
    return "\n".join(rows) + "\n"


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
        if r.get("truth", {}).get("absorbed_effects"):
            truth["absorbed"] = r["truth"]["absorbed_effects"]
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
    ap.add_argument("--quick", action="store_true", help="23 hand-spread cases at SNR 5")
    ap.add_argument("--full", action="store_true", help="every rig x effect x SNR (default: balanced, 45 cases)")
    ap.add_argument("--artefacts", action="store_true",
                    help="the artefact kinds (sensor, logger, run-up) at SNR 3/5/10 and file forms, 38 cases")
    ap.add_argument("--rigs", default=",".join(RIGS))
    ap.add_argument("--effects", default=",".join(EFFECTS))
    ap.add_argument("--snrs", default="3,5,10")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--seed-offset", type=int, default=0,
                    help="added to every case's seed: a held-out grid (new effect sizes, phases, noise) of the same design")
    ap.add_argument("--case", help="one case RIG:EFFECT:SNR:SEED:FORMAT:RATE:DURATION; files kept in out/independent/")
    ap.add_argument("--pumpsim", default=str(Path(sys.executable).with_name("pumpsim")))
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--skip", type=int, default=0, help="leave out the first SKIP cases of the grid (resume)")
    ap.add_argument("--jobs", type=int, default=1, help="cases run at once (default 1: one core)")
    ap.add_argument("--json", default="out/bench_independent.json")
    ap.add_argument("--findings", help="also write the failing cases as markdown to this file")
    ap.add_argument("--generate", action="store_true", help="with --case: write config and data only, no diagnose")
    ap.add_argument("--summarise", metavar="JSON", help="print the summary and README table of a finished run's JSON")
    a = ap.parse_args(argv)
    if a.summarise:
        s = summarise([rescored(r) for r in json.loads(Path(a.summarise).read_text())["cases"]])
        print_summary(s)
        print("\n" + rates_markdown(s))
        return s
    if a.case:
        r, e, snr, seed, fmt, rate, dur = a.case.split(":")
        cases = [(r, e, float(snr), int(seed), fmt, float(rate), float(dur))]
        if a.generate:
            keep = Path("out/independent") / a.case.replace(":", "_")
            keep.mkdir(parents=True, exist_ok=True)
            rec, cfg, data = write_case(cases[0], keep)
            print(cfg, data, json.dumps(rec.truth, default=str), f"noise_rms {rec.noise_rms:.4g}")
            return None
    elif a.artefacts:
        cases = artefact_grid(a.rigs.split(","))
    else:
        cases = grid(a.rigs.split(","), a.effects.split(","), [float(x) for x in a.snrs.split(",")], a.seeds, a.quick, a.full,
                     a.seed_offset)
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
                            right=False, clean=False, verdict=f"generator: {err}", named=[], unexplained=None,
                            false_name=False, absorbed=False)
            except subprocess.TimeoutExpired:
                return dict(case=case_id(c), rig=c[0], effect=c[1], snr=c[2], format=c[4], wall=a.timeout, exit=-1,
                            right=False, clean=False, verdict="timeout", named=[], unexplained=None,
                            false_name=False, absorbed=False)

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
