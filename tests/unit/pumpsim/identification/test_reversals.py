"""The reversal-aware cost's step detector (pumpsim/identification/reversals.py) and the detectors
on a masked series: a step between samples is found wherever it lies in its interval and whatever
the smooth torque around it does; the kept samples of white noise are still white noise."""
import math

import numpy as np
import pytest
from scipy import stats

from pumpsim.signals import ljung_box, runs_test, synchronous_f_test
from pumpsim.signals import noise_sigma
from pumpsim.identification.reversals import STEP_SIGMA, reversal_keep, step_signature
from tests.tolerances import NULL_KS_P, ROBUST_SIGMA_REL, STEP_SIGNATURE_ABS


def _cubic(t):
    return 0.3 + 0.2 * t - 0.05 * t**2 + 0.01 * t**3


def test_signature_of_a_smooth_cubic_vanishes_inside():
    """The D2 correction cancels the midpoint's curvature error: exact for a cubic (interior)."""
    k = np.arange(12.0)
    e = step_signature(_cubic(k), _cubic(k + 0.5))
    assert np.max(np.abs(e[1:-1])) < STEP_SIGNATURE_ABS


@pytest.mark.parametrize("where", [0.1, 0.5, 0.9])
def test_a_step_inside_an_interval_shows_as_half_its_height(where):
    """A step H at any place inside interval 5 on top of the cubic: e_5 = +-H/2, neighbours H/16."""
    H, k = 0.7, np.arange(12.0)
    f = lambda t: _cubic(t) + H * (t > 5 + where)  # noqa: E731
    e = step_signature(f(k), f(k + 0.5))
    assert abs(abs(e[5]) - H / 2) < STEP_SIGNATURE_ABS
    assert abs(abs(e[4]) - H / 16) < STEP_SIGNATURE_ABS and abs(abs(e[6]) - H / 16) < STEP_SIGNATURE_ABS


def test_keep_drops_the_samples_bracketing_steps_above_threshold():
    sigma, k = 1.0, np.arange(40.0)
    big, small = 4 * STEP_SIGMA * sigma, 1.5 * STEP_SIGMA * sigma  # heights: e = H/2 -> 2x and 0.75x threshold
    f = lambda t: _cubic(t / 10) + big * (t > 10.3) - small * (t > 25.6)  # noqa: E731
    keep = reversal_keep(f(k), f(k + 0.5), sigma)
    assert list(np.nonzero(~keep)[0]) == [10, 11]


@pytest.mark.parametrize("where, dropped", [(0.05, [10]), (0.3, []), (0.5, []), (0.7, []), (0.95, [11])])
def test_a_located_step_drops_only_a_sample_it_is_near(where, dropped):
    """With the model between samples (bisection to 1/8 interval) only a sample within 1/8 of an
    interval of the step is dropped: a step in mid-interval cannot cross a sample under a small
    parameter change."""
    sigma, k = 1.0, np.arange(40.0)
    f = lambda t: _cubic(t / 10) + 2.0 * (t > 10 + where)  # noqa: E731
    keep = reversal_keep(f(k), f(k + 0.5), sigma, evaluate=lambda kk, frac: f(kk + frac))
    assert list(np.nonzero(~keep)[0]) == dropped


def test_robust_noise_sigma_ignores_a_smooth_part_and_spikes():
    rng = np.random.default_rng(4)
    n = 20000
    x = rng.normal(0, 2.0, n) + 5 * np.sin(np.arange(n) * 2 * math.pi / 400)
    x[::50] += 30.0  # 2 % spikes
    assert abs(noise_sigma(x) / 2.0 - 1) < ROBUST_SIGMA_REL


def _reversal_like_mask(n, period=33):
    """Pairs of samples dropped at a fixed pattern per 'vane passage' (what the mask of a model
    at constant speed looks like): deterministic, independent of the noise."""
    keep = np.ones(n, bool)
    for s in range(0, n - 1, period):
        keep[s + 7:s + 9] = False
        keep[s + 20:s + 22] = False
    return keep


@pytest.mark.parametrize("detector", ["runs", "ljung_box", "synchronous_f"])
def test_detectors_on_the_kept_samples_keep_their_null_distribution(detector):
    """p-values of each detector on the kept samples (dropped, the rest in order, with their
    angles) of 300 white-noise records are uniform (Kolmogorov-Smirnov)."""
    rng = np.random.default_rng(21)
    n = 1200
    keep = _reversal_like_mask(n)
    angle = 0.3 + 471.0 * 1e-4 * np.arange(n)
    ps = []
    for _ in range(300):
        x = rng.normal(size=n)[keep]
        ps.append({"runs": lambda: runs_test(x)["p_value"], "ljung_box": lambda: ljung_box(x)["p_value"],
                   "synchronous_f": lambda: synchronous_f_test(x, angle[keep])["p_value"]}[detector]())
    if detector == "runs":  # a discrete statistic: its p-values are not continuous; size at 5 % instead
        rate = np.mean(np.array(ps) < 0.05)
        lo, hi = stats.binom.ppf([0.0005, 0.9995], 300, 0.05) / 300
        assert lo <= rate <= hi
        return
    assert stats.kstest(ps, "uniform").pvalue > NULL_KS_P
