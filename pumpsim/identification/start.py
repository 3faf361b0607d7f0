"""Start values for periodic parameters: theta0 is periodic and the speed moves the phase, so a
wrong initial phase could trap a local fit. The speed starts from shaft-synchronous evidence (in a
tolerance band) or the torque spectrum, the phase from a scan over one revolution."""
from __future__ import annotations

import math

import numpy as np

from ..diagnostics import synchronous_speed_scan
from ..simulate import inverse_dynamics

_GRID = np.linspace(0, 2 * math.pi, 720, endpoint=False)  # model over one revolution


def phase_and_speed_start(prob, x):
    """A constant-speed problem's start: the best phase (and, when fitted, the speed from the
    torque spectrum) at the other values of x."""
    x = np.array(x, dtype=float)
    names = prob.names
    d = dict(zip(names, x))
    w = d.get("speed", prob.fixed["speed"])
    one_rev = _one_revolution(prob, x, w)
    if "speed" in names:
        w_new = _speed_start(prob, w, one_rev)
        if w_new is not None:
            x[names.index("speed")] = w = w_new
            one_rev = _one_revolution(prob, x, w)
    if "theta0" in names:
        x[names.index("theta0")] = _phase_start(prob, one_rev, w, d.get("delay", prob.fixed["delay"]),
                                                d["theta0"])
    return x


def _one_revolution(prob, x, w):
    return inverse_dynamics(prob.kern, prob.parameter_vector(x), _GRID, w, 0.0)["torque"]


def _speed_start(prob, w, one_rev):
    """Inside the speed's tolerance band: from shaft-synchronous evidence only. Without a band:
    the torque spectrum's peak frequency divided by the model's dominant order (or another order
    within +-50 % of the current speed). None when the record is too short to say."""
    t, y, names = prob.t, prob.y, prob.names
    i = names.index("speed")
    if np.isfinite(prob.upper[i]):
        return synchronous_speed_scan(t, y, prob.lower[i], prob.upper[i], w)["speed"]
    if t.size <= 64:
        return None
    spec_y = np.abs(np.fft.rfft((y - y.mean()) * np.hanning(y.size)))
    f = np.fft.rfftfreq(y.size, t[1] - t[0])
    k = int(np.argmax(spec_y[1:])) + 1
    if 1 <= k < spec_y.size - 1:  # parabolic peak interpolation
        a, b, c = np.log(spec_y[k - 1:k + 2] + 1e-300)
        k = k + 0.5 * (a - c) / (a - 2 * b + c)
    f_peak = k * (f[1] - f[0])
    orders = np.abs(np.fft.rfft(one_rev - one_rev.mean()))
    order = int(np.argmax(orders[1:])) + 1
    candidates = [2 * math.pi * f_peak / o for o in range(1, 4 * prob.kern.structure.vanes + 1)]
    w_new = min(candidates, key=lambda c: abs(c - w) + (1e9 if abs(c - w) > 0.5 * w else 0))
    if abs(2 * math.pi * f_peak / order - w) < 0.5 * w:
        w_new = 2 * math.pi * f_peak / order
    return w_new


def _phase_start(prob, one_rev, w, delay, th_init):
    """The theta0 whose model (scaled, plus an offset) fits the torque best over a 1-degree scan;
    phases the torque cannot tell apart (its angular period) cost the same: the one nearest
    the initial guess. The angle runs with the problem's drive time (a drifting measured speed)."""
    t, y = prob.tau, prob.y
    costs = []
    for th0 in np.linspace(0, 2 * math.pi, 360, endpoint=False):
        ang = np.mod(th0 + w * (t - delay), 2 * math.pi)
        m = np.interp(ang, np.append(_GRID, 2 * math.pi), np.append(one_rev, one_rev[0]))
        A = np.column_stack([m, np.ones_like(m)])
        coef, res, *_ = np.linalg.lstsq(A, y, rcond=None)
        cost = float(res[0]) if res.size else float(np.sum((y - A @ coef) ** 2))
        if coef[0] > 0:
            costs.append((cost, th0))
    if not costs:
        return th_init
    lowest = min(c for c, _ in costs)
    near = [th for c, th in costs if c <= lowest * (1 + 1e-6) + 1e-300]
    dist = lambda a: abs((a - th_init + math.pi) % (2 * math.pi) - math.pi)  # noqa: E731
    return min(near, key=dist) if len(near) > 1 else min(costs)[1]
