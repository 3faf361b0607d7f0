"""Where a diagnosis spends its SIMD kernel calls, by workflow stage and by what the call is for.

    with Stages() as st:
        diagnose(cfg, data)
    print_stages(st.to_json())

Each SIMD call (a torque run or a Jacobian) is counted against the innermost workflow stage active
when it ran (the baseline, the screen's score tests, a contender's refit and, inside a polar
search, its quick looks, scouts and rephasing, the acceptance, the conclusion's tests) and against
its purpose, read off the call stack: a Gauss-Newton trial, the interval ends of the angle slope,
the sub-sample runs of the interval columns, the pointwise Jacobian, a probe-grid point, other.
Used by `bench/diagnose_scale.py --counts`; not a test."""
from __future__ import annotations

import functools
import sys
import time
from collections import defaultdict

# (module, function) pairs whose calls are stages; the innermost active one is charged
STAGES = {
    "workflow": ("_start", "_baseline", "detected_ripple_orders", "score_test", "contender_fits", "accept",
                 "find_rival", "_add_effect", "drop_superseded", "kurtosis_off_reversals", "drift_findings",
                 "confounded_notes", "where_unexplained", "_conclude"),
    "refit": ("_refit_from", "_finalists", "_scouted", "rephased"),
    "selection": ("full_fit",),
}
# the first of these functions found on the call stack names the call's purpose
PURPOSES = (("_interval_averages", "interval sub-sample runs"), ("pointwise_columns", "pointwise Jacobian"),
            ("model_and_jacobian", "interval ends (angle slope)"), ("_probe_grid", "probe grid"),
            ("gauss_newton", "Gauss-Newton trial"))


def _purpose(frame) -> str:
    names = set()
    while frame is not None:
        names.add(frame.f_code.co_name)
        frame = frame.f_back
    return next((label for fn, label in PURPOSES if fn in names), "other")


class Stages:
    """Counts per stage and per purpose: calls, samples and CPU seconds inside the SIMD library,
    for model runs and Jacobians apart; and each stage's CPU seconds including what it calls."""

    def __enter__(self):
        from pumpsim.diagnosis import refit, selection, workflow
        from pumpsim.kernels import simd
        mods = {"workflow": workflow, "refit": refit, "selection": selection}
        self.stack, self._patched = ["(outside the stages)"], []
        self.kernel = defaultdict(lambda: [0, 0, 0, 0, 0.0])  # runs, run samples, jacobians, jac samples, CPU
        self.purpose = defaultdict(lambda: [0, 0, 0.0])  # calls, samples, CPU
        self.inclusive = defaultdict(float)
        for mod_name, names in STAGES.items():
            for name in names:
                self._patch(mods[mod_name], name, self._staged(getattr(mods[mod_name], name), f"{mod_name}.{name}"))
        self._patch(simd.FastInverseDynamics, "_run", self._counted(simd.FastInverseDynamics._run))
        return self

    def _patch(self, owner, name, new):
        self._patched.append((owner, name, getattr(owner, name)))
        setattr(owner, name, new)

    def _staged(self, f, label):
        @functools.wraps(f)
        def staged(*a, **kw):  # the conclusion's score tests apart from the search's
            self.stack.append(f"{label} (conclusion)" if "workflow._conclude" in self.stack else label)
            c0 = time.process_time()
            try:
                return f(*a, **kw)
            finally:
                here = self.stack.pop()
                if here not in self.stack:  # recursion: counted once
                    self.inclusive[here] += time.process_time() - c0
        return staged

    def _counted(self, run):
        def counted(lib, fns, n, *a, **kw):
            c0 = time.process_time()
            try:
                return run(lib, fns, n, *a, **kw)
            finally:
                cpu = time.process_time() - c0
                jac = len(a) > 7 or bool(kw.get("extra"))
                e = self.kernel[self.stack[-1]]
                e[2 * jac] += 1
                e[2 * jac + 1] += n
                e[4] += cpu
                p = self.purpose[_purpose(sys._getframe(1))]
                p[0], p[1], p[2] = p[0] + 1, p[1] + n, p[2] + cpu
        return counted

    def __exit__(self, *exc):
        for owner, name, old in reversed(self._patched):
            setattr(owner, name, old)

    def to_json(self) -> dict:
        return {"stages": {k: {"runs": v[0], "run_samples": v[1], "jacobians": v[2], "jacobian_samples": v[3],
                               "kernel_cpu_seconds": v[4], "cpu_seconds": self.inclusive.get(k)}
                           for k, v in self.kernel.items()} | {k: {"cpu_seconds": c} for k, c in self.inclusive.items()
                                                                if k not in self.kernel},
                "purposes": {k: {"calls": v[0], "samples": v[1], "cpu_seconds": v[2]} for k, v in self.purpose.items()}}


def print_stages(js: dict, log=print):
    log(f"  {'stage (innermost)':<44}{'runs':>6}{'Msamples':>9}{'Jacs':>6}{'Msamples':>9}{'kernel s':>9}{'stage s':>9}")
    rows = sorted(js["stages"].items(), key=lambda kv: -kv[1].get("kernel_cpu_seconds", 0.0))
    for k, v in rows:
        incl = v.get("cpu_seconds")
        log(f"  {k:<44}{v.get('runs', 0):>6}{v.get('run_samples', 0) / 1e6:>9.2f}{v.get('jacobians', 0):>6}"
            f"{v.get('jacobian_samples', 0) / 1e6:>9.2f}{v.get('kernel_cpu_seconds', 0.0):>9.2f}"
            f"{'' if incl is None else f'{incl:9.2f}'}")
    log(f"  {'purpose':<44}{'calls':>6}{'Msamples':>9}{'kernel s':>9}")
    for k, v in sorted(js["purposes"].items(), key=lambda kv: -kv[1]["cpu_seconds"]):
        log(f"  {k:<44}{v['calls']:>6}{v['samples'] / 1e6:>9.2f}{v['cpu_seconds']:>9.2f}")
