"""A one-parameter problem whose Gauss-Newton stalls where no step lowers the residual, for the
optimisers' start-stall tests (identify's, the bench-log diagnosis's)."""
import numpy as np


class Kinked:
    """model = A t (1 + c |x - 1|) against data A t y_data + noise x N(0, 1) on n samples: at x = 1
    both one-sided slopes raise the model while the Jacobian reports the smooth slope A t
    (kink=True), as a friction reversal's staircase does; c = 1e4 > 2 * 2^9: even the ninth halving
    of any step raises the cost. kink=False: the line A t x. With A = 100 and unit noise the
    residual is in noise sigmas (the slope's standard error ~1 / (A |t|))."""

    names = ["x"]
    lower, upper = np.array([-10.0]), np.array([10.0])

    def __init__(self, y_data, kink=True, n=50, scale=1.0, noise=0.0, seed=0):
        self.t = np.linspace(0.0, 1.0, n)
        self.scale = scale
        self.y = scale * self.t * y_data + noise * np.random.default_rng(seed).normal(size=n)
        self.kink = kink

    def model(self, x):
        return self.scale * self.t * ((1.0 + 1e4 * abs(x[0] - 1.0)) if self.kink else x[0])

    def model_and_jacobian(self, x):
        return self.model(x), self.scale * self.t[:, None]

    def keep_at(self, x):
        return None
