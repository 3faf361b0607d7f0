"""Sampling of a record: the time stamps' resolution, gaps and jitter, resampling onto a uniform
grid and the constant-speed section of a run-up."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import DataError
from .dataset import Dataset

# A step longer than 1.5 regular steps is a gap: midway between one step (T) and two (one sample
# missing), so jitter up to +-T/2 passes and a single missing sample is caught. Time stamps written
# with resolution q put a regular step anywhere in (T - q, T + q) and a one-sample gap in
# (2T - q, 2T + q): the limit is T + max(T/2, q), which keeps every record whose time stamps
# increase (q < T) and still catches each missing sample that q leaves detectable (q <= T/2).
GAP_STEPS = 1.5
# a regular step is one below 2.5 median steps (a gap of 1.5 samples or more is surely not one): the
# mean over them is the sample interval, also when quantised steps alternate (3e-4, 4e-4 s at 3 kHz)
REGULAR_STEPS = 2.5
JITTER_NOTE = 0.01  # steps that vary by more than 1 % of the interval are named in a note


def time_resolution(t) -> float:
    """The decimal resolution the time stamps were written with (1e-4 for '0.0123'), in the
    column's unit, or 0.0 when they are not on a decimal grid (binary time channels)."""
    t = np.asarray(t, dtype=float)

    def on_grid(values, d):
        x = values * 10.0 ** d
        return bool(np.all(np.abs(x - np.round(x)) <= 1e-6 + 1e-14 * np.abs(x)))

    probe = t[:: max(1, t.size // 10000)]
    for d in range(0, 13):  # a probe first, then all in blocks (no temporaries the size of the column)
        if on_grid(probe, d) and all(on_grid(t[i:i + 65536], d) for i in range(0, t.size, 65536)):
            return 10.0 ** -d
    return 0.0


@dataclass
class TimeGaps:
    """The sampling of a time column: the regular step (s), the steps longer than `limit` (their
    indices i: a gap between samples i and i + 1) and a note on jitter ('' when steady)."""

    time: np.ndarray
    step: float
    limit: float
    gaps: np.ndarray
    jitter: str

    def message(self, row) -> str:
        """The refusal: the first gap by row (row(i) names sample i), time and size, and the fix."""
        i = int(self.gaps[0])
        size = self.time[i + 1] - self.time[i]
        more = f" ({self.gaps.size - 1} more after it)" if self.gaps.size > 1 else ""
        return (f"{row(i + 1)}: a gap of {size:.6g} s in time after {self.time[i]:.10g} s, "
                f"{size / self.step:.3g} times the sample interval {self.step:.6g} s (about "
                f"{max(1, round(size / self.step) - 1)} samples missing){more}; cut the record at the gap, or "
                "set resample to a rate in Hz (or 'auto') to interpolate onto a uniform grid across it")

    def bridged(self) -> str:
        if not self.gaps.size:
            return ""
        sizes = self.time[self.gaps + 1] - self.time[self.gaps]
        return (f" across {self.gaps.size} gap{'s' if self.gaps.size > 1 else ''} in time (the longest "
                f"{sizes.max():.6g} s after {self.time[self.gaps[np.argmax(sizes)]]:.10g} s)")


def time_gaps(time, resolution: float = 0.0) -> TimeGaps:
    """Gaps and jitter of a strictly increasing time column (see GAP_STEPS); resolution [s]: the
    time stamps' (see `time_resolution`)."""
    dt = np.diff(time)
    if dt.size == 0:
        return TimeGaps(time, 1.0, math.inf, np.zeros(0, int), "")
    regular = dt[dt <= REGULAR_STEPS * np.median(dt)]
    step = float(np.mean(regular))
    limit = step + max((GAP_STEPS - 1) * step, resolution)
    jitter = ""
    lo, hi = float(regular.min()), float(regular.max())
    if hi - lo > JITTER_NOTE * step:
        quantised = 0 < hi - lo <= resolution * (1 + 1e-6)
        cause = f"time stamps written to {resolution:.3g} s" if quantised else "jitter"
        jitter = (f"time steps vary between {lo:.6g} and {hi:.6g} s about the interval {step:.6g} s "
                  f"({cause}); accepted as measured")
    return TimeGaps(time, step, limit, np.flatnonzero(dt > limit), jitter)



def check_rate(rate) -> None:
    if not (isinstance(rate, (int, float)) and rate > 0 and math.isfinite(rate)):
        raise DataError(f"resample must be a rate > 0 [Hz] or 'auto', got {rate}")


def resample(ds: Dataset, rate: float, gaps: TimeGaps | None = None) -> Dataset:
    """`ds` linearly interpolated onto a uniform grid at `rate` [Hz] from its first sample; the note
    says so, and names the gaps bridged (`gaps`: from `time_gaps`). A new sample strictly inside a
    gap (between two measured samples farther apart than `gaps.limit`, the step that makes a gap)
    is a straight line drawn across it, not a measurement: `measured` marks it False, so a fit
    leaves it out of its residual, and the note counts them."""
    check_rate(rate)
    if (ds.time[-1] - ds.time[0]) * rate > 5_000_000:
        raise DataError(f"resample {rate:g} Hz over {ds.time[-1] - ds.time[0]:.4g} s gives more than "
                        "5,000,000 samples; resample at a lower rate or cut the record")
    t = np.arange(ds.time[0], ds.time[-1] + 0.5 / rate, 1.0 / rate)
    t = t[t <= ds.time[-1] + 1e-6 / rate]  # the last sample also when rounding puts it a hair beyond
    f = lambda a: None if a is None else np.interp(t, ds.time, a)  # noqa: E731
    note = f"resampled to {rate:.6g} Hz (linear interpolation){gaps.bridged() if gaps else ''}"
    measured = _outside_gaps(t, gaps) if gaps is not None and gaps.gaps.size else None
    if measured is not None:
        note += (f"; {int(np.sum(~measured))} of the {t.size} resampled samples lie inside the gaps "
                 "(interpolated, not measured) and are left out of the fit's residual")
    return Dataset(t, f(ds.torque), f(ds.speed), f(np.unwrap(ds.angle)) if ds.angle is not None else None,
                   ds.source, ds.notes + [note], measured)


def _outside_gaps(t, gaps: TimeGaps) -> np.ndarray:
    """True for each time in t not strictly inside one of the gaps' intervals (a grid time within
    1e-3 sample interval of a measured one, rounding of the grid, is that sample)."""
    eps = 1e-3 * gaps.step
    lo, hi = gaps.time[gaps.gaps] + eps, gaps.time[gaps.gaps + 1] - eps
    k = np.searchsorted(lo, t, side="right") - 1  # the last gap starting at or before t
    inside = (k >= 0) & (t > lo[np.maximum(k, 0)]) & (t < hi[np.maximum(k, 0)])
    return ~inside


def steady_section(ds: Dataset, tolerance: float = 0.01) -> Dataset:
    """The longest run of samples whose speed stays within tolerance of that run's median speed
    (a constant-speed fit of a run-up uses only that part)."""
    if ds.speed is None:
        raise DataError("the constant-speed section needs a speed column (or drop the steady option)")
    w = ds.speed
    ref = np.median(w[w > 0.5 * w.max()])
    inside = np.abs(w - ref) <= tolerance * abs(ref)
    best, start, best_span = None, None, (0, 0)
    for i, ok in enumerate(np.append(inside, False)):
        if ok and start is None:
            start = i
        elif not ok and start is not None:
            if i - start > best_span[1] - best_span[0]:
                best_span = (start, i)
            start = None
    lo, hi = best_span
    if hi - lo < 10:
        raise DataError(f"no constant-speed section: fewer than 10 samples stay within "
                        f"{tolerance:.1%} of {ref:.4g} rad/s")
    best = ds.window(lo, hi)
    best.notes.append(f"constant-speed section t = {ds.time[lo]:.6g} .. {ds.time[hi - 1]:.6g} s "
                      f"(speed within {tolerance:.1%} of {ref:.5g} rad/s)")
    return best
