"""The torque sensor between the shaft and the data file: an offset and a first-order lag.

Sensor effects are not mechanics, so they live here and not in the compiled model: the
identification applies the same functions to the model torque (and to its Jacobian columns).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter


def first_order_lag(y, dt, T):
    """T dy_s/dt = y - y_s, discretised exactly for a sample-and-hold input:
    y_s[k] = a y_s[k-1] + (1 - a) y[k], a = exp(-dt/T), started in steady state at y[0].
    Works column by column on a 2-D array; T <= 0 returns y unchanged."""
    if T <= 0:
        return y
    a = math.exp(-dt / T)
    y = np.asarray(y, dtype=float)
    if y.ndim > 1:
        return np.column_stack([first_order_lag(c, dt, T) for c in y.T])
    return lfilter([1 - a], [1, -a], y, zi=[a * y[0]])[0]


def measured_torque(time, torque, lag=0.0, offset=0.0):
    """What the sensor reports for the shaft torque `torque` sampled at `time`."""
    return first_order_lag(np.asarray(torque, dtype=float) + offset, time[1] - time[0], lag)
