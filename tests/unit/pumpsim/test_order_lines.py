"""The order-line detector (diagnostics.order_lines) that opens speed-ripple candidates above the
library's orders: on white noise its per-order p-values are uniform and its false-alarm rate at a
stated level (Bonferroni over the orders examined) is at most that level; it finds an integer-order
line; a non-integer line -- one far from an integer, or a pulse train's comb member within a bin of
one -- opens nothing."""
import math

import numpy as np
from scipy import stats

from pumpsim.signals import order_lines
from tests.tolerances import NULL_KS_P

DT = 1e-4
N = 3000
SPEED = 471.0  # 22.5 revolutions, 133.4 samples per revolution (not a whole number)
ORDERS = range(9, 25)
TRIALS = 400


def _angle(n=N):
    return 0.3 + SPEED * DT * np.arange(n)


def _upper_binomial(level, trials=TRIALS, confidence=0.999):
    return stats.binom.ppf(confidence, trials, level)


def test_p_values_are_uniform_on_white_noise():
    """Kolmogorov-Smirnov of each of two orders' p-values over 300 white-noise records."""
    rng = np.random.default_rng(21)
    ps = [order_lines(rng.normal(size=N), _angle(), (9, 17), 0.01)["p_values"] for _ in range(300)]
    for k in (9, 17):
        assert stats.kstest([p[k] for p in ps], "uniform").pvalue > NULL_KS_P


def test_false_alarm_rate_is_at_most_the_stated_level():
    """At family level 5 % over 16 orders: records with any order significant (Bonferroni: below
    5 %/16) stay below the binomial 99.9 % upper bound of a 5 % rate; opened orders (the significant
    ones that also pass the line-shape checks) are rarer still."""
    rng = np.random.default_rng(22)
    alpha = 0.05
    significant = opened = 0
    for _ in range(TRIALS):
        out = order_lines(rng.normal(size=N), _angle(), ORDERS, alpha)
        assert out["examined"] == list(ORDERS)
        significant += min(out["p_values"].values()) < alpha / len(ORDERS)
        opened += bool(out["orders"])
    assert significant <= _upper_binomial(alpha), f"{significant} of {TRIALS}"
    assert opened <= significant


def test_an_integer_order_line_is_opened():
    """A line at order 12 with a tenth of the noise sigma (its bin 13 x the noise's) is found at 12."""
    rng = np.random.default_rng(23)
    a = _angle()
    out = order_lines(rng.normal(size=N) + 0.15 * np.cos(12 * a + 1.0), a, ORDERS, 0.01)
    assert out["orders"] == [12], out
    assert abs(out["frequencies"][12] - 12) < 1 / out["revolutions"]


def test_non_integer_lines_open_no_order():
    """A strong line at order 11.6, and a pulse train at 1.374 x shaft (a gear or a valve, not the
    shaft; its 8th harmonic, 10.993, lies 0.06 bin from order 11 on 22 revolutions, so order 11 IS
    significant) open nothing."""
    rng = np.random.default_rng(24)
    a = _angle()
    out = order_lines(rng.normal(size=N) + 2.0 * np.cos(11.6 * a), a, ORDERS, 0.01)
    assert out["orders"] == [], out
    period = 2 * math.pi / 1.374
    pulses = (np.mod(a, period) < 3 * SPEED * DT).astype(float)
    pulses = 10 * (pulses - pulses.mean()) / pulses.std()
    out = order_lines(rng.normal(size=N) + pulses, a, ORDERS, 0.01)
    assert out["p_values"][11] < 0.01 / len(ORDERS)
    assert out["orders"] == [], out
