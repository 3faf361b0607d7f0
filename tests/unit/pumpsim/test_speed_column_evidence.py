"""A hypothesised speed ripple against a measured speed column (diagnostics.speed_column_disagreement)."""
import math

import numpy as np
import pytest

from pumpsim.signals import speed_column_disagreement

W, N = 471.0, 2000
T = np.arange(N) * 1e-4
THETA = 0.4 + W * T


def column(rc, rs, noise, seed, order=1):
    rng = np.random.default_rng(seed)
    return W * (1 + rc * np.cos(order * THETA) - rs * np.sin(order * THETA)) + rng.normal(0, noise, N)


def test_a_column_showing_the_hypothesised_ripple_agrees_at_the_test_level():
    """Under the null (the column holds the ripple, white noise) p is uniform: over 200 seeds the
    share below 0.05 stays within 5 % +- 4 binomial sd."""
    p = [speed_column_disagreement(column(0.004, 0.002, 0.3, s), T, THETA, W, 1, [0.004, 0.002], np.zeros((2, 2)))
         ["p_value"] for s in range(200)]
    share = np.mean(np.array(p) < 0.05)
    assert abs(share - 0.05) < 4 * math.sqrt(0.05 * 0.95 / 200)


def test_a_flat_column_refutes_a_half_percent_ripple():
    test = speed_column_disagreement(column(0, 0, 0.3, 1), T, THETA, W, 2, [0.004, 0.003], np.zeros((2, 2)))
    assert test["p_value"] < 1e-12
    assert test["column"] == pytest.approx([0, 0], abs=1e-4)


def test_the_torque_fits_own_uncertainty_widens_the_test():
    """An exact (noise-free) flat column against a ripple the torque determines only to +-0.2 %:
    a 0.1 % ripple is within it."""
    test = speed_column_disagreement(np.full(N, W), T, THETA, W, 1, [0.001, 0.0], np.diag([0.002**2, 0.002**2]))
    assert test["p_value"] > 0.5
