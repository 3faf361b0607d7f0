"""Global sensitivity through the study machinery (SALib).

The SALib problem lives in the unit cube, one coordinate per varied key; each coordinate goes
through that key's inverse CDF (sampling.Variable.ppf), so the designs follow the study's
distributions and the indices are those of the study's joint input distribution (keys are
independent). Sobol' indices are invariant under these monotone per-key maps; Morris elementary
effects are per unit of the key's quantile (mu* ranks the keys; compare keys, not units).

- sobol: Saltelli/Sobol' sampling (N (D + 2) designs without second order), first-order S1 and
  total ST with bootstrap confidence intervals (95 %, `resamples`), SALib's estimators.
- morris: r trajectories on a p-level grid (N (D + 1) designs) at the quantiles (k + 1/2)/p;
  mu*, its bootstrap interval, sigma.
A design the model could not evaluate has no output: the indices of that output are not
computed (named in `skipped`), since neither estimator can drop a design of a matrix block.
Sobol' indices too noisy to read (`unresolved`, see `resolution`) say so, with the base sample
N that would resolve them (`samples_needed`): their error falls as 1/sqrt(N).
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from ..errors import ConfigError
from ..presentation import resolved
from .execute import run_study
from .outputs import UNITS
from .summary import is_constant

METHODS = ("sobol", "morris")


def _settings(study, method, samples, seed, resamples):
    cfg = study.sensitivity or {}
    bad = set(cfg) - {"method", "samples", "resamples", "levels", "seed"}
    if bad:
        raise ConfigError(f"unknown key 'sensitivity.{sorted(bad)[0]}' (method, samples, resamples, levels, seed)")
    method = method or cfg.get("method", "sobol")
    if method not in METHODS:
        raise ConfigError(f"sensitivity method must be one of {', '.join(METHODS)}, got {method!r}")
    samples = samples or cfg.get("samples") or study.samples
    if not isinstance(samples, int) or samples < 2:
        raise ConfigError(f"sensitivity.samples must be an integer >= 2, got {samples!r}")
    resamples = resamples or cfg.get("resamples", 1000)
    levels = cfg.get("levels", 4)
    seed = study.seed if seed is None else seed
    return method, samples, seed, int(resamples), int(levels)


def _sample(study, method, n, seed, levels):
    """(SALib problem over the keys with a spread, unit-cube points U, design matrix X)."""
    from SALib.sample import morris as morris_sample
    from SALib.sample import sobol as sobol_sample

    active = [v for v in study.variables if not v.spread_zero]
    if not active:
        raise ConfigError("no varied key has a spread: nothing to analyse")
    problem = {"num_vars": len(active), "names": [v.key for v in active],
               "bounds": [[0.0, 1.0]] * len(active)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # SALib warns when N is not a power of 2
        if method == "sobol":
            U = sobol_sample.sample(problem, n, calc_second_order=False, scramble=True, seed=seed)
        else:
            U = morris_sample.sample(problem, n, num_levels=levels, seed=seed)
    # Morris levels include the cube's faces, where a normal key's inverse CDF is infinite:
    # its p levels are placed at the quantiles (k + 1/2)/p instead (same grid, scaled by (p-1)/p)
    Q = (U * (levels - 1) + 0.5) / levels if method == "morris" else U
    X = np.empty((U.shape[0], len(study.variables)))
    j = 0
    for c, v in enumerate(study.variables):
        if v.spread_zero:
            X[:, c] = v.values[0]
        else:
            X[:, c] = v.ppf(Q[:, j])
            j += 1
    return problem, U, X


def _analyse(method, problem, U, Y, seed, resamples, levels) -> dict:
    """key -> indices of one output's values Y at the points U."""
    from SALib.analyze import morris as morris_analyze
    from SALib.analyze import sobol as sobol_analyze

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if method == "sobol":
            r = sobol_analyze.analyze(problem, Y, calc_second_order=False, num_resamples=resamples,
                                      conf_level=0.95, seed=seed)
            return {k: {"S1": _f(r["S1"][i]), "S1_conf": _f(r["S1_conf"][i]),
                        "ST": _f(r["ST"][i]), "ST_conf": _f(r["ST_conf"][i])}
                    for i, k in enumerate(problem["names"])}
        r = morris_analyze.analyze(problem, U, Y, conf_level=0.95, num_resamples=resamples,
                                   num_levels=levels, seed=seed)
        return {k: {"mu": _f(r["mu"][i]), "mu_star": _f(r["mu_star"][i]),
                    "mu_star_conf": _f(r["mu_star_conf"][i]), "sigma": _f(r["sigma"][i])}
                for i, k in enumerate(problem["names"])}


# A Sobol' index is a share of the output's variance. Known to +-0.1 (95 %) it tells a key that
# carries 20 % of the variance from one that carries none (their intervals just touch): the least a
# ranking of tolerances needs. Wider intervals mean the base sample N is too small.
SOBOL_HALF_WIDTH = 0.1


def resolution(per: dict, n: int) -> dict | None:
    """Why one output's Sobol' indices (key -> S1, S1_conf, ST, ST_conf) from base sample n cannot
    be read ({reason, max_conf: the widest half-width, samples_needed: the n that would resolve
    them, inconsistent: they break the rules below}); None when they can. Not resolved: an interval
    wider than +-SOBOL_HALF_WIDTH, or, beyond the intervals, what shares of independent keys must
    satisfy broken: an index outside [0, 1], S1 > ST, the S1 summing above 1 or the ST below 1
    (sums' intervals: the keys' half-widths in quadrature). Such a break means the bootstrap
    intervals themselves are too narrow, so then at least 4 n (half the error). Errors fall as
    1/sqrt(n): n (widest half-width / SOBOL_HALF_WIDTH)^2, up to a power of 2 (Sobol' sequence)."""
    rows = [(k, r) for k, r in per.items() if None not in (r["S1"], r["S1_conf"], r["ST"], r["ST_conf"])]
    if len(rows) < len(per):
        return {"reason": "some indices are not numbers (the estimator divided by a zero variance)",
                "max_conf": None, "samples_needed": None, "inconsistent": True}
    broken = []
    for k, r in rows:
        for name in ("S1", "ST"):
            v, c = r[name], r[f"{name}_conf"]
            if v - c > 1 or v + c < 0:
                broken.append(f"{name} of {k} = {v:.2f} ± {c:.2f}, outside [0, 1] where a share of the variance lies")
        if r["S1"] - r["ST"] > math.hypot(r["S1_conf"], r["ST_conf"]):
            broken.append(f"S1 of {k} ({r['S1']:.2f}) exceeds its ST ({r['ST']:.2f}): its share alone above its "
                          "share with its interactions")
    for name, what, sign, why in (("S1", "first-order", 1, "above 1: more than the whole variance"),
                                  ("ST", "total", -1, "below 1, though together the keys explain all the variance")):
        total = sum(r[name] for _, r in rows)
        c = math.sqrt(sum(r[f"{name}_conf"] ** 2 for _, r in rows))
        if sign * (total - 1) > c:  # S1 sum at most 1, ST at least 1 (independent keys)
            broken.append(f"the {what} indices sum to {total:.2f} ± {c:.2f}, {why}")
    widest = max((max(r["S1_conf"], r["ST_conf"]) for _, r in rows), default=0.0)
    if widest <= SOBOL_HALF_WIDTH and not broken:
        return None
    wide = ([f"intervals up to ±{widest:.2f} (wider than ±{SOBOL_HALF_WIDTH:g})"]
            if widest > SOBOL_HALF_WIDTH else [])
    need = max(n * (widest / SOBOL_HALF_WIDTH) ** 2, 4 * n if broken else n + 1)
    return {"reason": "; ".join(wide + broken), "max_conf": widest,
            "samples_needed": 2 ** math.ceil(math.log2(need)), "inconsistent": bool(broken)}


def unresolved_text(res) -> dict | None:
    """The warning about a result's unresolved Sobol' indices, for the terminal and the report
    (which may not import this module: sensitivity() keeps it as res["_unresolved"]): {head,
    groups: [(outputs, reason)] with the outputs of one reason together, advice, limit: the
    half-width asked for, inconsistent: some break the rules}; None when every output's are resolved."""
    if not res.get("unresolved"):
        return None
    groups: dict = {}
    for u in res["unresolved"]:
        groups.setdefault(u["reason"], []).append(u["output"])
    n, k = res["samples"], len(res["keys"])
    broken = sum(u["inconsistent"] for u in res["unresolved"])
    head = (f"the sample (base N = {n}, {res['designs']:,} designs) is too small for the Sobol' indices of "
            f"{len(res['unresolved'])} of {len(res['indices'])} outputs"
            + (f"; those of {broken} break what variance shares must satisfy, beyond their intervals: read them "
               "as noise" if broken else ""))
    need = res.get("samples_needed")
    found = {"head": head, "groups": [(tuple(o), r) for r, o in groups.items()], "advice": "",
             "limit": SOBOL_HALF_WIDTH, "inconsistent": bool(broken)}
    if need is None:
        return found
    widest = max((u["max_conf"] for u in res["unresolved"] if u["max_conf"] is not None), default=0.0)
    designs = need * (k + 2)
    took = _estimate(res.get("run") or {}, designs)
    advice = (f"Their error falls as 1/sqrt(N): --samples {need} ({designs:,} designs{took}) brings the widest "
              f"interval from ±{widest:.2f} to about ±{widest * math.sqrt(n / need):.2f}.")
    return {**found, "advice": advice}


def _estimate(run: dict, designs: int) -> str:
    """', about T at this run's pace': its wall time (start-up included) plus the evaluation of the
    further designs at its in-task time per design on its workers; '' without run statistics."""
    done, workers = run.get("designs", 0), max(run.get("workers", 1), 1)
    if not done or "wall" not in run or "compute" not in run:
        return ""
    seconds = run["wall"] + run["compute"] / done * max(designs - done, 0) / workers
    return f", {'under a second' if seconds < 1 else 'about ' + _duration(seconds)} at this run's pace"


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


def sensitivity(study, method=None, samples=None, seed=None, resamples=None, **run_kw) -> dict:
    """Sobol' or Morris indices per output (and speed) and varied key; for Sobol' also the outputs
    whose indices the sample cannot resolve (`unresolved`, `samples_needed`: resolution). run_kw go
    to run_study (workers, scheduler, out, progress ...)."""
    method, n, seed, resamples, levels = _settings(study, method, samples, seed, resamples)
    problem, U, X = _sample(study, method, n, seed, levels)
    df, stats = run_study(study, X=X, **run_kw)
    # operating points are separate analyses; a varied operation.speed is an input like any other
    speeds = sorted(df["speed"].unique()) if study.speeds and len(study.speeds) > 1 else [None]
    indices, skipped = {}, []
    for o in study.outputs:
        if o not in df.columns or df[o].dtype == bool or str(df[o].dtype) == "bool":
            continue
        for w in speeds:
            sub = df if w is None else df[df["speed"] == w]
            Y = sub.sort_values("design")[o].to_numpy(dtype=float)
            name = o if len(speeds) == 1 else f"{o}@{w:g}"
            if Y.size != U.shape[0] or not np.all(np.isfinite(Y)):
                skipped.append({"output": name, "reason": f"{int(np.sum(~np.isfinite(Y)))} of "
                                f"{U.shape[0]} designs have no value"})
            elif is_constant(Y, o):
                median = resolved(float(np.median(Y)), UNITS.get(o, ""))  # round-off of 0 shown as 0
                skipped.append({"output": name, "reason": f"constant ({median:.6g}): no variance to share"})
            else:
                indices[name] = _analyse(method, problem, U, Y, seed, resamples, levels)
    unresolved = []
    for name, per in indices.items() if method == "sobol" else ():
        why = resolution(per, n)
        if why is not None:
            unresolved.append({"output": name, **why})
    needed = [u["samples_needed"] for u in unresolved if u["samples_needed"]]
    res = {"method": method, "samples": n, "designs": int(U.shape[0]), "seed": seed,
            "resamples": resamples, "keys": problem["names"],
            "speeds": [float(w) for w in speeds if w is not None], "indices": indices,
            "skipped": skipped, "unresolved": unresolved, "samples_needed": max(needed, default=None),
            "status": {k: int(v) for k, v in df["status"].str.split(":").str[0].value_counts().items()},
            "run": stats.as_dict(), "_table": df}
    res["_unresolved"] = unresolved_text(res)
    return res


def _f(x):
    x = float(x)
    return None if math.isnan(x) else x
