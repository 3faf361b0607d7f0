"""Gauss-Newton's stop where no step lowers the residual. At the start point that is a minimum
only if the data cannot tell the start from the minimum the model's slope points to (an F test:
the start inside the fit's own 95 % confidence region); a start on a kink of the cost whose slope
points many standard errors away is NOT converged, and the message says where the slope points
and to fit again from another start. Later in a fit it is the usual minimum."""
import numpy as np
import pytest

from pumpsim.identification.optimiser import START_TEST_LEVEL, gauss_newton, start_test
from tests.stall_problems import Kinked as _Kinked

N = 50


def Kinked(y_data, kink=True, noise=0.0, seed=0):
    """tests/stall_problems.Kinked on N samples, slope scale 1."""
    return _Kinked(y_data, kink, N, 1.0, noise, seed)


def test_a_start_the_slope_leads_far_from_is_not_converged():
    # the least-squares slope of the data is ~0.9, 1e-3 noise: the start 1 is ~400 standard errors off
    out = gauss_newton(Kinked(0.9, noise=1e-3), np.array([1.0]))
    assert len(out.history) == 1 and out.x[0] == 1.0
    assert not out.converged
    assert "NOT a minimum" in out.message and "--start" in out.message
    # the message names where the slope points: the data's least-squares slope
    prob = Kinked(0.9, noise=1e-3)
    slope = float(prob.t @ prob.y / (prob.t @ prob.t))
    assert f"x = {slope:.6g}" in out.message


def test_noise_free_data_off_the_start_is_not_converged():
    out = gauss_newton(Kinked(0.9996), np.array([1.0]))
    assert not out.converged and "infinitely many" in out.message


def test_a_start_at_the_truth_is_converged_as_often_as_the_test_level_says():
    """Started at the truth (the kink at x = 1, data slope 1, noise): the step from it is noise, so
    the start passes in 1 - START_TEST_LEVEL of the records. 400 seeds: the count that fails is
    binomial(400, 0.05), mean 20, sd 4.4; 4 sd either side."""
    fails = 0
    for seed in range(400):
        out = gauss_newton(Kinked(1.0, noise=1e-2, seed=seed), np.array([1.0]))
        assert len(out.history) == 1
        fails += not out.converged
        if out.converged:
            assert "cannot tell the start from a minimum" in out.message
    mean, sd = 400 * START_TEST_LEVEL, np.sqrt(400 * START_TEST_LEVEL * (1 - START_TEST_LEVEL))
    assert mean - 4 * sd <= fails <= mean + 4 * sd


def test_a_parameter_on_its_bound_the_step_points_past_is_held_in_the_test():
    """Two orthogonal columns; the data wants x1 = 0.5 but x1 sits on its upper bound 0: the start
    is the minimum on that face (only x0 is tested, and its step is noise). Without the bound it is not."""
    rng = np.random.default_rng(1)
    t = np.arange(200) / 200
    J = np.column_stack([np.sin(6 * np.pi * t), np.cos(6 * np.pi * t)])
    rw = 0.5 * J[:, 1] + 1e-3 * rng.normal(size=t.size)
    full = np.linalg.lstsq(J, rw, rcond=None)[0]
    x = np.array([1.0, 0.0])
    se, p = start_test(x, full, rw, J, np.array([-10.0, -10.0]), np.array([10.0, 0.0]), t.size)
    assert p > START_TEST_LEVEL and se < 3.0
    se, p = start_test(x, full, rw, J, np.array([-10.0, -10.0]), np.array([10.0, 10.0]), t.size)
    assert p < 1e-12 and se > 100


def test_a_minimum_reached_by_steps_keeps_the_usual_message():
    out = gauss_newton(Kinked(0.9996, kink=False), np.array([0.9]))
    assert len(out.history) > 1 and abs(out.x[0] - 0.9996) < 1e-9
    assert "from the start" not in out.message


@pytest.mark.parametrize("y_data", [0.9, 1.1])
def test_a_smooth_cost_from_the_start_steps_away(y_data):
    # no kink: the start is left and the fit converges at the data's slope (the test never runs)
    out = gauss_newton(Kinked(y_data, kink=False, noise=1e-3), np.array([1.0]))
    assert out.converged and len(out.history) > 1 and "from the start" not in out.message


def test_levenberg_marquardt_stalled_at_the_start_is_judged_the_same_way():
    # before: no damping lowered the residual, a step damped to rounding was taken anyway and read
    # as "step below tolerance", converged
    far = gauss_newton(Kinked(0.9, noise=1e-3), np.array([1.0]), lm=True)
    assert not far.converged and len(far.history) == 1 and "NOT a minimum" in far.message
    near = gauss_newton(Kinked(0.9, kink=False, noise=1e-3), np.array([1.0]), lm=True)
    assert near.converged and abs(near.x[0] - 0.9) < 0.01


def test_a_start_that_is_not_a_minimum_says_where_its_slope_points():
    """FitOutcome.points_to: the start the Gauss-Newton step from a stalled start points to (the
    data's least-squares slope here), for a caller to fit again from; None for a start that is a
    minimum and for a fit that left its start."""
    prob = Kinked(0.9, noise=1e-3)
    out = gauss_newton(prob, np.array([1.0]))
    slope = float(prob.t @ prob.y / (prob.t @ prob.t))
    assert not out.converged and out.points_to == pytest.approx([slope], rel=1e-12)
    assert gauss_newton(Kinked(1.0, noise=1e-2, seed=1), np.array([1.0])).points_to is None
    assert gauss_newton(Kinked(0.9, kink=False, noise=1e-3), np.array([1.0])).points_to is None


def test_a_fit_that_did_not_converge_says_what_its_remaining_step_is_worth():
    """FitOutcome.left_chi2: the remaining Gauss-Newton step's squared length in standard errors
    (what the linear model would still take off the cost, in noise variances): the start test's
    length squared for a stalled start, the same measure at an iteration limit; None once converged."""
    prob = Kinked(0.9, noise=1e-3)
    out = gauss_newton(prob, np.array([1.0]))
    t = prob.t
    gn = t @ (prob.y - t) / (t @ t)
    length, _ = start_test(np.array([1.0]), np.array([gn]), prob.y - t, t[:, None], prob.lower, prob.upper, N)
    assert not out.converged and out.left_chi2 == pytest.approx(length ** 2, rel=1e-12) and out.left_chi2 > 1e4
    held = gauss_newton(Kinked(0.9, kink=False, noise=1e-3), np.array([1.0]), relaxation=0.1, max_iter=1)
    assert not held.converged and held.left_chi2 > 100  # 0.9 of a ~400-standard-error step left
    assert gauss_newton(Kinked(0.9, kink=False, noise=1e-3), np.array([1.0])).left_chi2 is None
