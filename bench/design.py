"""Design-study benchmarks (issue 14), run by `make bench` after bench/run.py (or `make bench-design`):
designs per second for one-revolution (360-sample) evaluations on one core, the speed-up with 2
Dask workers, the Dask overhead share, and a 10,000-design tolerance Monte Carlo of the test rig end
to end (sampling, evaluation, Parquet, report). Merges a "design" section into the JSON file."""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pumpsim.design import load_study  # noqa: E402
from pumpsim.cli.design import override_samples  # noqa: E402
from pumpsim.design.cluster import connect  # noqa: E402
from pumpsim.design.execute import run_study  # noqa: E402
from pumpsim.report.design import sweep_report  # noqa: E402

STUDY = ROOT / "examples" / "studies" / "test_rig_tolerances.toml"


def rig(samples):
    s = load_study(STUDY)
    override_samples(s, samples)
    return s


def kernel_alone(s, repeats=3):
    """The SIMD kernel's own time for the study's designs (their parameter vectors, in the
    study's batches: evaluate.batch_designs): what a design costs without any Python around it --
    every vane through the N-vane library (what a study evaluated before alike vanes went through
    one), one vane through the 1-vane library (design.alike) with every output stored, and
    "fused": the call the study makes, one vane with the reductions in C (codegen/simd_reduce.py).
    Best of `repeats`, {name: (wall, CPU seconds)}."""
    from pumpsim.design.evaluate import KERNEL_OUTPUTS, batch_designs, evaluate_designs, one_vane, revolution
    from pumpsim.design.execute import study_designs
    from pumpsim.design.vector import design_maps
    from pumpsim.kernels import load_kernels

    X = study_designs(s)
    dm = design_maps(s, X)[0][0][0]
    P, speed, _ = dm.vectors(X)
    kern, theta = load_kernels(dm.structure), revolution(dm.cfg.angle, s.revolution_samples)
    one = one_vane(dm.structure)
    N = dm.structure.vanes
    zeros = np.zeros((len(P), 4))
    runs = {"every_vane": (lambda p, w: evaluate_designs(kern, p, theta, w), batch_designs(N, False)),
            "one_vane": (lambda p, w: one.evaluate(p, theta, w, KERNEL_OUTPUTS), batch_designs(N, True))}
    if one.fast.has_reductions:  # the call the study makes: the kernel and the reductions in C
        runs["fused"] = (lambda p, w: one.fast.reduce_designs(theta, w, p[:, one.columns], zeros[:len(p)],
                                                              (1e-10, 1e-6), N),
                         batch_designs(N, True))
    best = {name: (float("inf"), float("inf")) for name in runs}
    for _ in range(repeats):
        for name, (run, size) in runs.items():
            t0, c0 = time.perf_counter(), time.thread_time()
            for lo in range(0, len(P), size):
                run(P[lo:lo + size], speed[lo:lo + size])
            best[name] = min(best[name], (time.perf_counter() - t0, time.thread_time() - c0))
    return best


def one_core(n=2000, repeats=3):
    """In process: designs per second of wall time and per CPU second (the machine is shared:
    CPU time is what the study itself used), best of `repeats`, against the kernel alone."""
    s = rig(n)
    run_study(rig(16), workers=0, progress=False)  # warm: kernels, maps
    wall = cpu = float("inf")
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        run_study(s, workers=0, progress=False)
        wall, cpu = min(wall, time.perf_counter() - t0), min(cpu, time.process_time() - c0)
    k = kernel_alone(s)
    k_cpu, one_cpu = k["every_vane"][1], k["one_vane"][1]
    fused_cpu = k.get("fused", (math.nan, math.nan))[1]
    return {"designs": n, "wall_s": wall, "cpu_s": cpu, "designs_per_s": n / wall, "designs_per_cpu_s": n / cpu,
            "kernel_wall_s": k["every_vane"][0], "kernel_cpu_s": k_cpu, "kernel_designs_per_cpu_s": n / k_cpu,
            "one_vane_kernel_cpu_s": one_cpu, "one_vane_kernel_designs_per_cpu_s": n / one_cpu,
            "ratio_to_kernel": k_cpu / cpu, "outside_kernel_share_cpu": 1 - one_cpu / cpu,
            "fused_call_cpu_s": fused_cpu, "outside_fused_call_share_cpu": 1 - fused_cpu / cpu, "repeats": repeats}


def workers_scaling(n=24_000, repeats=3):
    """The same study on a LocalCluster of 1 and of 2 worker processes (clusters started before
    the clock: the evaluation phase is timed), alternating, best of `repeats` each: the machine is
    shared, and the best run is the one least disturbed. Each with the layout a user gets (equal
    batches on one worker, guided on two). The overhead share is also given over all runs.
    24,000 designs: a few seconds of work on one worker (alike vanes through one vane), which a
    smaller study would not give a cluster (execute.IN_PROCESS_SECONDS)."""
    s = rig(n)
    clusters = {w: connect(None, w, True) for w in (1, 2)}
    best, shares = {}, []
    try:
        for w, (client, _) in clusters.items():
            run_study(rig(64), client=client, workers=w, progress=False)  # warm the workers
        for _ in range(repeats):
            for w, (client, _) in clusters.items():
                _, st = run_study(s, client=client, workers=w, progress=False)
                if w == 2:
                    shares.append(st.overhead_share)
                if w not in best or st.wall < best[w].wall:
                    best[w] = st
    finally:
        for client, cluster in clusters.values():
            client.close()
            cluster.close()
    b = best[2]
    W = b.workers * b.wall
    return {"designs": n, "batch_size": b.batch_size, "wall_1_s": best[1].wall, "wall_2_s": b.wall,
            "speedup_2_workers": best[1].wall / b.wall,
            "overhead_share_1": best[1].overhead_share, "overhead_share_2": b.overhead_share,
            "overhead_share_2_all_runs": shares,
            "idle_2_start": b.idle_start / W, "idle_2_between": b.idle_between / W, "idle_2_end": b.idle_end / W,
            "cpu_share_in_tasks_2": b.compute_cpu / b.compute,
            "tasks": b.batches, "guided": b.guided, "repeats": repeats}


def end_to_end(n=10_000):
    """As a user runs it: sampling, the pilot, a LocalCluster (one worker per core) if the pilot
    says one would pay for its start (execute.worth_a_cluster) else this process, evaluation,
    Parquet parts, the HTML report. The kernels are built (the cache of a machine that ran a study
    before); nothing else is warm. client_cpu_s: this process's CPU time (all of it when in process)."""
    s = rig(n)
    with tempfile.TemporaryDirectory() as tmp:
        t0, c0 = time.perf_counter(), time.process_time()
        df, st = run_study(s, out=Path(tmp) / "mc", progress=False)
        t_eval = time.perf_counter() - t0
        c1 = time.process_time()
        sweep_report(df, s, Path(tmp) / "mc.html")
        total = time.perf_counter() - t0
        report_cpu = time.process_time() - c1
        ok = int((df["status"] == "ok").sum())
    return {"designs": n, "ok": ok, "total_s": total, "evaluation_and_parquet_s": t_eval,
            "report_s": total - t_eval, "report_cpu_s": report_cpu, "client_cpu_s": time.process_time() - c0,
            "workers": st.workers, "setup_s": st.setup,
            "overhead_share": st.overhead_share, "idle_start": st.idle_start / (st.workers * st.wall),
            "idle_between": st.between_tasks_share, "idle_end": st.idle_end / (st.workers * st.wall),
            "cpu_share_in_tasks": st.compute_cpu / st.compute, "tasks": st.batches}


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", default=str(ROOT / "out" / "bench.json"))
    a = ap.parse_args()
    res = {"cores": os.cpu_count(), "load_average_before": os.getloadavg()}
    print("design studies (test rig tolerance MC, 360 samples per revolution, Model 2)")
    r = one_core()
    res["one_core"] = r
    print(f"  one core, in process: {r['designs_per_s']:.0f} designs/s of wall time, {r['designs_per_cpu_s']:.0f} "
          f"per CPU second (target >= 5,000 per core; {r['designs']} designs, best of {r['repeats']}); the "
          f"SIMD kernel alone on the same designs, every vane: {r['kernel_designs_per_cpu_s']:.0f} per CPU "
          f"second ({r['ratio_to_kernel']:.2f}x); one vane standing for the alike four, every output stored: "
          f"{r['one_vane_kernel_designs_per_cpu_s']:.0f} per CPU second, so {100 * r['outside_kernel_share_cpu']:.0f} % "
          "of the study's CPU time is outside the kernel (housing, geometry, reductions, table, pilot); "
          f"{100 * r['outside_fused_call_share_cpu']:.0f} % outside the library call the study makes (the kernel "
          "with the reductions in C): the study's Python, per design and per study")
    r = workers_scaling()
    res["workers"] = r
    print(f"  LocalCluster 1 -> 2 workers: {r['wall_1_s']:.2f} s -> {r['wall_2_s']:.2f} s, speed-up "
          f"{r['speedup_2_workers']:.2f}x (target >= 1.7), Dask overhead share {100 * r['overhead_share_2']:.1f} % "
          f"(target <= 5 %; start {100 * r['idle_2_start']:.1f} + between tasks {100 * r['idle_2_between']:.1f} "
          f"+ end {100 * r['idle_2_end']:.1f}; all runs "
          f"{', '.join(f'{100 * x:.1f}' for x in r['overhead_share_2_all_runs'])} %), {r['tasks']} tasks "
          f"({'guided, first ' if r['guided'] else 'of '}{r['batch_size']} designs); the tasks had "
          f"{100 * r['cpu_share_in_tasks_2']:.0f} % of their wall time on a core (the rest: other processes)")
    r = end_to_end()
    res["end_to_end_10k"] = r
    print(f"  10,000-design MC end to end (sampling, pilot, evaluation, Parquet, report; a cluster if worth "
          f"its start): {r['total_s']:.1f} s, {r['client_cpu_s']:.1f} s CPU (target <= 5 s; setup {r['setup_s']:.1f} s, "
          f"report {r['report_s']:.1f} s ({r['report_cpu_s']:.1f} s CPU), {r['workers']} worker(s), "
          f"Dask overhead share {100 * r['overhead_share']:.1f} % = start {100 * r['idle_start']:.1f} + between "
          f"{100 * r['idle_between']:.1f} + end {100 * r['idle_end']:.1f}, {r['tasks']} tasks, "
          f"{100 * r['cpu_share_in_tasks']:.0f} % CPU in tasks)")
    path = Path(a.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = json.loads(path.read_text()) if path.exists() else {}
    res["load_average_after"] = os.getloadavg()
    print(f"  load average before/after: {res['load_average_before'][0]:.1f} / {res['load_average_after'][0]:.1f} "
          f"on {os.cpu_count()} cores (the machine is shared)")
    data["design"] = res
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    os.replace(tmp, path)
    print(f"wrote {path} (design)")


if __name__ == "__main__":
    main()
