"""A measured speed column that drifts (F19: a motor sagging 2 % over the record): the model's angle
must follow the integral of the measured speed, not its mean. The record is made by the compiled
inverse dynamics along the drifting motion (theta, omega, omegadot exact), with noise on the
torque and on the speed column."""
import math

import numpy as np
import pytest

from pumpsim.config import as_array, load_config
from pumpsim.data import Dataset, speed_trend
from pumpsim.diagnosis import diagnose
from pumpsim.identification import identify, make_problem
from pumpsim.kernels import load_kernels
from pumpsim.kernels import inverse_dynamics
from tests.conftest import ROOT
from tests.tolerances import COMPILED_REL, EFFECT_FINAL_RMS, EFFECT_MU_REL

RATE, DURATION, THETA0 = 10000.0, 0.5, 0.7


def drifting_motion(t, speed, drift):
    """A linear sag: omega = speed (1 + drift (t - t_mid) / D), theta its exact integral."""
    D = t[-1] - t[0]
    tm = 0.5 * D
    theta = THETA0 + speed * t + speed * drift * ((t - tm) ** 2 - tm ** 2) / (2 * D)
    return theta, speed * (1 + drift * (t - tm) / D), np.full_like(t, speed * drift / D)


def record(drift, seed=3, speed_noise=1e-3):
    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml")
    pv = cfg.parameters("constrained")
    t = np.arange(int(DURATION * RATE) + 1) / RATE
    theta, omega, omegadot = drifting_motion(t, cfg.speed, drift)
    torque = inverse_dynamics(load_kernels(pv.structure), as_array(pv), theta, omega, omegadot)["torque"]
    rng = np.random.default_rng(seed)
    sigma = 0.03 * float(np.std(torque))
    y = torque + rng.normal(0, sigma, t.size)
    w = omega + rng.normal(0, speed_noise * cfg.speed, t.size)
    return cfg, Dataset(t, y, speed=w), sigma


def test_trend_of_a_drifting_column_is_its_speed_integral_and_rate():
    _, data, _ = record(-0.02)
    tr = data.speed_trend()
    assert tr is not None and tr.p_value < 1e-10
    t = data.time
    theta, omega, omegadot = drifting_motion(t, 471.0, -0.02)
    noise = 1e-3 * 471.0 / math.sqrt(t.size)  # the column's noise averaged over the record
    assert np.max(np.abs(tr.speed(t) - omega)) < 10 * noise
    assert np.max(np.abs(tr.mean * tr.warped_time(t) - (theta - THETA0))) < 10 * noise * DURATION
    assert abs(tr.change() - 0.02) < 0.002


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_constant_column_within_noise_is_its_mean(seed):
    """White noise on a constant speed: no trend, and the model is exactly the one with the
    column's mean (today's constant-speed problem)."""
    cfg, data, _ = record(0.0, seed=seed)
    assert speed_trend(data.time, data.speed) is None
    flat = Dataset(data.time, data.torque, speed=np.full(data.n, np.mean(data.speed)))
    held = {"speed": float(np.mean(data.speed))}
    a, b = (make_problem(cfg, d, ["mu", "theta0"], extra=held) for d in (data, flat))
    assert a.tau is a.t
    np.testing.assert_array_equal(a.model(a.x0), b.model(b.x0))


def test_white_or_rippling_columns_show_no_trend():
    """The trend test's false alarms: none in 50 white-noise columns (level 1e-3) and none where the
    column carries a 1 % shaft-order 1 or 2 ripple (left to the model's ripple)."""
    t = np.arange(int(DURATION * RATE) + 1) / RATE
    w0 = 471.0
    for seed in range(50):
        rng = np.random.default_rng(seed)
        ripple = 0.01 * np.cos((1 + seed % 2) * w0 * t + rng.uniform(0, 2 * math.pi)) if seed < 20 else 0.0
        assert speed_trend(t, w0 * (1 + ripple) + rng.normal(0, 1e-3 * w0, t.size)) is None, seed


def test_identify_follows_a_drifting_speed_column():
    """F19: with the column reduced to its mean the residual is several noise sigmas; with its
    trend the fit is the record up to the noise and mu is the configured one."""
    cfg, data, sigma = record(-0.02)
    res = identify(cfg, data, ["mu", "theta0"])
    assert res.rms < EFFECT_FINAL_RMS * sigma
    mu = cfg.parameters("constrained").values["friction.housing.dynamic"]
    assert abs(res.estimates["mu"].value - mu) < EFFECT_MU_REL * mu
    assert "speed column drifts" in res.message


def test_diagnose_names_nothing_for_a_drifting_speed():
    cfg, data, _ = record(-0.02)
    out = diagnose(cfg, data)
    assert out["effects"] == []
    assert not out["unexplained"]


def test_symbolic_model_follows_the_drift():
    """The IPOPT path's CasADi expression is the same model as the NumPy one."""
    import casadi as ca

    cfg, data, _ = record(-0.02)
    prob = make_problem(cfg, data, ["mu", "theta0"])
    phi = ca.MX.sym("phi", 2)
    f = ca.Function("m", [phi], [prob.symbolic_model(phi)])
    sym = np.asarray(f(prob.x0)).ravel()
    num = prob.model(prob.x0)
    assert np.max(np.abs(sym - num)) < COMPILED_REL * np.max(np.abs(num))
