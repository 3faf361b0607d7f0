"""Start values for the parameters whose cost is not convex: theta0 is periodic and the speed moves
the phase, so a local fit from a wrong phase or speed ends in a wrong valley. A fitted speed starts
from the record's own shaft-order evidence over a wide band (or, refining a known operating point,
from shaft-synchronous evidence in its tolerance band), the phase from a scan over one revolution
at that speed; the local fit starts there."""
from __future__ import annotations

import math

import numpy as np

from ..distributions import f_sf
from ..signals import synchronous_speed_scan
from ..model_spec.parameters import MEASUREMENT_BY_NAME, registry
from ..kernels import sampled_inverse_dynamics

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
    for i, period in periodic_config_names(prob):
        x[i] = _periodic_start(prob, x, i, period)
    return x


PERIODIC_SCAN = 24  # start values tried over one period of a periodic config parameter


def periodic_config_names(prob) -> list:
    """(index, period) of the fitted config parameters that are angles (a harmonic's phase)."""
    reg = registry(prob.kern.structure)
    return [(i, reg[n].period) for i, n in enumerate(prob.names) if n in reg and reg[n].period]


def _periodic_start(prob, x, i, period):
    """The value of x[i] over one period (PERIODIC_SCAN points and the current one) whose model
    fits best at the other values of x."""
    def cost(v):
        z = x.copy()
        z[i] = v
        return float(np.sum((prob.y - prob.model(z)) ** 2))

    tried = [x[i]] + list(x[i] + period * np.arange(1, PERIODIC_SCAN) / PERIODIC_SCAN)
    return min(tried, key=cost)


def _one_revolution(prob, x, w):
    return sampled_inverse_dynamics(prob.kern, prob.parameter_vector(x), _GRID, w, 0.0, ("torque",))["torque"]


def _speed_start(prob, w, one_rev):
    """Inside the speed's tolerance band (a known operating point refined): from shaft-synchronous
    evidence only. Otherwise the speed the model's orders explain best over the whole start band
    (model_order_scan); None when nothing in the record tells (a model without shaft orders, a
    record too short, no significant match)."""
    i = prob.names.index("speed")
    if prob.speed_band is not None:
        return synchronous_speed_scan(prob.t, prob.y, prob.lower[i], prob.upper[i], w)["speed"]
    half = MEASUREMENT_BY_NAME["speed"].band
    lower, upper = max(w * (1 - half), prob.lower[i]), min(w * (1 + half), prob.upper[i])
    return model_order_scan(prob.tau, prob.y, one_rev, lower, upper)


SCAN_ALPHA = 1e-3  # family-wise false-alarm rate of the start scan (Bonferroni over its grid)
SCAN_BUDGET = 3e7  # complex multiply-adds of the coarse stage: ~0.3 s
SCAN_POWER = 0.999  # the model orders kept carry this share of its shaft-order power


def model_order_scan(t, y, one_rev, lower, upper):
    """The speed in [lower, upper] at which the record holds most of the model's shaft orders:
    the score sum_k |c_k| |Y_k(w)|, c_k the model's order-k Fourier coefficient over one
    revolution and Y_k(w) the record's at k w. Weighting by |c_k| and ignoring their phases keeps
    the score blind to lines the model does not have and robust to a model whose shape is still
    off (a COF start far from the truth moves the orders' phases, not where they lie).

    Coarse to fine: the grid step keeps the highest kept order's phase drift under pi/2 over the
    window; the first window is as long as the budget allows, each further stage four times longer
    around the best point, the last the whole record. The best point is used only when the
    kept orders' power there is significant (F-test against the rest, Bonferroni over the grid);
    None otherwise. Assumes a constant speed over the record."""
    t = np.asarray(t, dtype=float) - t[0]
    y = np.asarray(y, dtype=float) - np.mean(y)
    n = y.size
    if n < 64 or not upper > lower > 0:
        return None
    c = np.abs(np.fft.rfft(one_rev - np.mean(one_rev)))[1:] / one_rev.size
    dt = t[-1] / (n - 1)
    power = np.cumsum(np.sort(c**2)[::-1])
    if power[-1] <= 0:
        return None  # no shaft orders: the record cannot tell the speed
    kept = np.sort(np.argsort(c**2)[::-1][:int(np.searchsorted(power, SCAN_POWER * power[-1])) + 1])
    orders = kept + 1
    orders = orders[orders * upper * dt < 0.9 * math.pi][:32]  # below Nyquist
    if orders.size == 0:
        return None
    weights, kmax = c[orders - 1], int(orders.max())
    width = upper - lower
    m = int(min(n, max(64, math.sqrt(SCAN_BUDGET * math.pi / (2 * width * kmax**2 * dt)))))
    step = math.pi / (2 * kmax * max(t[m - 1], dt))
    grid = np.arange(lower, upper + 0.5 * step, step)
    first = _order_spectra(t[:m], y[:m], grid, orders)
    j = int(np.argmax(first @ weights))
    best = float(grid[j])
    explained = 2.0 * float(np.sum(first[j] ** 2)) / m
    total = float(y[:m] @ y[:m])
    dof = 2 * orders.size
    F = (explained / dof) / max((total - explained) / max(m - dof - 1, 1), 1e-300)
    if not f_sf(F, dof, max(m - dof - 1, 1)) * grid.size < SCAN_ALPHA:
        return None
    while m < n:
        m, step = min(n, 4 * m), step / 4
        local = best + step * np.arange(-8, 9)
        local = local[(local >= lower) & (local <= upper)]
        best = float(local[int(np.argmax(_order_spectra(t[:m], y[:m], local, orders) @ weights))])
    return best


def _order_spectra(t, y, speeds, orders):
    """|Y_k(w)| = |sum_j y_j exp(-i k w t_j)| for every speed w (rows) and order k (columns)."""
    out = np.empty((speeds.size, orders.size))
    for lo in range(0, speeds.size, 64):  # a block of speeds at a time: bounded memory
        e = np.exp(-1j * np.outer(speeds[lo:lo + 64], t))
        p = np.ones_like(e)
        col = 0
        for k in range(1, int(orders.max()) + 1):
            p *= e
            if k == orders[col]:
                out[lo:lo + 64, col] = np.abs(p @ y)
                col += 1
    return out


def _dot(a, b) -> float:
    """a . b without BLAS: OpenBLAS threads a long ddot, and on a busy machine its spinning threads
    made the 360 phases' dot products ~10x slower than one core's loop."""
    return float(np.einsum("i,i", a, b))


def _phase_start(prob, one_rev, w, delay, th_init):
    """The theta0 whose model (scaled, plus an offset) fits the torque best over a 1-degree scan;
    phases the torque cannot tell apart (its angular period) cost the same: the one nearest
    the initial guess. The angle runs with the problem's drive time (a drifting measured speed)."""
    t, y = prob.tau, prob.y
    yc = y - y.mean()
    grid, values = np.append(_GRID, 2 * math.pi), np.append(one_rev, one_rev[0])
    costs = []
    for th0 in np.linspace(0, 2 * math.pi, 360, endpoint=False):
        m = np.interp(np.mod(th0 + w * (t - delay), 2 * math.pi), grid, values)
        m -= m.mean()
        mm = _dot(m, m)
        if mm > 0:  # y ~ scale m + offset in closed form (an n x 2 lstsq per phase costs 5x more)
            scale = _dot(m, yc) / mm
            m *= scale
            m -= yc
            cost = _dot(m, m)
        else:  # a torque without ripple: every phase the same
            A = np.column_stack([m, np.ones_like(m)])
            coef, res, *_ = np.linalg.lstsq(A, y, rcond=None)
            scale, cost = coef[0], float(res[0]) if res.size else float(np.sum((y - A @ coef) ** 2))
        if scale > 0:
            costs.append((cost, th0))
    if not costs:
        return th_init
    lowest = min(c for c, _ in costs)
    near = [th for c, th in costs if c <= lowest * (1 + 1e-6) + 1e-300]
    dist = lambda a: abs((a - th_init + math.pi) % (2 * math.pi) - math.pi)  # noqa: E731
    return min(near, key=dist) if len(near) > 1 else min(costs)[1]
