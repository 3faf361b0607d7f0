"""The torque sensor's first-order low-pass acts on the continuous torque: its discretisation is
checked against the closed-form response, and the lagged model against a finer evaluation."""
import dataclasses
import math

import numpy as np

import pumpsim
from pumpsim.data import Dataset
from pumpsim.identification import make_problem
from pumpsim.sensor import LAG_SUBSTEPS, first_order_lag, refine
from tests.conftest import make_config
from tests.tolerances import LAG_FOH_ORDER_SLACK, LAG_MODEL_SUBSAMPLE_REL


def _steady_error(dt, T, w):
    t = np.arange(int(round(0.05 / dt))) * dt
    y = first_order_lag(np.sin(w * t), dt, T)
    exact = (np.sin(w * t) - w * T * np.cos(w * t)) / (1 + (w * T) ** 2)  # steady-state response
    settled = t > 20 * T
    return float(np.max(np.abs(y - exact)[settled]))


def test_lowpass_matches_the_continuous_filter_to_second_order():
    """First-order hold: exact for a torque linear between samples, so on a sine the error is
    O((omega dt)^2); halving dt divides it by ~4 (a zero-order hold: by 2, and it starts at half a
    sample of delay)."""
    T, w = 1.6e-4, 2 * math.pi * 400
    e1, e2 = _steady_error(1e-4, T, w), _steady_error(0.5e-4, T, w)
    assert e1 < 0.01  # (omega dt)^2 / 8 ~ 8e-3 of the amplitude at omega dt = 0.25
    assert e1 / e2 > 4 / LAG_FOH_ORDER_SLACK


def test_refine_interpolates_and_keeps_the_samples():
    a = np.array([[0.0, 1.0], [2.0, 3.0], [5.0, 3.0]])
    r = refine(a, 4)
    assert r.shape == (9, 2)
    assert np.array_equal(r[::4], a)
    assert np.allclose(r[1], [0.5, 1.5]) and np.allclose(r[6], [3.5, 3.0])


def test_lagged_model_is_the_continuous_filter_of_the_torque():
    """A lag of 1.7 samples on the 3-vane ellipse: the identification model (LAG_SUBSTEPS points
    per interval) against the filter applied to a simulation 16 x finer (a near-continuous
    reference). Coulomb reversals are jumps inside intervals; seen at their place to dt/4 the
    error is a small share of the lag's own effect (on samples only it is 10 %)."""
    cfg = dataclasses.replace(make_config("ellipse_4vanes", **{"rotor.vanes": 3}), angle=0.4)
    T = 0.25 / (3 * cfg.speed)
    fine = pumpsim.simulate(cfg, duration=0.02, rate=16 * 10000.0)
    coarse = pumpsim.simulate(cfg, duration=0.02, rate=10000.0)
    n = coarse.time.size
    ref = first_order_lag(fine.torque, fine.time[1] - fine.time[0], T)[::16][:n]
    prob = make_problem(cfg, Dataset(coarse.time, coarse.torque), ["lag"], initial={"lag": T})
    model = prob.model(prob.x0)
    effect = np.sqrt(np.mean((ref - coarse.torque) ** 2))  # what the lag changes
    err = np.sqrt(np.mean((model - ref) ** 2))
    assert LAG_SUBSTEPS > 1 and err < LAG_MODEL_SUBSAMPLE_REL * effect
    y, J = prob.model_and_jacobian(prob.x0)
    assert np.allclose(y, model, rtol=0, atol=1e-15 + 1e-12 * np.max(np.abs(model)))
    dT = 1e-3 * T
    fd = (prob.model(prob.x0 + dT) - prob.model(prob.x0 - dT)) / (2 * dT)
    assert np.allclose(J[:, 0], fd, rtol=1e-4, atol=1e-6 * np.max(np.abs(fd)))


def test_the_lowpass_is_the_sequential_recursion():
    """first_order_lag (a vectorised scan) equals the recursion y_s[k] = a y_s[k-1] + (1 - c) y[k]
    + (c - a) y[k-1] from steady state (scipy.signal.lfilter, as it was computed before) to 1e-12 of
    the input's scale: lags from far below a sample (a^d underflows after one pass) to far above
    the record (every pass), 1-D and column by column, records of 1 to 20,001 samples."""
    from scipy.signal import lfilter, lfilter_zi

    def recursion(y, dt, T):
        a = math.exp(-dt / T)
        c = T / dt * (1 - a)
        b = [1 - c, c - a]
        return lfilter(b, [1, -a], y, axis=0, zi=np.outer(lfilter_zi(b, [1, -a]), y[0]) if y.ndim > 1
                       else lfilter_zi(b, [1, -a]) * y[0])[0]

    rng = np.random.default_rng(0)
    dt = 1.25e-5
    for n in (1, 2, 3, 17, 5000, 20001):
        y = 3 + 0.01 * np.cumsum(rng.normal(size=(n, 3)), axis=0) + np.sin(np.arange(n))[:, None]
        for T in (1e-9, 1e-6, 5e-5, 2e-4, 1e-2, 10.0):
            for v in (y, y[:, 0]):
                assert np.max(np.abs(first_order_lag(v, dt, T) - recursion(v, dt, T))) <= 1e-12 * np.max(np.abs(v))
