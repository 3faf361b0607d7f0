"""The prescribed drive: output sample times and the rotor angle, speed and acceleration of a
speed drive (with an optional shaft-order speed ripple). NumPy only; every simulation and fit
shares these formulas."""
from __future__ import annotations

import math

import numpy as np

from .errors import ConfigError


MAX_SAMPLES = 5_000_000  # output samples of one run (~40 bytes each per output column)


def sample_times(duration, rate):
    """The output times [s]: every 1/rate from 0 to duration."""
    if duration is None or not 0 < duration < math.inf:
        raise ConfigError(f"duration must be > 0 and finite, got {duration}")
    if rate is None or not 0 < rate < math.inf:
        raise ConfigError(f"rate must be > 0 and finite, got {rate}")
    n = int(math.floor(duration * rate + 1e-9)) + 1
    if n < 2:
        raise ConfigError(f"duration {duration:g} s at rate {rate:g} Hz gives fewer than 2 samples; "
                          "lengthen the duration or raise the rate")
    if n > MAX_SAMPLES:
        raise ConfigError(f"duration x rate gives {n} samples; the limit is {MAX_SAMPLES:,}: shorten the "
                          "duration or lower the rate")
    return np.arange(n) / rate


def ripple_motion(theta_n, theta_start, omega0, rc, rs, k, lib=np):
    """Rotor angle, speed and acceleration under a shaft-order-k speed ripple, as functions of the
    nominal angle theta_n (= theta_start at the start): omega = omega0 (1 + rc cos(k theta_n) -
    rs sin(k theta_n)) -- rc = A cos(phase), rs = A sin(phase) -- and theta its exact integral from
    theta_start. lib: numpy, or casadi for symbolic arguments (simulation, fits and their graphs
    share this one formula)."""
    c, s = lib.cos(k * theta_n), lib.sin(k * theta_n)
    theta = theta_n + (rc * (s - lib.sin(k * theta_start)) + rs * (c - lib.cos(k * theta_start))) / k
    return theta, omega0 * (1 + rc * c - rs * s), -k * omega0**2 * (rc * s + rs * c)


def speed_profile(theta0, speed, t, ripple=None):
    """Prescribed rotor angle, speed and acceleration; ripple = (k, A, phase) gives
    omega = speed (1 + A cos(k theta_n + phase)) with theta_n = theta0 + speed t."""
    theta_n = theta0 + speed * t
    if not ripple or ripple[1] == 0:
        return theta_n, np.full_like(t, speed), np.zeros_like(t)
    k, A, phase = ripple
    return ripple_motion(theta_n, theta0, speed, A * math.cos(phase), A * math.sin(phase), k)
