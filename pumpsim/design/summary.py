"""Statistics of a result table against spec limits: yield, Cpk, status counts, and the text
summary `pumpsim sweep --summary` prints.

Yield = share of rows (design x speed) that were evaluated (status `ok`) and meet every limit;
a design that was not evaluated, lifts off or meets a friction paradox counts as a failure.
In spec (per output) = share of the evaluated rows within that output's limits; the rows the
model could not evaluate (geometry, numerical) are left out of the denominator and counted apart.
Cpk = min(USL - mean, mean - LSL) / (3 sd) over the rows with a finite value (one-sided with one
limit); it assumes a roughly normal output -- the histogram in the report shows whether it is.
A grid's designs are not a sample: no yield, Cpk or spread is computed for them.
"""
from __future__ import annotations

import math

import numpy as np

from ..presentation import resolution as unit_resolution
from ..presentation import resolved
from ..tolerances import DESIGN_CONSTANT_REL
from .outputs import BOOL_OUTPUTS, UNITS

EVALUATED = ("ok", "lift_off", "paradox")  # status kinds that carry output values


def status_kind(df):
    """The status's kind per row: the text before the first colon ('ok', 'geometry', ...)."""
    status = df["status"].astype(str)
    kinds = {t: t.split(":")[0] for t in status.unique()}  # few distinct texts among many rows
    return status.map(kinds)


def evaluated(df) -> np.ndarray:
    """Rows the model evaluated (with output values), lift-off and paradox included."""
    return status_kind(df).isin(EVALUATED).to_numpy()


def _size(values) -> float:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.abs(v).max()) if v.size else 0.0


def resolution(values, output) -> float:
    """The smallest difference the solver resolves in these values of an output: relative to
    their size plus an absolute floor per unit (a torque of 1e-13 N·m is rounding, not ripple)."""
    return DESIGN_CONSTANT_REL * _size(values) + unit_resolution(UNITS.get(output, ""))


def is_constant(values, output) -> bool:
    """No spread beyond the solver's resolution (or no value at all)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return not v.size or float(np.ptp(v)) <= resolution(v, output)


def resolved_among(x, values, output):
    """x, or 0.0 where it is below the resolution of the output's values (rounding noise)."""
    return resolved(x, UNITS.get(output, ""), _size(values))


def within(values, lim) -> np.ndarray:
    lo, hi = lim
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v)
    if lo is not None:
        ok &= v >= lo
    if hi is not None:
        ok &= v <= hi
    return ok


def cpk(values, lim) -> float:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 2:
        return math.nan
    m, s = v.mean(), v.std(ddof=1)
    lo, hi = lim
    sides = []
    if hi is not None:
        sides.append(hi - m)
    if lo is not None:
        sides.append(m - lo)
    if s == 0:
        return math.inf if min(sides) >= 0 else -math.inf
    return min(sides) / (3 * s)


def yield_share(df, limits) -> float:
    if len(df) == 0:
        return math.nan
    ok = (df["status"] == "ok").to_numpy().copy()
    for out, lim in limits.items():
        if out in df.columns:
            ok &= within(df[out].to_numpy(dtype=float), lim)
    return float(ok.mean())


def output_table(df, outputs, limits, sample: bool = True) -> list[dict]:
    """Per output: n, mean, sd, min, max, limits, whether it is constant (spread below the solver's
    resolution), and with limits the in-spec share of the evaluated rows (and Cpk for a sample;
    sample=False for a grid, whose points are chosen, not drawn)."""
    rows = []
    for o in outputs:
        if o not in df.columns or o in BOOL_OUTPUTS:
            continue
        v = df[o].to_numpy(dtype=float)
        v = v[np.isfinite(v)]
        lim = limits.get(o, (None, None))
        r = {"output": o, "unit": UNITS.get(o, ""), "n": int(v.size),
             "mean": float(v.mean()) if v.size else math.nan,
             "sd": float(v.std(ddof=1)) if v.size > 1 else math.nan,
             "min": float(v.min()) if v.size else math.nan, "max": float(v.max()) if v.size else math.nan,
             "lower": lim[0], "upper": lim[1]}
        r["constant"] = bool(v.size) and is_constant(v, o)
        # rounding noise shown as what it is: 0 below the solver's resolution
        r.update(mean=resolved_among(r["mean"], v, o), min=resolved_among(r["min"], v, o),
                 max=resolved_among(r["max"], v, o))
        if r["constant"]:
            r["sd"] = 0.0
        if o in limits:
            ev = evaluated(df)
            inside = within(df[o].to_numpy(dtype=float), lim)[ev]
            r["within"] = float(inside.mean()) if inside.size else math.nan
            r["n_within"], r["n_evaluated"], r["n_failed"] = int(inside.sum()), int(ev.sum()), int((~ev).sum())
            if sample:
                r["cpk"] = cpk(v, lim)
        rows.append(r)
    return rows


def status_counts(df) -> dict:
    """Counts by the status's kind (the text before the first colon)."""
    return {k: int(n) for k, n in status_kind(df).value_counts().items()}


def flag_counts(df) -> dict:
    return {f: int(df[f].fillna(False).astype(bool).sum()) for f in BOOL_OUTPUTS if f in df.columns}


def coverage(df, designs: int) -> dict:
    """Which of the designs 0..designs-1 the table misses, and which it holds more than once (a
    design is one row per speed: a (design, speed) pair that repeats is a duplicate)."""
    ids = df["design"].to_numpy(dtype=np.int64) if len(df) else np.zeros(0, np.int64)
    missing = np.setdiff1d(np.arange(designs), ids)
    keys = [c for c in ("design", "speed") if c in df.columns]
    dup = df.loc[df.duplicated(keys, keep=False), "design"].unique() if len(df) else []
    return {"missing": [int(i) for i in missing], "duplicated": sorted(int(i) for i in dup)}


def coverage_text(cov) -> str | None:
    """None when every design appears exactly once."""
    def ids(v):
        return ", ".join(map(str, v[:8])) + (", ..." if len(v) > 8 else "")

    parts = []
    if cov["missing"]:
        parts.append(f"{len(cov['missing'])} designs missing ({ids(cov['missing'])})")
    if cov["duplicated"]:
        parts.append(f"{len(cov['duplicated'])} designs appear more than once ({ids(cov['duplicated'])})")
    return "; ".join(parts) or None


def summary_text(df, study_outputs, limits, manifest=None, sampler=None) -> str:
    """The terminal's table of a result; a grid's designs (the manifest's sampler, else
    `sampler`) are chosen, not drawn: no spread, Cpk or yield, only the in-spec shares."""
    lines = []
    if manifest:
        status = manifest.get("status")
        gaps = coverage_text(coverage(df, int(manifest.get("designs") or 0)))
        if gaps:
            status = f"NOT complete: {gaps}"
        lines.append(f"study {manifest.get('study')} (hash {manifest.get('study_hash')}), sampler "
                     f"{manifest.get('sampler')}, seed {manifest.get('seed')}, {manifest.get('designs')} "
                     f"designs, status {status}")
    designs = df["design"].nunique() if len(df) else 0
    lines.append(f"{designs} designs, {len(df)} rows; status: "
                 + ", ".join(f"{k} {n}" for k, n in status_counts(df).items()))
    fl = flag_counts(df)
    if fl:
        lines.append("flags: " + ", ".join(f"{k} {n}" for k, n in fl.items()))
    head = f"{'output':22s} {'unit':>6s} {'n':>6s} {'mean':>11s} {'sd':>10s} {'min':>11s} {'max':>11s} {'LSL':>9s} {'USL':>9s} {'in spec':>8s} {'Cpk':>6s}"
    lines.append(head)

    def f(x, w, p=5):
        return f"{'—':>{w}s}" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:>{w}.{p}g}"

    grid = (manifest.get("sampler") if manifest else sampler) == "grid"
    table = output_table(df, study_outputs, limits, sample=not grid)
    for r in table:
        ins = f"{100 * r['within']:7.2f}%" if "within" in r else f"{'':>8s}"
        # values below the solvers' resolution are round-off: shown as 0, not as 2.6e-13
        size = max(abs(r["min"]), abs(r["max"])) if r["n"] else 0.0
        mean, lo, hi = (resolved(r[k], r["unit"]) for k in ("mean", "min", "max"))
        sd = None if grid else resolved(r["sd"], r["unit"], size)
        lines.append(f"{r['output']:22s} {r['unit']:>6s} {r['n']:6d} {f(mean, 11)} {f(sd, 10, 4)} "
                     f"{f(lo, 11)} {f(hi, 11)} {f(r['lower'], 9, 4)} {f(r['upper'], 9, 4)} {ins} "
                     f"{f(r.get('cpk'), 6, 3)}")
    failed = int((~evaluated(df)).sum()) if len(df) else 0
    if limits and failed:
        lines.append(f"in spec: share of the {len(df) - failed} evaluated rows ({failed} not evaluated)")
    if limits and not grid:
        lines.append(f"yield (evaluated and within every limit): {100 * yield_share(df, limits):.2f} %")
    elif limits:
        n_ok = int(evaluated(df).sum()) if len(df) else 0
        inside = round(yield_share(df, limits) * len(df)) if len(df) else 0
        lines.append(f"within every limit: {inside} of the {n_ok} evaluated rows (a grid: no yield, spread "
                     "or Cpk)")
    return "\n".join(lines)
