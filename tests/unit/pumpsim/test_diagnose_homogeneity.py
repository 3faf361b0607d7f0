"""The stationarity test: the chi-square test that per-segment estimates of an effect agree."""

import numpy as np
from scipy import stats

from tests.tolerances import HOMOGENEITY_MEAN_ABS, HOMOGENEITY_RATE_ABS

from pumpsim.diagnosis import stationarity as diag
from pumpsim.diagnosis.options import OPTIONS

STATIONARY_ALPHA = OPTIONS.stationary_alpha


def _design(n=400, segments=4):
    t = np.linspace(0, segments, n, endpoint=False)
    J = np.column_stack([np.cos(2 * np.pi * t), 3.0 * np.sin(2 * np.pi * t) + 0.5])  # scaled, correlated
    return J, np.floor(t)


def test_homogeneity_holds_its_level_under_the_null():
    """A stationary effect (same b in every segment) plus white noise, and a nuisance (an offset)
    that differs between segments and is profiled out: the statistic is chi-square with
    (S - 1) q = 6 dof -- mean 6, 5 % of draws below p 0.05."""
    J, seg = _design()
    rng = np.random.default_rng(11)
    b, sigma = np.array([0.7, -0.2]), 0.3
    N = np.ones((J.shape[0], 1))
    drift = 0.5 * seg  # the nuisance's value changes from segment to segment
    out = [diag.homogeneity(J, J @ b + drift + rng.normal(0, sigma, J.shape[0]), seg, sigma, N)
           for _ in range(2000)]
    assert all(h.dof == 6 for h in out)
    p = np.array([h.p_value for h in out])
    assert abs(np.mean(p < 0.05) - 0.05) < HOMOGENEITY_RATE_ABS
    assert abs(np.mean([h.statistic for h in out]) - 6) < HOMOGENEITY_MEAN_ABS
    assert stats.kstest(p, "uniform").pvalue > 0.001


def test_homogeneity_rejects_an_effect_that_changes_between_segments():
    J, seg = _design()
    rng = np.random.default_rng(3)
    b = np.where(seg[:, None] < 2, [0.7, -0.2], [0.2, 0.1])  # not the same effect in both halves
    r = np.sum(J * b, axis=1) + rng.normal(0, 0.3, J.shape[0])
    assert diag.homogeneity(J, r, seg, 0.3).p_value < STATIONARY_ALPHA


def test_segments_are_whole_revolutions():
    angle = np.linspace(0, 2 * np.pi * 9.5, 950)  # 9.5 revolutions: 4 segments of 2 (last takes the rest)
    seg = diag.revolution_segments(angle, np.array([0, angle.size]))
    assert set(np.unique(seg)) == {0, 1, 2, 3}
    rev = np.floor(angle / (2 * np.pi))
    assert all(np.unique(seg[rev == k]).size == 1 for k in range(10))
    assert diag.revolution_segments(angle[:300], np.array([0, 300])) is None  # 3 revolutions: too short
