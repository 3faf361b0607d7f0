"""The integrator wrapper's state scaling on a problem with a known answer."""
import casadi as ca
import numpy as np

from pumpsim.integrate import Integrator, integrate_segmented
from tests.tolerances import OSCILLATOR_REL, OSCILLATOR_RTOL, SCALING_SAME_REL


def _oscillator(w):
    """x'' = -w^2 x as (x, v)."""
    return lambda x, pp: ca.vertcat(x[1], -w**2 * x[0])


def test_uniform_scale_is_the_same_as_a_scaled_atol():
    """CVODES's error weights 1 / (rtol |y| + atol) on y = x / c equal c / (rtol |x| + atol c):
    integrating x / c with atol a is integrating x with atol a c, step for step."""
    w, c, a = 30.0, 1e3, 1e-12
    t = np.linspace(0.0, 0.5, 51)
    x0 = np.array([0.0, 1.0])
    runs = []
    for scale, atol in ((np.full(2, c), a), (None, a * c)):
        integ = Integrator(_oscillator(w), 2, [], t[1], rtol=OSCILLATOR_RTOL, atol=atol, scale=scale)
        xs, _, stats = integrate_segmented(integ, x0, t)
        runs.append((xs, stats["nsteps"]))
    (xa, na), (xb, nb) = runs
    assert na == nb
    assert np.max(np.abs(xa - xb)) <= SCALING_SAME_REL * np.max(np.abs(xb))
    exact = np.sin(w * t) / w
    assert np.max(np.abs(xa[:, 0] - exact)) <= OSCILLATOR_REL * np.max(np.abs(exact))  # and it is right

