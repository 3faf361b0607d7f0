"""The bench-log diagnosis's Gauss-Newton (pump_workflow.gauss_newton) where no step leaves its
start: converged only when the data cannot tell the start from a minimum (optimiser.start_test, as
identify's Gauss-Newton); else NOT converged, saying where the slope points. A fit that does not
converge is said in the diagnosis's notes, its JSON and its report."""
import numpy as np
import pytest

from pumpsim.diagnosis.pump_workflow import NotConverged, gauss_newton
from pumpsim.identification.optimiser import START_TEST_LEVEL
from tests.stall_problems import Kinked as _Kinked

N, A = 200, 100.0  # residuals in noise sigmas: the slope's standard error 1 / (A |t|) = 0.0012


def Kinked(y_data, kink=True, seed=0):
    """tests/stall_problems.Kinked in noise sigmas (the diagnosis's residual): N samples, slope A,
    unit noise."""
    return _Kinked(y_data, kink, N, A, 1.0, seed)


def test_a_start_the_slope_leads_far_from_is_not_converged():
    # before: converged (no halving lowered the residual); the data's slope is 0.9, ~80 standard errors off
    prob = Kinked(0.9)
    x, r, J, converged, why = gauss_newton(prob, np.array([1.0]))
    assert x[0] == 1.0 and not converged
    slope = float(prob.t @ prob.y / (prob.t @ prob.t)) / A
    assert "NOT a minimum" in why and f"x = {slope:.6g}" in why
    # the step in standard errors, sigma from the residual the step leaves (3 digits in the message)
    r = prob.y - prob.model(x)
    sigma = np.sqrt((r @ r - (prob.t @ r) ** 2 / (prob.t @ prob.t)) / (N - 1))
    se = float(why.split("points ")[1].split(" standard")[0])
    assert se == pytest.approx((1.0 - slope) * A * np.linalg.norm(prob.t) / sigma, rel=1e-2)


def test_a_start_at_the_minimum_is_converged():
    x, r, J, converged, why = gauss_newton(Kinked(1.0, seed=3), np.array([1.0]))
    assert x[0] == 1.0 and converged and why == ""


def test_a_start_at_the_truth_fails_as_often_as_the_test_level_says():
    """400 records at the truth: the count called not converged is binomial(400, 0.05), mean 20,
    sd 4.4; 4 sd either side."""
    fails = sum(not gauss_newton(Kinked(1.0, seed=seed), np.array([1.0]))[3] for seed in range(400))
    mean, sd = 400 * START_TEST_LEVEL, np.sqrt(400 * START_TEST_LEVEL * (1 - START_TEST_LEVEL))
    assert mean - 4 * sd <= fails <= mean + 4 * sd


def test_values_of_infinite_weight_are_not_counted_as_samples(monkeypatch):
    # the weighted problem: the current's switch-on block has weight inf, its residual and Jacobian
    # rows 0; counted as samples they would shrink the noise estimate and lengthen the step
    import pumpsim.diagnosis.pump_workflow as pw

    seen = []
    monkeypatch.setattr(pw, "start_test", lambda *a: seen.append(a[-1]) or (0.0, 1.0))
    prob = Kinked(0.9)
    prob.w = np.where(np.arange(N) < 3, np.inf, 1.0)
    assert gauss_newton(prob, np.array([1.0]))[3] and seen == [N - 3]


def test_a_smooth_fit_leaves_the_start_and_converges():
    x, r, J, converged, why = gauss_newton(Kinked(0.9, kink=False), np.array([1.0]))
    assert converged and why == "" and abs(x[0] - 0.9) < 0.01


def test_a_fit_stopped_by_its_iteration_limit_says_so():
    x, r, J, converged, why = gauss_newton(Kinked(0.9, kink=False), np.array([3.0]), max_iter=1)
    assert not converged and "1 Gauss-Newton step did not settle" in why


def test_the_notes_say_what_a_fit_that_did_not_converge_leaves_open():
    base = NotConverged("baseline", "why").text()
    assert base.startswith("the baseline fit is NOT converged (why)") and "the verdict may be wrong" in base
    refit = NotConverged("booster_leak", "why").text()
    assert refit.startswith("the refit of booster_leak is NOT converged (why)") and "understated" in refit
    # the torque workflow's: its baseline advice names its data, its final model's whole-record fit
    assert NotConverged("baseline", "why", "measurement").text().endswith("fit the measurement with pumpsim identify")
    final = NotConverged("final", "why").text()
    assert final.startswith("the final model's fit is NOT converged (why)") and "not the fit's minimum" in final
