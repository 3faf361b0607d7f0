"""Diagnose cost against the record length, stated as fixed + per-sample terms: a no-effect record
and a k = 4 out-of-round record (the `make bench` diagnose case) on the 4-vane ellipse at 20 kHz,
5 % noise, each at several lengths, in one process, kernels built and loaded before any clock.

    .venv/bin/python bench/diagnose_scale.py [--samples 1000 5000 20000 80000] [--case none oval4]
        [--kernel simd scalar] [--profile out/diagnose.prof] [--counts] [--json out/bench_diagnose_scale.json]

Prints, per case, length and kernel: wall time, the process's CPU time (all threads; on a shared
machine the less load-dependent number), the effects named and the verdict; then per case and
kernel the least-squares terms CPU = fixed + per window sample x min(samples, window) + per sample
x samples (`scaling_terms`). `--counts`: per diagnosis, the SIMD library's calls (model runs and
Jacobians: calls, samples, CPU seconds inside them), the CasADi map's, and the Gauss-Newton fits
(fits, accepted steps, trial runs that a halving rejected); the SIMD calls by workflow stage and by
purpose (bench/diagnose_stages.py). `--rate 10000 --samples 5001`: the `make bench` diagnose
row's record. The search runs on a screening window (the first
DiagnosisOptions.screen_samples = 5,000 samples), the whole-record refits, detectors and tests on
every sample. `--kernel scalar` sets PUMPSIM_FIT_KERNEL=scalar
(model torques on the CasADi map, as before the SIMD path); with both kernels each record runs back
to back under the same load. Not a test: the machine is shared; compare within one run and quote
the load with the numbers."""
from __future__ import annotations

import argparse
import cProfile
import dataclasses
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pumpsim.config import load_config  # noqa: E402
from pumpsim.data import Dataset  # noqa: E402
from pumpsim.diagnosis import diagnose  # noqa: E402
from pumpsim.diagnosis.effects import with_harmonic_pair  # noqa: E402
from pumpsim.diagnosis.options import OPTIONS  # noqa: E402
from pumpsim.distributions import chi2_sf  # noqa: E402
from pumpsim.kernels import fast_kernel, load_kernels  # noqa: E402
from pumpsim.simulate import simulate  # noqa: E402

from diagnose_stages import Stages, print_stages  # noqa: E402

RATE = 20000.0
CASES = {"none": [], "oval4": [[4, 2e-5, 0.3]]}


def warm_kernels(base) -> tuple[list, float, bool]:
    """Build or load the kernels a diagnosis of `base` uses -- its variant and the one with a
    harmonic pair (the out-of-round candidates, and the model that names one) -- before any clock:
    (their structures, the seconds it took, whether the SIMD library has Jacobian entries). The
    test statistics' special functions are imported here too: pumpsim imports scipy.special on
    first use (a command's start; the `startup` bench row), and an import is no diagnosis work."""
    t0 = time.perf_counter()
    chi2_sf(1.0, 1)
    variants = [cfg.parameters("constrained").structure for cfg in (base, with_harmonic_pair(base, 4))]
    jac = True
    for structure in variants:
        load_kernels(structure)
        simd = fast_kernel(structure)
        jac = jac and simd is not None and simd.has_jacobian
    return variants, time.perf_counter() - t0, jac


def record(case: str, samples: int, seed: int = 0):
    """The base config and a simulated record with the case's hidden harmonics and 5 % noise."""
    base = load_config(ROOT / "examples" / "ellipse_4vanes.toml")
    truth = dataclasses.replace(base, angle=0.4)
    if CASES[case]:
        truth = truth.with_harmonics(CASES[case])
    sim = simulate(truth, duration=(samples - 0.5) / RATE, rate=RATE)
    y = sim.torque + np.random.default_rng(seed).normal(0, 0.05 * np.std(sim.torque), sim.time.size)
    return base, Dataset(sim.time, y)


class Counts:
    """The kernel calls and Gauss-Newton work of what runs inside the `with` (see --counts), by
    wrapping the SIMD library's call, the CasADi map's evaluation and the optimiser's trials."""

    def __enter__(self):
        from pumpsim.identification import optimiser, problem
        from pumpsim.kernels import simd
        self.kernel = {k: [0, 0, 0.0] for k in ("model", "jacobian", "casadi map")}
        self.fits = [0, 0, 0]  # fits, accepted steps, rejected trials
        self._patched = [(simd.FastInverseDynamics, "_run"), (optimiser, "gauss_newton"), (problem, "sample_torque")]
        self._orig = [getattr(o, n) for o, n in self._patched]
        run, gn, maps, k, fits = *self._orig, self.kernel, self.fits

        def counted_map(kern, directions, samples):
            f = maps(kern, directions, samples)

            def call(*args):
                c0 = time.process_time()
                try:
                    return f(*args)
                finally:
                    e = k["casadi map"]
                    e[0], e[1], e[2] = e[0] + 1, e[1] + samples, e[2] + time.process_time() - c0
            return call

        def counted_run(lib, fns, n, *a, **kw):
            c0 = time.process_time()
            try:
                return run(lib, fns, n, *a, **kw)
            finally:
                e = k["jacobian" if len(a) > 7 or kw.get("extra") else "model"]
                e[0], e[1], e[2] = e[0] + 1, e[1] + n, e[2] + time.process_time() - c0

        def counted_gn(prob, x0, *a, **kw):
            model, calls = prob.model, [0]

            def trial(x):
                calls[0] += 1
                return model(x)
            prob.model = trial
            try:
                out = gn(prob, x0, *a, **kw)
            finally:
                del prob.model
            steps = len(out.history) - 1  # each accepted step's trial; without a final Jacobian, one call more
            rejected = calls[0] - steps - (out.jacobian is None)  # at the end (its remembered model)
            fits[0], fits[1], fits[2] = fits[0] + 1, fits[1] + steps, fits[2] + rejected
            return out
        simd.FastInverseDynamics._run, optimiser.gauss_newton, problem.sample_torque = counted_run, counted_gn, counted_map
        return self

    def __exit__(self, *exc):
        for (o, n), f in zip(self._patched, self._orig):
            setattr(o, n, f)

    def to_json(self) -> dict:
        return {"kernel": {k: {"calls": c, "samples": n, "cpu_seconds": t} for k, (c, n, t) in self.kernel.items()},
                "gauss_newton": {"fits": self.fits[0], "accepted_steps": self.fits[1], "rejected_trials": self.fits[2]}}


def run_one(case: str, samples: int, kernel: str = "simd", profile=None, counts=False) -> dict:
    base, data = record(case, samples)
    os.environ["PUMPSIM_FIT_KERNEL"] = kernel
    t0, c0 = time.perf_counter(), time.process_time()
    counted = None
    if profile:
        pr = cProfile.Profile(time.process_time)  # CPU, not wall: on a shared machine waits are not costs
        out = pr.runcall(diagnose, base, data)
        pr.dump_stats(profile)
    elif counts:
        with Counts() as counted, Stages() as staged:
            out = diagnose(base, data)
    else:
        out = diagnose(base, data)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    js = out.to_json() if hasattr(out, "to_json") else dict(out)
    return {"case": case, "samples": int(data.n), "kernel": kernel, "seconds": wall, "cpu_seconds": cpu,
            "load": os.getloadavg()[0], "effects": list(js["effects"]),
            "verdict": js["verdict"], "unexplained": js.get("unexplained"), "final_rms": js["final"]["rms"],
            **({"counts": counted.to_json(), "stages": staged.to_json()} if counted else {})}


def columns_ratio(base, data, repeats: int = 3) -> dict:
    """CPU seconds of `repeats` diagnoses of `data` each with the geometric Jacobian columns from
    exact derivatives (today's path) and from the sub-sample runs on every sample
    (PUMPSIM_INTERVAL_COLUMNS=runs, the path before), interleaved under the same load: the
    medians, their ratio and whether both named the same effects."""
    cpu = {"exact": [], "runs": []}
    effects = {}
    for _ in range(repeats):
        for path in ("exact", "runs"):
            if path == "runs":
                os.environ["PUMPSIM_INTERVAL_COLUMNS"] = "runs"
            c0 = time.process_time()
            try:
                out = diagnose(base, data)
            finally:
                os.environ.pop("PUMPSIM_INTERVAL_COLUMNS", None)
            cpu[path].append(time.process_time() - c0)
            effects[path] = list(out["effects"])
    med = {k: float(np.median(v)) for k, v in cpu.items()}
    return {"cpu_seconds": med["exact"], "cpu_seconds_runs": med["runs"], "ratio": med["runs"] / med["exact"],
            "cpu_all": cpu, "same_effects": effects["exact"] == effects["runs"]}


def scaling_terms(rows, window: int = OPTIONS.screen_samples) -> list[dict]:
    """Per (case, kernel): CPU seconds = fixed + per_window_sample x min(samples, window) +
    per_sample x samples by least squares (the search runs on the first `window` samples, the
    whole-record refits and tests on all); with fewer than three lengths or none beyond the
    window, a line (per_window_sample 0). The fixed term's share at each length."""
    out = []
    for key in sorted({(r["case"], r["kernel"]) for r in rows}):
        rs = [r for r in rows if (r["case"], r["kernel"]) == key]
        n = np.array([r["samples"] for r in rs], dtype=float)
        if np.unique(n).size < 2:
            continue
        cpu = np.array([r["cpu_seconds"] for r in rs])
        A = np.column_stack([np.ones_like(n), np.minimum(n, window), n])
        if np.linalg.matrix_rank(A) < 3:
            A = A[:, [0, 2]]
        coef = np.linalg.lstsq(A, cpu, rcond=None)[0]
        fixed, per = coef[0], coef[-1]
        per_window = coef[1] if coef.size == 3 else 0.0
        fit = A @ coef
        out.append({"case": key[0], "kernel": key[1], "window": window, "fixed_cpu_seconds": float(fixed),
                    "per_window_sample_cpu_us": float(per_window * 1e6), "per_sample_cpu_us": float(per * 1e6),
                    "worst_residual_cpu_seconds": float(np.max(np.abs(cpu - fit))),
                    "fixed_share": {int(k): float(fixed / f) for k, f in zip(n, fit)}})
    return out


def print_terms(terms):
    for t in terms:
        shares = ", ".join(f"{k}: {v:.0%}" for k, v in t["fixed_share"].items())
        print(f"{t['case']:6s} {t['kernel']:6s} CPU = {t['fixed_cpu_seconds']:.1f} s + "
              f"{t['per_window_sample_cpu_us']:.0f} us x min(samples, {t['window']}) + "
              f"{t['per_sample_cpu_us']:.0f} us x samples (worst residual {t['worst_residual_cpu_seconds']:.1f} s; "
              f"fixed share by length {shares})")


def scale(samples, cases=("oval4",), kernels=("simd",), profile=None, log=print, counts=False) -> dict:
    """The rows and the fitted terms (see the module docstring), warmed up first."""
    load = os.getloadavg()
    log(f"load average at start: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    _, seconds, _ = warm_kernels(load_config(ROOT / "examples" / "ellipse_4vanes.toml"))
    log(f"kernels built or loaded before the clock: {seconds:.1f} s")
    diagnose(*record("none", 2000))  # one-time costs of a first diagnosis outside the timings
    rows = []
    for case in cases:
        for n in samples:
            for kernel in kernels:
                r = run_one(case, n, kernel, profile, counts)
                rows.append(r)
                log(f"{case:6s} {r['samples']:6d} samples  {kernel:6s} {r['seconds']:6.1f} s wall  "
                    f"{r['cpu_seconds']:6.1f} s CPU  load {r['load']:.1f}  effects {r['effects']}  "
                    f"verdict {r['verdict']}")
                if counts:
                    log("  " + json.dumps(r["counts"]))
                    print_stages(r["stages"], log)
    os.environ.pop("PUMPSIM_FIT_KERNEL", None)
    end = os.getloadavg()
    log(f"load average at end: {' '.join(f'{v:.2f}' for v in end)}")
    return {"load_start": load, "load_end": end, "rows": rows, "terms": scaling_terms(rows)}


def main():
    global RATE
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, nargs="*", default=[1000, 5000, 20000, 80000])
    ap.add_argument("--case", nargs="*", choices=list(CASES), default=["oval4"])
    ap.add_argument("--kernel", nargs="*", choices=["simd", "scalar"], default=["simd"])
    ap.add_argument("--profile", help="cProfile output in process CPU time (one case and length only)")
    ap.add_argument("--counts", action="store_true", help="kernel calls and Gauss-Newton work per diagnosis")
    ap.add_argument("--rate", type=float, default=RATE, help="sampling rate, Hz (make bench's diagnose row: 10000)")
    ap.add_argument("--json")
    a = ap.parse_args()
    RATE = a.rate
    res = scale(a.samples, a.case, a.kernel, a.profile, log=lambda m: print(m, flush=True), counts=a.counts)
    print_terms(res["terms"])
    if a.json:
        Path(a.json).parent.mkdir(parents=True, exist_ok=True)
        Path(a.json).write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
