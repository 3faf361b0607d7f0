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
    if y.ndim > 1:
        return np.column_stack([first_order_lag(col, dt, T) for col in y.T])
    from scipy.signal import lfilter, lfilter_zi  # here: scipy.signal imports scipy.stats (~0.5 s)

    b = [1 - c, c - a]
    return lfilter(b, [1, -a], y, zi=lfilter_zi(b, [1, -a]) * y[0])[0]


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
