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


def sensitivity(study, method=None, samples=None, seed=None, resamples=None, **run_kw) -> dict:
    """Sobol' or Morris indices per output (and speed) and varied key. run_kw go to run_study
    (workers, scheduler, out, progress ...)."""
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
    return {"method": method, "samples": n, "designs": int(U.shape[0]), "seed": seed,
            "resamples": resamples, "keys": problem["names"],
            "speeds": [float(w) for w in speeds if w is not None], "indices": indices,
            "skipped": skipped, "status": {k: int(v) for k, v in df["status"].str.split(":").str[0].value_counts().items()},
            "run": stats.as_dict(), "_table": df}


def _f(x):
    x = float(x)
    return None if math.isnan(x) else x
