"""Gauss-Newton's stop where no step lowers the residual: at the start point it says so (the
model's slope there does not lead anywhere lower, as on a friction reversal's kink, and another
start tells whether it is a minimum), later it is the usual minimum."""
import numpy as np

from pumpsim.identification.optimiser import gauss_newton


class Kinked:
    """model = t (1 + c |x - 1|) against data t y_data: at x = 1 the model has a kink whose
    one-sided slopes both raise it, while the Jacobian reports the smooth slope t (kink=True);
    kink=False: the plain line t x."""

    names = ["x"]
    lower, upper = np.array([-10.0]), np.array([10.0])

    def __init__(self, y_data, kink=True):
        self.t = np.linspace(0.0, 1.0, 50)
        self.y = self.t * y_data
        self.kink = kink

    def model(self, x):
        return self.t * ((1.0 + 3.0 * abs(x[0] - 1.0)) if self.kink else x[0])

    def model_and_jacobian(self, x):
        return self.model(x), self.t[:, None].copy()

    def keep_at(self, x):
        return None


def test_a_start_no_step_leaves_is_named_as_such():
    out = gauss_newton(Kinked(0.9996), np.array([1.0]))
    assert out.converged and len(out.history) == 1
    assert "no step from the start lowered the residual" in out.message and "--start" in out.message


def test_a_minimum_reached_by_steps_keeps_the_usual_message():
    out = gauss_newton(Kinked(0.9996, kink=False), np.array([0.9]))
    assert len(out.history) > 1 and abs(out.x[0] - 0.9996) < 1e-9
    assert "from the start" not in out.message
