"""`pumpsim sweep | sensitivity | optimize STUDY`: the design studies of a study file."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from .. import interrupt
from ..errors import ConfigError
from .common import LOG, at_least, live, outputs, positive_int, staged, warn


def _idle_text(stats) -> str:
    W = max(stats.workers * stats.wall, 1e-300)
    return (f"before their first task {100 * stats.idle_start / W:.1f} % (start-up), between tasks "
            f"{100 * stats.idle_between / W:.1f} %, after their last {100 * stats.idle_end / W:.1f} %")


def _load(path):
    """The study, read and checked: each command's first work, before it imports what runs it."""
    from ..design.study import load_study

    study = load_study(path)
    LOG.debug("study %s: %d keys varied, %s", path, len(study.variables), study.sampler)
    warn(study.warnings)
    return study


def _inputs(a, study) -> list:
    """The files a study run reads: the study file and the base config it names."""
    return [a.study] + ([study.config_path] if study.config_path else [])


def _json_safe(obj):
    return {k: v for k, v in obj.items() if not k.startswith("_")}


def cmd_sweep(a) -> int:
    study = _load(a.study)
    if a.samples is not None:
        override_samples(study, a.samples)
    if a.summary:
        return _summary(a, study)
    from ..design.execute import check_out_dir, kept_note, read_manifest, run_study
    from ..design.summary import summary_text

    outs = outputs(a, _inputs(a, study), csv=None, report=None)
    check_out_dir(a.out, study.study_hash())
    df, stats = run_study(study, out=a.out, scheduler=a.scheduler, workers=a.workers,
                          batch_size=a.batch_size, progress=None if live() else False)
    try:  # a signal after the study: its designs are all in the folder, the other outputs not written
        man = read_manifest(a.out) if a.out else None
        print(summary_text(df, study.outputs, study.limits, man, sampler=study.sampler))
        size = f"of {stats.batch_size}" if not stats.guided else f"(guided: {stats.batch_size} designs first, shrinking)"
        print(f"{stats.designs} designs in {stats.batches} batches {size} on {stats.workers} "
              f"worker(s), {stats.wall:.2f} s evaluating ({stats.batches_skipped} batches resumed; "
              f"workers idle {100 * stats.overhead_share:.1f} % of the time: {_idle_text(stats)})")
        with staged(outs) as tmp:
            if a.csv:
                df.to_csv(tmp["--csv"], index=False, float_format="%.10g")
            if a.report:
                from ..report.design import sweep_report  # (matplotlib: only for a report)

                sweep_report(df, study, tmp["--report"])
    except interrupt.Interrupted as e:
        if a.out:
            e.notes.append(kept_note(len(df), a.out))
        raise
    return 0


def _summary(a, study) -> int:
    """--summary: the table so far; exit 1 when a design appears more than once (a mixed folder)."""
    from ..locks import holder_of
    from ..design.execute import check_out_dir, read_manifest, read_results
    from ..design.summary import coverage, summary_text

    if not a.out:
        raise ConfigError("--summary reads the results folder given by --out DIR")
    if not Path(a.out).is_dir():
        raise ConfigError(f"--out '{a.out}' is not a results folder (it does not exist)")
    man = read_manifest(a.out)
    if a.samples is None and study.sampler != "grid" and man.get("samples") not in (None, study.samples):
        override_samples(study, int(man["samples"]))  # the run's own --samples, as the folder records it
    check_out_dir(a.out, study.study_hash())
    df = read_results(a.out)
    running = holder_of(a.out)
    if running:
        print(f"a run is writing this folder ({running}); the summary is of the parts written so far")
    print(summary_text(df, study.outputs, study.limits, man, sampler=study.sampler))
    parts = len(list(Path(a.out).glob("part-*.parquet")))
    if parts < man.get("batches", 0) and not running:
        print(f"{parts} of {man['batches']} batches written: rerun without --summary to resume")
    if coverage(df, int(man.get("designs") or 0))["duplicated"]:
        print(f"pumpsim: error: '{a.out}' holds designs more than once (parts of different runs); "
              "remove it and run the study again", file=sys.stderr)
        return 1
    return 0


def override_samples(study, n):
    """--samples N: a reduced (or larger) study; it is a different study (hash) from the file's."""
    if n < 1:
        raise ConfigError(f"--samples must be >= 1, got {n}")
    if study.sampler == "grid":
        raise ConfigError("--samples does not apply to a grid (its size is the product of the value lists)")
    study.samples = n
    study.raw = {**study.raw, "study": {**study.raw.get("study", {}), "samples": n}}


def cmd_sensitivity(a) -> int:
    study = _load(a.study)
    from ..design.indices import sensitivity
    from ..io import write_text

    outs = outputs(a, _inputs(a, study), json=None, report=None)
    res = sensitivity(study, method=a.method, samples=a.samples, scheduler=a.scheduler,
                      workers=a.workers, progress=None if live() else False)
    print(sensitivity_text(res))
    with staged(outs) as tmp:
        if a.json:
            write_text(tmp["--json"], json.dumps(_json_safe(res), indent=1))
        if a.report:
            from ..report.design import sensitivity_report  # (matplotlib: only for a report)

            sensitivity_report(res, study, tmp["--report"])
    return 0


def _unit(output: str) -> str:
    """The unit of an output, also of one named per speed ('ptp_torque@300')."""
    from ..design.outputs import UNITS

    return UNITS.get(output.split("@")[0], "")


def sensitivity_text(res) -> str:
    from ..presentation import resolved

    lines = [f"{res['method']} indices from {res['designs']} designs (seed {res['seed']})"]
    if res["method"] == "sobol":
        lines.append(f"{'output':26s} {'key':28s} {'S1':>8s} {'±95%':>7s} {'ST':>8s} {'±95%':>7s}")
        for o, per in res["indices"].items():
            for k, r in per.items():
                lines.append(f"{o:26s} {k:28s} {r['S1']:8.4f} {r['S1_conf']:7.4f} {r['ST']:8.4f} {r['ST_conf']:7.4f}")
    else:
        lines.append(f"{'output':26s} {'key':28s} {'mu*':>11s} {'±95%':>10s} {'sigma':>11s}")
        for o, per in res["indices"].items():
            for k, r in per.items():  # Morris effects are in the output's unit: round-off shown as 0
                mu, conf, sigma = (resolved(r[n], _unit(o)) for n in ("mu_star", "mu_star_conf", "sigma"))
                lines.append(f"{o:26s} {k:28s} {mu:11.4g} {conf:10.3g} {sigma:11.4g}")
    for s in res["skipped"]:
        lines.append(f"not computed: {s['output']} ({s['reason']})")
    found = res.get("_unresolved")
    if found:  # after the table, where the numbers it qualifies were just read
        lines.append(f"WARNING: {found['head']}:")
        lines += [f"  {', '.join(outs)}: {why}" for outs, why in found["groups"]]
        if found["advice"]:
            lines.append(f"  {found['advice']}")
    return "\n".join(lines)


def cmd_optimize(a) -> int:
    study = _load(a.study)
    from ..design.optimiser import optimize
    from ..io import write_text

    outs = outputs(a, _inputs(a, study), json=None, report=None)
    res = optimize(study, method=a.method, max_iter=a.max_iter)
    print(optimize_text(res))
    with staged(outs) as tmp:
        if a.json:
            write_text(tmp["--json"], json.dumps(res, indent=1))
        if a.report:
            from ..report.design import optimize_report  # (matplotlib: only for a report)

            optimize_report(res, study, tmp["--report"])
    return 0 if res["success"] else 1


def optimize_text(res) -> str:
    from ..presentation import fmt_limit, fmt_number, resolved

    def value(x, output):
        return fmt_number(resolved(x, _unit(output)))

    if res["method"] == "nsga2":
        lines = [f"NSGA-II Pareto front of {', '.join(res['objectives'])}: {len(res['front'])} designs, "
                 f"{res['evaluations']} evaluations, {res['seconds']:.1f} s"]
        for f in res["front"]:
            lines.append("  " + ", ".join(f"{k} = {v:.6g}" for k, v in f["design"].items()) + "  ->  "
                         + ", ".join(f"{k} = {value(v, k)}" for k, v in f["objectives"].items()))
        return "\n".join(lines)
    o = res["objective"]
    lines = [f"{res['method']}: {res['message']} after {len(res['iterations']) - 1} iterations, "
             f"{res['evaluations']} evaluations, {res['seconds']:.2f} s",
             f"minimize {o['minimize']}: {value(o['start'], o['minimize'])} (start) -> "
             f"{value(o['value'], o['minimize'])} {_unit(o['minimize'])}".rstrip()]
    for k, v in res["design"].items():
        lo, hi = res["bounds"][k]
        lines.append(f"  {k:28s} {res['start'][k]:.6g} -> {v:.6g}   bounds {fmt_limit(lo)} .. {fmt_limit(hi)}")
    for k, c in res["constraints"].items():
        lines.append(f"  constraint {k}: {value(c['value'], k)} (lower {fmt_limit(c['lower'])}, upper "
                     f"{fmt_limit(c['upper'])}) {'ok' if c['satisfied'] else 'VIOLATED'}")
    if not res["success"]:
        lines.append("the optimiser did not reach a feasible optimum")
    return "\n".join(lines)


def register(sub) -> None:
    """Register sweep, sensitivity and optimize on the pumpsim sub-command parser."""
    def cluster(p):
        g = p.add_argument_group("execution (dask.distributed)")
        g.add_argument("--scheduler", metavar="ADDRESS",
                       help="existing Dask scheduler, e.g. tcp://host:8786 (default: a local cluster)")
        g.add_argument("--workers", type=positive_int, help="local workers (default: one per core; a study too small to pay for a cluster's start runs in this process)")

    sw = sub.add_parser("sweep", help="evaluate a study's designs (grid, Monte Carlo)")
    sw.add_argument("study", help="study file (TOML)")
    sw.add_argument("--out", metavar="DIR", help="results folder: Parquet parts + manifest.json (resumes)")
    sw.add_argument("--csv", help="the result table as CSV")
    sw.add_argument("--report", help="self-contained HTML report")
    sw.add_argument("--summary", action="store_true", help="print the summary of --out DIR, run nothing")
    sw.add_argument("--samples", type=positive_int, help="sample count instead of study.samples (not for a grid)")
    sw.add_argument("--batch-size", type=positive_int, dest="batch_size",
                    help="designs per task (default: >= 0.5 s of work from a pilot run)")
    cluster(sw)
    sw.set_defaults(func=cmd_sweep)
    def analysis(name, help):
        """A command on a study with --json and --report outputs."""
        p = sub.add_parser(name, help=help)
        p.add_argument("study")
        p.add_argument("--json")
        p.add_argument("--report", help="self-contained HTML report")
        return p

    se = analysis("sensitivity", "Sobol' indices or Morris screening of a study (SALib)")
    se.add_argument("--method", choices=["sobol", "morris"])
    se.add_argument("--samples", type=at_least(2), help="base sample count N (Sobol: N (D + 2) designs)")
    cluster(se)
    se.set_defaults(func=cmd_sensitivity)
    op = analysis("optimize", "minimise an output subject to constraints")
    op.add_argument("--method", choices=["slsqp", "trust-constr", "nsga2"])
    op.add_argument("--max-iter", type=positive_int, dest="max_iter")
    op.set_defaults(func=cmd_optimize)

