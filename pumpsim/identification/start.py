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


PHASE_STEPS = 360  # theta0 tried over one revolution (each 2 points of _GRID)


def _phase_costs(t, y, one_rev, w, delay):
    """The least-squares cost of y ~ scale m(theta0) + offset for each of the PHASE_STEPS phases
    theta0 = j 2 pi / PHASE_STEPS, m(theta0) the one-revolution model interpolated linearly at
    theta0 + w (t - delay), and whether its scale is positive. A phase step is a shift of the
    model's grid by whole points, so every sample keeps its interval and weight for all phases:
    the sums the cost needs (of m, m^2, m y) are circular correlations of the grid values with
    per-point sums of the samples' weights, O(grid^2) for all phases instead of an interpolation
    of every sample per phase (which made the scan a per-sample cost of every diagnosis fit)."""
    G = _GRID.size
    shift = G // PHASE_STEPS
    pos = np.mod(w * (np.asarray(t, dtype=float) - delay), 2 * math.pi) * (G / (2 * math.pi))
    i = np.minimum(pos.astype(np.int64), G - 1)
    f = pos - i
    nxt = (i + 1) % G
    yc = y - y.mean()

    def spread(lo, hi):  # per grid point: the samples' weights as the lower and as the upper point
        return np.bincount(i, lo, G) + np.bincount(nxt, hi, G)
    ones, my, mm = spread(1 - f, f), spread((1 - f) * yc, f * yc), spread((1 - f) ** 2, f * f)
    cross = np.bincount(i, f * (1 - f), G)
    rows = np.lib.stride_tricks.sliding_window_view(np.concatenate([one_rev, one_rev]), G + 1)
    V = rows[:PHASE_STEPS * shift:shift]  # V[j, g]: the model at grid point g (and g + 1) for phase j
    n = y.size
    s1, sy = V[:, :G] @ ones, V[:, :G] @ my
    s2 = (V[:, :G] ** 2) @ mm + 2 * (V[:, :G] * V[:, 1:]) @ cross
    var = s2 - s1 * s1 / n  # |m - mean(m)|^2
    with np.errstate(divide="ignore", invalid="ignore"):
        cost = float(yc @ yc) - np.where(var > 0, sy * sy / var, 0.0)
    return cost, (sy > 0) & (var > 0)


def _phase_start(prob, one_rev, w, delay, th_init):
    """The theta0 whose model (scaled, plus an offset) fits the torque best over a 1-degree scan;
    phases the torque cannot tell apart (its angular period) cost the same: the one nearest
    the initial guess; a one-revolution model without ripple (to rounding): every phase the same,
    the initial guess. The angle runs with the problem's drive time (a drifting measured speed)."""
    one_rev = np.asarray(one_rev, dtype=float)
    if np.ptp(one_rev) <= 1e-12 * max(float(np.max(np.abs(one_rev))), 1e-300):
        return th_init
    cost, valid = _phase_costs(prob.tau, prob.y, one_rev, w, delay)
    if not valid.any():
        return th_init
    phases = np.linspace(0, 2 * math.pi, PHASE_STEPS, endpoint=False)  # the values the scan always tried
    costs = list(zip(cost[valid], phases[valid]))
    lowest = min(c for c, _ in costs)
    near = [th for c, th in costs if c <= lowest * (1 + 1e-6) + 1e-300]
    dist = lambda a: abs((a - th_init + math.pi) % (2 * math.pi) - math.pi)  # noqa: E731
    return min(near, key=dist) if len(near) > 1 else min(costs)[1]
