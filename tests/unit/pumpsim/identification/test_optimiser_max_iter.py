"""Gauss-Newton stopped by its iteration limit while still lowering the residual: converged when
the Gauss-Newton step left from its last point is below STEP_SE standard errors in every
parameter (what is left moves no estimate by a fifth of its uncertainty), not converged when it
is longer; the iterates and estimates are the same either way. The creep: the line
(tests/stall_problems.Kinked, kink=False) fitted with relaxation f = 0.5, whose distance to the
least-squares minimum halves at every step exactly -- the RMS falls by more than 1e-6 (relative)
per step down to ~0.003 standard errors, so only the iteration limit stops it."""
import numpy as np
import pytest

from pumpsim.identification.optimiser import MAX_ITER, gauss_newton
from pumpsim.tolerances import STEP_SE
from tests.stall_problems import Kinked

N, NOISE, F, ITER = 50, 1e-2, 0.5, 8  # a start 5 s.e. off after ITER steps: x0 ~ 4, in the bounds


def _line(seed=3):
    prob = Kinked(1.0, kink=False, n=N, noise=NOISE, seed=seed)
    x_min = float(prob.t @ prob.y / (prob.t @ prob.t))  # the least-squares minimum
    return prob, x_min


def _se(prob, x):
    """The standard error at x as the rule reads it: sigma^2 (J'J)^-1, sigma^2 = rss / (n - 1)."""
    r = prob.y - prob.model(np.array([x]))
    return float(np.sqrt(r @ r / (N - 1) / (prob.t @ prob.t)))


@pytest.mark.parametrize("left_se, converged", [(5.0, False), (0.6, False), (0.25, False), (0.15, True),
                                               (0.1, True), (0.02, True)])
def test_a_fit_still_creeping_at_its_limit_is_converged_only_within_the_step_rule(left_se, converged):
    prob, x_min = _line()
    se = _se(prob, x_min)
    # start where ITER relaxed steps leave left_se standard errors: d_k = d_0 (1 - F)^k
    x0 = x_min + left_se * se / (1 - F) ** ITER
    out = gauss_newton(prob, np.array([x0]), relaxation=F, max_iter=ITER)
    assert len(out.history) == ITER + 1  # the limit stopped it, not the RMS or step rule
    rel = [(a["rms"] - b["rms"]) / b["rms"] for a, b in zip(out.history, out.history[1:])]
    assert min(rel) > 1e-6  # still creeping at the last step
    # the iterates are the relaxed ones (d_0 (1 - F)^ITER from the minimum, to rounding)
    assert abs(out.x[0] - x_min) / se == pytest.approx(left_se, rel=1e-6)
    # the rule's standard error is the final point's: its rss holds the distance left too
    # (sigma^2 grows by left^2 / (n - 1) of itself: 5 s.e. read as 4.1, 0.25 as 0.2497)
    left = abs(out.x[0] - x_min) / _se(prob, out.x[0])
    assert bool(left <= STEP_SE) is converged
    assert out.converged is converged
    assert out.message.startswith(MAX_ITER)
    if converged:
        assert f"below {STEP_SE:g} standard errors" in out.message
        assert f"at most {left:.2g}, in x" in out.message
    else:
        assert f"step is {left:.3g} standard errors in x" in out.message


def test_the_rule_changes_the_flag_only_never_the_estimates():
    prob, x_min = _line()
    x0 = x_min + 0.1 * _se(prob, x_min) / (1 - F) ** ITER
    ruled = gauss_newton(prob, np.array([x0]), relaxation=F, max_iter=ITER)
    # the same fit one step shorter, continued by hand: the same iterates
    shorter = gauss_newton(prob, np.array([x0]), relaxation=F, max_iter=ITER - 1)
    assert [h["params"]["x"] for h in ruled.history[:-1]] == [h["params"]["x"] for h in shorter.history]
    assert ruled.x[0] == ruled.history[-1]["params"]["x"]


def test_a_scout_without_a_final_jacobian_keeps_the_plain_limit():
    prob, x_min = _line()
    x0 = x_min + 0.02 * _se(prob, x_min) / (1 - F) ** ITER
    out = gauss_newton(prob, np.array([x0]), relaxation=F, max_iter=ITER, final_jacobian=False)
    assert out.jacobian is None and not out.converged and out.message == MAX_ITER


def test_noise_free_data_is_converged_only_at_the_minimum():
    # sigma 0: every standard error is 0, so any step left is infinitely many of them
    prob = Kinked(0.9996, kink=False, n=N)
    out = gauss_newton(prob, np.array([1.5]), relaxation=F, max_iter=ITER)
    assert len(out.history) == ITER + 1 and not out.converged
