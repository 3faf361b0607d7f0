"""Varied keys, their distributions and the samplers (scipy.stats.qmc).

Every sampler draws points u in the unit cube; each key maps its coordinate through the inverse
CDF of its distribution (or picks from its value list), so Sobol and Latin-hypercube designs keep
their space-filling property in every marginal. `random` gives design d its own stream
SeedSequence(seed, spawn_key=(d,)): its values depend on the study seed and d only, never on the
batching or on how many workers run.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..distributions import Marginal
from ..errors import ConfigError

SAMPLERS = ("grid", "sobol", "lhs", "random")
DISTRIBUTIONS = ("normal", "truncnormal", "uniform", "lognormal")
_KEYS = {"values", "range", "distribution", "mean", "sd", "low", "high", "relative", "bounds",
         "start"}
U_EPS = 1e-12  # keep inverse CDFs finite at a sampler's exact 0 (Sobol's first point)


@dataclass
class Variable:
    key: str
    values: list | None = None  # grid values (or a discrete choice for the other samplers)
    distribution: str | None = None
    dist: Marginal | None = None  # scipy.stats' frozen distribution of that name, without the import
    params: dict | None = None  # absolute parameters as given after `relative` is applied
    bounds: tuple | None = None  # optimisation bounds
    start: float | None = None  # optimisation start (default: the base value)
    base: float | None = None  # the base config's value

    def ppf(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        if self.values is not None:
            idx = np.minimum((u * len(self.values)).astype(int), len(self.values) - 1)
            return np.asarray(self.values, dtype=float)[idx]
        return self.dist.ppf(np.clip(u, U_EPS, 1 - U_EPS))

    @property
    def spread_zero(self) -> bool:
        return self.dist is None and self.values is not None and len(set(self.values)) == 1


def _num(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def parse_variable(key: str, spec, default, sampler) -> Variable:
    where = f"vary.\"{key}\""
    if not isinstance(spec, dict):
        raise ConfigError(f"{where} must be a table (values, range or distribution)")
    for k in spec:
        if k not in _KEYS:
            raise ConfigError(f"unknown key '{where}.{k}'")
    var = Variable(key, base=default)
    given = [k for k in ("values", "range", "distribution") if k in spec]
    if len(given) > 1:
        raise ConfigError(f"{where}: give one of values, range or distribution, not {' and '.join(given)}")
    if "values" in spec:
        vals = spec["values"]
        if not isinstance(vals, list) or not vals or not all(_num(x) for x in vals):
            raise ConfigError(f"{where}.values must be a non-empty list of numbers, got {vals!r}")
        var.values = [float(x) for x in vals]
    elif "range" in spec:
        r = spec["range"]
        if (not isinstance(r, list) or len(r) != 3 or not all(_num(x) for x in r) or r[2] != int(r[2])
                or r[2] < 1):
            raise ConfigError(f"{where}.range must be [low, high, count], got {r!r}")
        if not r[0] <= r[1]:
            raise ConfigError(f"{where}.range low ({r[0]:g}) must be <= high ({r[1]:g})")
        if r[2] == 1 and r[0] != r[1]:
            raise ConfigError(f"{where}.range [{r[0]:g}, {r[1]:g}, 1] has one value but two ends: give a "
                              "count >= 2 to span them, or values = [...] for one value")
        var.values = [float(x) for x in np.linspace(r[0], r[1], int(r[2]))]
    elif "distribution" in spec:
        _parse_distribution(var, spec, where, key, default)
    elif "bounds" not in spec:
        raise ConfigError(f"{where} needs values, range, distribution or bounds")
    if "bounds" in spec:
        b = spec["bounds"]
        if not isinstance(b, list) or len(b) != 2 or not all(_num(x) for x in b) or not b[0] < b[1]:
            raise ConfigError(f"{where}.bounds must be [low, high] with low < high, got {b!r}")
        var.bounds = (float(b[0]), float(b[1]))
    else:
        var.bounds = implied_bounds(var)
    if "start" in spec:
        var.start = _need(spec, where, "start")
    if var.values is None and var.dist is None and sampler != "grid":
        # bounds only: sampled uniformly between them
        var.dist = Marginal("uniform", var.bounds[0], var.bounds[1] - var.bounds[0])
        var.distribution = "uniform"
    return var


def _need(spec: dict, where: str, name: str) -> float:
    """spec[name] as a float; a ConfigError unless it is a finite number."""
    v = spec.get(name)
    if not _num(v):
        raise ConfigError(f"{where}.{name} must be a finite number, got {v!r}")
    return float(v)


def _parse_distribution(var: Variable, spec: dict, where: str, key: str, default) -> None:
    """Sets var's distribution (dist, params, distribution; values = [mean] at zero spread) from spec."""
    name = spec["distribution"]
    if name not in DISTRIBUTIONS:
        raise ConfigError(f"{where}.distribution must be one of {', '.join(DISTRIBUTIONS)}, got {name!r}")
    rel = spec.get("relative", False)
    if not isinstance(rel, bool):
        raise ConfigError(f"{where}.relative must be true or false")
    mean = _need(spec, where, "mean") if "mean" in spec else default
    if name != "uniform" and mean is None:
        raise ConfigError(f"{where}.mean is needed (the config has no value for {key})")
    scale = abs(mean) if rel else 1.0
    if rel and mean == 0:
        raise ConfigError(f"{where}: relative = true needs a non-zero mean")
    if name in ("normal", "truncnormal", "lognormal"):
        sd = _need(spec, where, "sd") * scale
        if sd < 0:
            raise ConfigError(f"{where}.sd must be >= 0, got {sd:g}")
    if name == "normal":
        var.dist = Marginal("norm", mean, sd) if sd > 0 else None
        var.params = {"mean": mean, "sd": sd}
    elif name == "truncnormal":
        # relative: low/high are multiples of the mean (0.98 = 2 % below it)
        lo, hi = _need(spec, where, "low"), _need(spec, where, "high")
        if rel:
            lo, hi = lo * mean, hi * mean
        if not lo < hi:
            raise ConfigError(f"{where}.low ({lo:g}) must be < high ({hi:g})")
        if sd > 0:
            var.dist = Marginal("truncnorm", mean, sd, ((lo - mean) / sd, (hi - mean) / sd))
        var.params = {"mean": mean, "sd": sd, "low": lo, "high": hi}
    elif name == "uniform":
        lo, hi = _need(spec, where, "low"), _need(spec, where, "high")
        if rel:
            if mean is None:
                raise ConfigError(f"{where}.mean is needed for relative = true")
            lo, hi = lo * mean, hi * mean
        if not lo <= hi:
            raise ConfigError(f"{where}.low ({lo:g}) must be <= high ({hi:g})")
        var.dist = Marginal("uniform", lo, hi - lo) if hi > lo else None
        var.params = {"low": lo, "high": hi}
        mean = 0.5 * (lo + hi)
    else:  # lognormal with the given mean and standard deviation of the variable itself
        if not mean > 0:
            raise ConfigError(f"{where}: a lognormal needs mean > 0, got {mean:g}")
        s2 = math.log1p((sd / mean) ** 2)
        var.dist = Marginal("lognorm", 0.0, mean * math.exp(-s2 / 2), (math.sqrt(s2),)) if sd > 0 else None
        var.params = {"mean": mean, "sd": sd, "sigma_log": math.sqrt(s2)}
    var.distribution = name
    if var.dist is None:  # zero spread: the mean, exactly
        var.values = [float(mean)]


def implied_bounds(var: Variable):
    if var.values is not None and len(var.values) > 1:
        return (min(var.values), max(var.values))
    if var.dist is not None:
        lo, hi = var.dist.support()
        if math.isfinite(lo) and math.isfinite(hi):
            return (float(lo), float(hi))
        return (float(var.dist.ppf(0.001)), float(var.dist.ppf(0.999)))
    return None


def unit_points(sampler: str, n: int, dim: int, seed: int) -> np.ndarray:
    """n points in [0, 1)^dim. sobol: scrambled (Owen) Sobol' sequence; lhs: Latin hypercube;
    random: one SeedSequence stream per design."""
    if sampler in ("sobol", "lhs"):
        from scipy.stats import qmc  # here: scipy.stats takes ~0.5 s to import, which reading a study need not pay

    if sampler == "sobol":
        return qmc.Sobol(dim, scramble=True, rng=np.random.default_rng(np.random.SeedSequence(seed))).random(n)
    if sampler == "lhs":
        return qmc.LatinHypercube(dim, rng=np.random.default_rng(np.random.SeedSequence(seed))).random(n)
    if sampler == "random":
        return np.array([np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(d,))).random(dim)
                         for d in range(n)]).reshape(n, dim)
    raise ConfigError(f"unknown sampler {sampler!r}")


def design_matrix(variables, sampler: str, n: int, seed: int) -> np.ndarray:
    """(designs, keys) values. grid: the product of the value lists (n ignored)."""
    if sampler == "grid":
        return np.array(list(itertools.product(*[v.values for v in variables])), dtype=float)
    u = unit_points(sampler, n, len(variables), seed)
    return np.column_stack([v.ppf(u[:, j]) for j, v in enumerate(variables)])


def grid_size(variables) -> int:
    return int(np.prod([len(v.values) for v in variables]))
