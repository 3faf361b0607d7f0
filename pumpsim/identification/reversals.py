"""The samples next to the model's torque steps (Coulomb friction reversals between samples).

A Coulomb friction force changes sign within ~1e-4 rad of the rotor angle, far less than a sample
angle, so the point-sampled model torque has steps between samples. A parameter that moves a
reversal (theta0, speed, geometry, ripple, lag) changes the sampled model only when the step
crosses a sample: a least-squares cost over all samples is piecewise constant (a staircase) in it,
with steps far larger than the information criteria's margins. The samples that bracket each step
are therefore given weight 0 in the reversal-aware cost (the fits and every comparison in
diagnose) when the step lies within 1/8 of a sample interval of them: a small parameter change can
move it across them; a step nearer the middle of its interval cannot, and its samples keep the
reversal's timing evidence (which interval it is in) without making the cost a staircase. The mask depends on the model at
the current parameters, not on the noise, so under the noise-only null the kept samples are still
independent with one variance: the detectors run on the kept samples (dropped, not zero-filled).
"""
from __future__ import annotations


import numpy as np

# a step is masked when its midpoint signature exceeds this fraction of the noise sigma: a step of
# height H shows as |e| = H/2, so steps above 0.5 sigma are masked; a smaller step hopping across a
# sample changes the cost by < (0.5 sigma)^2 = 0.25 sigma^2, a quarter of one sample's expected
# squared noise (an n ln(RSS ratio) of ~0.25)
STEP_SIGMA = 0.25


def step_signature(samples, mids):
    """e_k = tau(t_k + dt/2) - (tau_k + tau_{k+1})/2 + (D2_k + D2_{k+1})/16 per interval k (n - 1
    values), D2 the sampled second difference (0 at the ends). For a torque smooth on the sample
    scale e = O(tau'''' dt^4) (the curvature term cancels -tau'' dt^2/8); for a step of height H
    inside the interval e = +-H/2 (the step's D2 terms cancel), wherever in the interval it is."""
    s = np.asarray(samples, dtype=float)
    d2 = np.zeros_like(s)
    d2[1:-1] = s[2:] - 2 * s[1:-1] + s[:-2]
    return np.asarray(mids, dtype=float)[:-1] - 0.5 * (s[:-1] + s[1:]) + (d2[:-1] + d2[1:]) / 16


# the step's place inside its interval is found by bisection to 1/2^BISECTIONS of a sample; a
# sample closer to a step than that is dropped (a step further from every sample cannot cross one
# within a small parameter change: the cost is smooth there and keeps the step's timing evidence)
BISECTIONS = 3


def _is_post(s, k, frac, v):
    """Whether v (the model at t_k + frac dt) is on the step's far side: nearer the value
    extrapolated linearly back from samples k+1, k+2 than forward from k-1, k."""
    n = s.size
    pre = s[k] + frac * (s[k] - s[np.maximum(k - 1, 0)])
    post = s[k + 1] - (1 - frac) * (s[np.minimum(k + 2, n - 1)] - s[k + 1])
    return np.abs(v - post) < np.abs(v - pre)


def reversal_keep(samples, mids, sigma, evaluate=None) -> np.ndarray:
    """Boolean per sample: False for a sample next to a step (an interval whose step signature
    exceeds STEP_SIGMA x sigma). With `evaluate(k, frac)` (the model at t_k + frac dt for the
    intervals k) the step is located by bisection and only a sample within 1/2^BISECTIONS of a
    sample interval of it is dropped; without, both samples bracketing the interval."""
    s = np.asarray(samples, dtype=float)
    keep = np.ones(s.size, dtype=bool)
    if sigma <= 0 or s.size < 2:
        return keep
    k = np.nonzero(np.abs(step_signature(s, mids)) > STEP_SIGMA * sigma)[0]
    if evaluate is None or k.size == 0:
        keep[k] = False
        keep[k + 1] = False
        return keep
    lo, hi = np.zeros(k.size), np.ones(k.size)
    frac = np.full(k.size, 0.5)
    v = np.asarray(mids, dtype=float)[k]
    for level in range(BISECTIONS):
        if level:
            frac = 0.5 * (lo + hi)
            v = np.asarray(evaluate(k, frac), dtype=float)
        post = _is_post(s, k, frac, v)
        hi, lo = np.where(post, frac, hi), np.where(post, lo, frac)
    keep[k[lo == 0]] = False
    keep[k[hi == 1] + 1] = False
    return keep
