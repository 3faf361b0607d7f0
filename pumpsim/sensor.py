"""The torque sensor between the shaft and the data file: an offset and a first-order lag.

Sensor effects are not mechanics, so they live here and not in the compiled model: the
identification applies the same functions to the model torque (and to its Jacobian columns).
"""
from __future__ import annotations

import math

import numpy as np


def first_order_lag(y, dt, T):
    """T dy_s/dt = y - y_s: a sensor low-pass acting on the CONTINUOUS shaft torque, discretised
    exactly for an input linear between samples (first-order hold):
    y_s[k] = a y_s[k-1] + (1 - c) y[k] + (c - a) y[k-1], a = exp(-dt/T), c = (T/dt)(1 - a),
    started in steady state at y[0]. A zero-order hold (input held over each interval) would
    advance the output by up to half a sample and misstate the attenuation of the orders near
    1/T; the torque between samples is not held. Assumes the torque is smooth on the scale of a
    sample (a friction reversal inside an interval is seen as a ramp).
    Works column by column on a 2-D array; T <= 0 returns y unchanged."""
    if T <= 0:
        return y
    a = math.exp(-dt / T)
    c = T / dt * (1 - a)
    y = np.asarray(y, dtype=float)
    u = np.empty_like(y)  # y_s[k] = sum_j a^(k-j) u[j]: the input terms, y_s[0] = y[0] (steady state)
    u[0] = y[0]
    np.multiply(y[1:], 1 - c, out=u[1:])
    u[1:] += (c - a) * y[:-1]
    return _geometric_scan(u, a)


def _geometric_scan(u, a):
    """s[k] = a s[k-1] + u[k] (s[0] = u[0]) along the first axis, by recursive doubling: after the
    pass with shift d each s[k] holds the terms j > k - 2d; the passes stop where a^d drops below
    the float resolution (those terms are below the last bit). Each pass only multiplies by
    a^d <= 1 and adds, so the result is the sequential recursion's to a few rounding errors, in
    log2(min(n, 39 / ln(1/a))) vectorised passes instead of a loop over the samples (and without
    scipy.signal, whose import, with scipy.stats, is ~1 s of a command)."""
    s = np.array(u, dtype=float)
    d, ad = 1, a
    while d < s.shape[0] and ad > 1e-17:
        s[d:] += ad * s[:-d]
        d, ad = 2 * d, ad * ad
    return s


# points per sample interval at which a model with a sensor lag evaluates the torque: the filter
# sees friction reversals inside an interval at their place to dt/4 (a linear hold over the whole
# interval misplaces them: on an independent 3-vane record with T = 1.6 dt, 0.56 x the noise
# sigma left on exact data; 4 points: 0.12 x), at 4 x the cost of the lagged model only
LAG_SUBSTEPS = 4


def refine(a, m):
    """a (per sample, rows) linearly interpolated onto m points per sample interval: rows
    a[0], a[0] + (a[1] - a[0])/m, ..., a[-1] (m (n - 1) + 1 rows)."""
    a = np.asarray(a, dtype=float)
    w = (np.arange(m) / m).reshape((m,) + (1,) * (a.ndim - 1))
    inner = a[:-1][None] * (1 - w[:, None]) + a[1:][None] * w[:, None]  # (m, n-1, ...)
    return np.concatenate([np.moveaxis(inner, 0, 1).reshape((-1,) + a.shape[1:]), a[-1:]])


def measured_torque(time, torque, lag=0.0, offset=0.0, every=1):
    """What the sensor reports for the shaft torque `torque` sampled at `time`; with every > 1
    the torque is a finer simulation (every points per reported sample interval) and the
    reported samples are time[::every]."""
    y = first_order_lag(np.asarray(torque, dtype=float) + offset, time[1] - time[0], lag)
    return y[::every]
