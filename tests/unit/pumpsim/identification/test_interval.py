"""The interval-average columns' pieces (identification/interval.py): the step finder flags the
intervals of a step (and its margin) and no smooth interval; the smooth-part formula is the
8-point interval average's derivative to O(h^4)."""
import numpy as np

from pumpsim.identification.interval import MARGIN, smooth_interval_columns, stepped_samples, subpoint_offsets


def _torque(theta, step_at=None):
    tq = 0.08 + 0.02 * np.sin(4 * theta) + 0.01 * np.cos(12 * theta + 0.3)
    if step_at is not None:
        tq = tq + 0.004 * (theta > step_at)  # a friction reversal: 5 % of the scale
    return tq


def test_a_step_is_flagged_with_its_margin_and_smooth_intervals_are_not():
    h = 0.0236  # the 4-vane ellipse at 20 kHz: the sample interval, rad
    theta = np.arange(400) * h
    step_at = theta[200] + 0.3 * h  # inside sample 200's interval [theta - h/2, theta + h/2]
    flags = stepped_samples(_torque(theta, step_at), _torque(theta - h / 2, step_at),
                            _torque(theta + h / 2, step_at), 0.12)
    near = np.nonzero(flags[10:-10])[0] + 10
    # its interval and neighbours with the margin; the signatures' own stencils reach 3 samples
    assert flags[199 - MARGIN:202 + MARGIN].all() and near.min() >= 197 - MARGIN and near.max() <= 203 + MARGIN
    smooth = stepped_samples(_torque(theta), _torque(theta - h / 2), _torque(theta + h / 2), 0.12)
    assert smooth.sum() == 2 * (2 + MARGIN)  # the record's ends only


def test_a_step_centred_on_a_sample_is_flagged():
    """A step at the sample itself leaves the second difference over the half-intervals at 0; the
    slope signature sees it (H/2)."""
    h = 0.0236
    theta = np.arange(400) * h
    step_at = theta[200]
    tq = _torque(theta, step_at) + 0.002 * (theta == step_at)  # the sample sits mid-transition
    flags = stepped_samples(tq, _torque(theta - h / 2, step_at), _torque(theta + h / 2, step_at), 0.12)
    assert flags[200] and flags[200 - MARGIN] and flags[200 + MARGIN]
    assert not flags[100:190].any() and not flags[210:390].any()


def test_a_derivative_spike_is_flagged():
    """A transition narrower than the samples' spacing that the parameter moves: no step in the
    sampled torque, a spike in its exact derivative."""
    h = 0.0236
    theta = np.arange(400) * h
    d = np.cos(4 * theta)[:, None]
    d[300] += 40.0
    flags = stepped_samples(_torque(theta), _torque(theta - h / 2), _torque(theta + h / 2), 0.12, d)
    assert flags[300 - MARGIN:301 + MARGIN].all() and not flags[100:290].any()


def test_smooth_columns_are_the_interval_average_derivative_to_fourth_order():
    """d/dp of the 8-point interval mean of sin(k theta + p) is the mean of cos over the points:
    the formula from the derivatives at the samples agrees to O((k h)^4)."""
    k, p = 12, 0.4
    for h in (0.0236, 0.0118):
        theta = np.arange(200) * h
        d = np.cos(k * theta + p)[:, None]
        exact = np.mean([np.cos(k * (theta + o * h) + p) for o in subpoint_offsets(8)], axis=0)
        err = np.max(np.abs(smooth_interval_columns(d, 8)[1:-1, 0] - exact[1:-1]))
        assert err < 0.02 * (k * h) ** 4  # the O(h^4) term's coefficient is below 1/100
        assert np.max(np.abs(d[1:-1, 0] - exact[1:-1])) > 10 * err  # the correction matters
