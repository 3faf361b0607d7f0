"""A parameter that changes over the record -- the friction of a pump warming up, a COF running
in -- found by fitting it on consecutive segments and testing their trend, and reported with its
time course ("mu +7.0 % over 2 s"), not left as a low-order line in the residual.

Each segment (whole revolutions, at least DRIFT_MIN_REVS) refits the parameter and the phase from
the whole-record values; the others are held. The segment values' straight line in time is tested
by the slope's t statistic with the scatter about the line as its variance (S - 2 dof): a
stationary unmodelled effect scatters the segment values but gives them no trend, and the test
stays valid where the fits' own standard errors are optimistic. Named when the trend is
significant (DRIFT_ALPHA) and relevant (a change over the record of at least DRIFT_RELEVANT).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ..distributions import t_sf

DRIFT_SEGMENTS = 8
DRIFT_MIN_REVS = 3
DRIFT_ALPHA = 1e-3
DRIFT_RELEVANT = 0.01


@dataclass
class Drift:
    parameter: str
    change: float  # relative change over the record (the line's end over its start, less 1)
    over: float  # record length [s]
    p_value: float
    segments: list = field(default_factory=list)  # [{"time", "value", "stderr"}]
    line: tuple = ()  # the trend's value at the record's start and end

    def text(self) -> str:
        return f"drift: {self.parameter} {100 * self.change:+.2g} % over {self.over:.3g} s"

    def to_json(self) -> dict:
        return {**asdict(self), "text": self.text()}


def segment_bounds(n: int, revolutions: float) -> list:
    """Sample ranges of up to DRIFT_SEGMENTS consecutive segments of >= DRIFT_MIN_REVS revolutions."""
    count = min(DRIFT_SEGMENTS, int(revolutions // DRIFT_MIN_REVS))
    if count < 3:
        return []
    edges = np.linspace(0, n, count + 1).astype(int)
    return list(zip(edges[:-1], edges[1:]))


def trend(times, values) -> tuple:
    """(slope, its two-sided p-value, intercept) of the least-squares line through the points,
    the slope's variance from the scatter about the line (S - 2 dof)."""
    t, v = np.asarray(times, dtype=float), np.asarray(values, dtype=float)
    A = np.column_stack([np.ones_like(t), t - t.mean()])
    coef, *_ = np.linalg.lstsq(A, v, rcond=None)
    dof = t.size - 2
    s2 = float(np.sum((v - A @ coef) ** 2)) / max(dof, 1)
    var_b = s2 / float(np.sum((t - t.mean()) ** 2))
    if var_b <= 0:
        return float(coef[1]), (0.0 if coef[1] != 0 else 1.0), float(coef[0])
    tstat = float(coef[1]) / math.sqrt(var_b)
    return float(coef[1]), float(2 * t_sf(abs(tstat), dof)), float(coef[0])


def parameter_drift(fit, data, name: str, values: dict, speed: float) -> Drift | None:
    """The drift of `name` over the record `data` (a Dataset), or None (no trend, too short).
    `fit(segment, names, initial)` returns an IdentificationResult; `values` the whole-record
    fitted values (theta0 at the record's first sample, advanced to each segment's start)."""
    T = float(data.time[-1] - data.time[0])
    bounds = segment_bounds(data.n, abs(speed) * T / (2 * math.pi))
    if not bounds or name not in values:
        return None
    names = [name] + (["theta0"] if "theta0" in values else [])
    rows = []
    for a, b in bounds:
        seg = data.window(a, b)
        init = {name: values[name]}
        if "theta0" in names:
            init["theta0"] = float(np.mod(values["theta0"] + speed * (seg.time[0] - data.time[0]), 2 * math.pi))
        res = fit(seg, names, init)
        e = res.estimates[name]
        if e.value is None:
            return None
        rows.append({"time": float(0.5 * (seg.time[0] + seg.time[-1]) - data.time[0]), "value": float(e.value),
                     "stderr": None if e.stderr is None else float(e.stderr)})
    slope, p, mean = trend([r["time"] for r in rows], [r["value"] for r in rows])
    start = mean - slope * (T / 2)
    change = slope * T / start if start != 0 else 0.0
    if p >= DRIFT_ALPHA or abs(change) < DRIFT_RELEVANT:
        return None
    return Drift(name, float(change), T, float(p), rows, (float(start), float(start + slope * T)))
