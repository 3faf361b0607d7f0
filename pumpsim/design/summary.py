"""Statistics of a result table against spec limits: yield, Cpk, status counts, and the text
summary `pumpsim sweep --summary` prints.

Yield = share of rows (design x speed) that were evaluated (status `ok`) and meet every limit;
a design that was not evaluated, lifts off or meets a friction paradox counts as a failure.
Cpk = min(USL - mean, mean - LSL) / (3 sd) over the rows with a finite value (one-sided with one
limit); it assumes a roughly normal output -- the histogram in the report shows whether it is.
"""
from __future__ import annotations

import math

import numpy as np

from ..presentation import resolved
from ..tolerances import DESIGN_CONSTANT_ABS, DESIGN_CONSTANT_REL
from .outputs import BOOL_OUTPUTS, UNITS




def is_constant(values, output) -> bool:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return not v.size or np.ptp(v) <= (DESIGN_CONSTANT_REL * np.abs(v).max()
                                      + DESIGN_CONSTANT_ABS.get(UNITS.get(output), 0.0))


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


def output_table(df, outputs, limits) -> list[dict]:
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
        if o in limits:
            r["within"] = float(within(df[o].to_numpy(dtype=float), lim).mean())
            r["cpk"] = cpk(v, lim)
        rows.append(r)
    return rows


def status_counts(df) -> dict:
    """Counts by the status's kind (the text before the first colon)."""
    kinds = df["status"].astype(str).str.split(":").str[0]
    return {k: int(n) for k, n in kinds.value_counts().items()}


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


def summary_text(df, study_outputs, limits, manifest=None) -> str:
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

    for r in output_table(df, study_outputs, limits):
        ins = f"{100 * r['within']:7.2f}%" if "within" in r else f"{'':>8s}"
        # values below the solvers' resolution are round-off: shown as 0, not as 2.6e-13
        size = max(abs(r["min"]), abs(r["max"])) if r["n"] else 0.0
        mean, lo, hi = (resolved(r[k], r["unit"]) for k in ("mean", "min", "max"))
        sd = resolved(r["sd"], r["unit"], size)
        lines.append(f"{r['output']:22s} {r['unit']:>6s} {r['n']:6d} {f(mean, 11)} {f(sd, 10, 4)} "
                     f"{f(lo, 11)} {f(hi, 11)} {f(r['lower'], 9, 4)} {f(r['upper'], 9, 4)} {ins} "
                     f"{f(r.get('cpk'), 6, 3)}")
    if limits:
        lines.append(f"yield (evaluated and within every limit): {100 * yield_share(df, limits):.2f} %")
    return "\n".join(lines)
