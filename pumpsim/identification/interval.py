"""The sample-interval average of the model torque and its derivative by a geometric defect's
parameters from one exact derivative per sample, the difference quotients of the average kept only
where the torque is not smooth on the sample scale (problem.ConstantSpeedProblem._interval_columns).

The average over a sample interval of INTERVAL_SUBPOINTS equally spaced points (offsets o_j of the
interval h, centred on the sample) is, for a torque smooth there, f + mean(o^2) h^2 f''/2 +
O(h^4 f''''): its derivative by a parameter is the exact derivative d at the sample plus
mean(o^2)/2 times d's second difference over the neighbouring samples (h^2 d'' to O(h^4)). Only
where a Coulomb friction reversal (a step of the torque within ~1e-4 rad) lies in or next to the
interval does the average's difference quotient carry more -- the step's motion, the reason the
columns exist -- and there it is computed as before, from the sub-sample runs."""
from __future__ import annotations

import numpy as np

# a sample interval holds a step where one of its signatures (stepped_samples) departs from its
# neighbours' mean by more than this fraction of the torque's scale. A step of height H shows as H or
# H/2; the smooth part as ~f'''' h^4: on the 4-vane ellipse at 20 kHz the 95th percentile of the
# second-difference signature is 3e-4 of the scale, the friction reversals' steps 2-10 %. The
# threshold sits below the smooth part's tail on purpose: the torque's kinks (a contact side
# changing with a continuous force) are no steps but the smooth formula misses them too; at 1e-3
# the columns differed from the sub-sample runs' by 3e-4 - 9e-4 of their norm, at 1e-4 by 1e-7 -
# 5e-6 (a quarter to a half of the samples then take the runs). Too low a threshold costs only time.
STEP_FRACTION = 1e-4
# samples either side of an interval flagged by the step finder whose columns use the sub-sample runs:
# a sample's smooth formula takes its neighbours' derivatives (a step flags its own interval and,
# at half its height, both neighbours: with the margin, three samples either side of it; a margin
# of 1 doubled the columns' difference from the all-sample runs, 4e-4 -> 1e-3 of their norm)
MARGIN = 2
# an exact derivative departing from its neighbours' mean by more than this fraction of its own size
# plus the column's median size: a torque transition narrower than a sample (smooth, so no step
# between the sampled points) that the parameter moves; on a smooth column the departure is
# ~(k h)^2 / 2 of it, ~3e-3 for the 12th harmonic at h = 0.024 rad
KINK_FRACTION = 0.05


def subpoint_offsets(points: int) -> np.ndarray:
    """The sub-sample points' offsets from the sample, in sample intervals (centred, equally spaced)."""
    return (np.arange(points) + 0.5) / points - 0.5


def stepped_samples(samples, before, after, scale, columns=None) -> np.ndarray:
    """Boolean per sample: the interval (before, after: the torque half an interval either side of
    the samples) holds a step, or the exact derivatives `columns` (n, m) jump there, or it is within
    MARGIN samples of either; the first and last samples always, with their margin (no neighbours
    for the second differences). Two signatures of a step of height H, each compared with its
    neighbours' mean (which removes the smooth part to fourth order): the second difference over
    the half-intervals (H wherever the step lies, 0 for one centred on the sample) and the
    interval's slope against its neighbours' (H/2 for a centred step)."""
    a, b, c = (np.asarray(v, dtype=float) for v in (before, samples, after))
    e = a - 2 * b + c
    t = np.zeros_like(b)
    t[1:-1] = (c - a)[1:-1] - 0.5 * (b[2:] - b[:-2])
    hit = np.zeros(b.size, dtype=bool)
    for sig in (e, t):
        r = np.zeros_like(sig)
        r[2:-2] = sig[2:-2] - 0.5 * (sig[1:-3] + sig[3:-1])
        hit |= np.abs(r) > STEP_FRACTION * scale
    if columns is not None:  # a transition narrower than the samples' spacing, seen by its derivative
        d = np.atleast_2d(np.asarray(columns, dtype=float).T).T
        q = np.zeros_like(d)
        q[1:-1] = np.abs(d[1:-1] - 0.5 * (d[:-2] + d[2:]))
        hit |= np.any(q > KINK_FRACTION * (np.median(np.abs(d), axis=0) + np.abs(d)), axis=1)
    hit[:2] = hit[-2:] = True
    out = hit.copy()
    for s in range(1, MARGIN + 1):
        out[s:] |= hit[:-s]
        out[:-s] |= hit[s:]
    return out


def smooth_interval_columns(d, points: int) -> np.ndarray:
    """d (n, m), exact derivatives at the samples -> the derivatives of the interval averages where
    the torque is smooth: d + mean(o^2)/2 x the second difference of d over the samples (the end
    samples' rows left as d: they are stepped_samples' by construction)."""
    c = 0.5 * float(np.mean(subpoint_offsets(points) ** 2))
    out = np.array(d, dtype=float)
    out[1:-1] += c * (d[2:] - 2 * d[1:-1] + d[:-2])
    return out
