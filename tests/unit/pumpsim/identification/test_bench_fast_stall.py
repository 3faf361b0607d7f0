"""The bench-log fit's full-model steps after the fast model's fit (bench_fast._chord_steps) where
a step does not lower the residual: converged only when the data cannot tell that point from the
minimum the full model's step points to (optimiser.start_test against the full model's Jacobian,
at the point reached, not only the start); else NOT converged, saying where it points and that
the estimates are not the full model's fit."""
import numpy as np

from pumpsim.identification.bench_fast import STEP_SE, _chord_steps
from pumpsim.identification.optimiser import NO_DECREASE

N, A = 200, 100.0  # residuals in noise sigmas: the slope's standard error 1 / (A |t|) = 0.0012


class Walled:
    """model = A t (x + c max(1 - x, 0)) against data A t y_data + unit noise: the line above
    x = 1, a wall below it (c = 1e4) that the Jacobian A t does not show; kink=True: also a wall
    above (A t (1 + c |x - 1|) near 1, the friction staircase's step)."""

    names = ["x"]
    lower, upper = np.array([-10.0]), np.array([10.0])

    def __init__(self, y_data, kink=False, seed=0):
        self.t = np.linspace(0.0, 1.0, N)
        self.y = A * self.t * y_data + np.random.default_rng(seed).normal(size=N)
        self.kink = kink

    def model(self, x):
        x = x[0]
        if self.kink:
            return A * self.t * (1.0 + 1e4 * abs(x - 1.0))
        return A * self.t * (x + 1e4 * max(1.0 - x, 0.0))


def steps(prob, x0, slope=1.0):
    """_chord_steps from x0 with the Jacobian slope x A t (1: the model's own above the wall), no
    Broyden update (secant inf)."""
    x0 = np.array([x0])
    history = []
    return _chord_steps(prob, x0, prob.model(x0), slope * A * prob.t[:, None], lambda *a: history.append(a),
                        history, np.array([np.inf]))


def test_a_step_that_raises_the_residual_far_from_the_minimum_is_not_converged():
    # before: converged, "no further decrease of the residual"; the data's slope 0.9 is ~80 s.e. off
    out = steps(Walled(0.9, kink=True), 1.0)
    assert out.x[0] == 1.0 and not out.converged
    assert "NOT at the full model's minimum" in out.message and "do not use them" in out.message


def test_the_test_is_at_the_point_reached_not_the_start():
    """A Jacobian 1.25x the model's slope (a fast model's guide): from 2 the first step (-0.88) lowers
    the residual, to 1.12; the next (-0.18) hits the wall below 1. The fit stalls at 1.12, ~100
    standard errors from the data's 0.9: not converged, pointing to 1.12 - 0.18."""
    prob = Walled(0.9)
    out = steps(prob, 2.0, slope=1.25)
    assert 1.0 < out.x[0] < 1.2 and out.x[0] != 2.0 and not out.converged
    to = out.x[0] + float(prob.t @ (prob.y - prob.model(out.x)) / (prob.t @ prob.t)) / (1.25 * A)
    assert f"x = {to:.6g}" in out.message


def test_a_stall_at_the_minimum_is_converged():
    # the data's slope 1 (the wall's foot): the step is noise; seed 1: longer than STEP_SE s.e. (so
    # the stall is what stops the fit, not the step's size) and inside the 95 % region
    prob = Walled(1.0, kink=True, seed=1)
    out = steps(prob, 1.0)
    se = 1.0 / (A * np.linalg.norm(prob.t))
    assert abs(float(prob.t @ (prob.y - A * prob.t)) / (prob.t @ prob.t) / A) > STEP_SE * se
    assert out.converged and out.message == NO_DECREASE and out.x[0] == 1.0
