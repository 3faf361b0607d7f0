"""Model adequacy (identification/adequacy.py) on signals with a known answer: the fit percentage's
closed form, a residual that is noise, an effect the model lacks, and a model that is not the pump."""
import math

import numpy as np
import pytest

from pumpsim.identification.adequacy import ORDER_MISFIT_MAX, assess

N, DT, W = 4000, 1e-4, 471.0
T = np.arange(N) * DT
ANGLE = 0.3 + W * T


def lines(orders_amps, angle=ANGLE):
    return sum(a * np.cos(k * angle + 0.1 * k) for k, a in orders_amps)


def noise(sigma, seed=0):
    return np.random.default_rng(seed).normal(0, sigma, N)


def test_noise_only_residual_is_adequate_and_fit_percent_is_its_closed_form():
    model = 0.2 + lines([(4, 0.05), (8, 0.02)])
    e = noise(0.005)
    a = assess(model + e, model, ANGLE, DT, W)
    assert a.verdict == "adequate"
    expected = 100 * (1 - np.linalg.norm(e) / np.linalg.norm(model + e - np.mean(model + e)))
    assert a.fit_percent == pytest.approx(expected, rel=1e-12)
    assert a.model_orders[:2] == [4, 8]
    # the noise floor from the high-frequency band: within 10 % (median of ~800 bins: ~4 % sd)
    assert a.noise_sigma == pytest.approx(0.005, rel=0.1)


def test_an_effect_the_model_lacks_is_systematic_not_inadequate():
    """An order-1 line (an eccentric rotor) of 6 x the noise beside a model that fits its own orders."""
    model = 0.2 + lines([(4, 0.05), (8, 0.02)])
    y = model + 0.03 * np.cos(ANGLE + 1.0) + noise(0.005)
    a = assess(y, model, ANGLE, DT, W)
    assert a.verdict == "systematic"
    assert a.systematic_rms == pytest.approx(0.03 / math.sqrt(2), rel=0.1)
    assert a.order_misfit < 0.05
    assert abs(a.worst_orders[0]["order"] - 1) < 0.1
    assert a.warning() and a.problem() is None


def test_a_model_that_is_not_the_pump_is_inadequate():
    """Data of a 4-vane pump (order 4) fitted by a 3-vane model (order 6): the model's own line is
    the residual's."""
    data = 0.2 + lines([(4, 0.05)]) + noise(0.005)
    model = 0.2 + lines([(6, 0.02)])
    a = assess(data, model, ANGLE, DT, W)
    assert a.verdict == "inadequate" and a.order_misfit > ORDER_MISFIT_MAX
    assert "cannot describe" in a.problem()


def test_a_wrong_speed_leaves_the_model_lines_in_the_residual():
    """The record at 471 rad/s, the model's angle at 3 % more: the lines drift apart over the record."""
    data = 0.2 + lines([(4, 0.05), (8, 0.02)]) + noise(0.005)
    model = 0.2 + lines([(4, 0.05), (8, 0.02)], angle=0.3 + 1.03 * W * T)
    assert assess(data, model, 0.3 + 1.03 * W * T, DT, 1.03 * W).verdict == "inadequate"


def test_a_flat_model_is_judged_by_its_systematic_share():
    """A model without shaft orders cannot be checked at its orders: a systematic residual of more
    than half the torque is inadequate, a few per cent is an effect."""
    flat = np.full(N, 0.2)
    a = assess(flat + lines([(2, 0.25)]) + noise(0.005), flat, ANGLE, DT, W)
    assert a.model_orders == [] and a.verdict == "inadequate"
    b = assess(flat + lines([(1, 0.01)]) + noise(0.002), flat, ANGLE, DT, W)
    assert b.verdict == "systematic"


@pytest.mark.parametrize("offset,verdict", [(0.0, "adequate"), (0.002, "systematic"), (0.4, "inadequate")])
def test_a_white_residual_about_a_mean_the_fit_left_is_not_adequate(offset, verdict):
    """White noise about a constant the fit could not remove (a COF on its bound, a reversed sensor):
    0.002 N m is 25 standard errors of the mean of 4,000 samples at sigma 0.005 -- systematic; an
    offset of twice the model's level is inadequate; none is adequate."""
    model = 0.2 + lines([(4, 0.05), (8, 0.02)])
    a = assess(model + offset + noise(0.005, seed=3), model, ANGLE, DT, W)
    assert a.verdict == verdict
