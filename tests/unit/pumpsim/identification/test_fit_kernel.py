"""The fits' model torques on the SIMD library (problem.torque_at) against the CasADi map they
replace (PUMPSIM_FIT_KERNEL=scalar): same model, with a ripple, a sensor lag (the refined grid), a
torque offset, a housing harmonic and a drifting speed column (the drive time and its rates)."""
import numpy as np
import pytest

from pumpsim.config import load_config
from pumpsim.data import Dataset
from pumpsim.identification import make_problem
from pumpsim.kernels import fast_kernel
from tests.conftest import ROOT
from tests.tolerances import SIMD_REL

NAMES = ["mu", "theta0", "speed", "ripple_cos", "ripple_sin", "torque_offset", "lag",
         "housing.harmonics.0.amplitude"]


def _problem():
    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml").with_harmonics([[4, 1e-5, 0.3]])
    t = np.arange(3001) / 10000.0
    w = cfg.speed * (1 - 0.02 * t / t[-1]) + np.random.default_rng(0).normal(0, 0.3, t.size)
    data = Dataset(t, np.zeros(t.size), speed=w)
    initial = {"ripple_cos": 0.01, "ripple_sin": -0.004, "torque_offset": 0.01, "lag": 5e-5}
    return make_problem(cfg, data, NAMES, initial=initial, ripple_order=2)


def test_simd_model_torques_equal_the_casadi_map(monkeypatch):
    prob = _problem()
    if fast_kernel(prob.kern.structure) is None:
        pytest.skip("no SIMD library on this machine: the fits use the CasADi map already")
    assert prob.tau is not prob.t  # the drifting column drives the model
    x = prob.x0
    fast_m, (fast_mj, fast_J) = prob.model(x), prob.model_and_jacobian(x)
    monkeypatch.setenv("PUMPSIM_FIT_KERNEL", "scalar")
    ref_m, (ref_mj, ref_J) = prob.model(x), prob.model_and_jacobian(x)
    scale = np.max(np.abs(ref_m))
    assert np.max(np.abs(fast_m - ref_m)) < SIMD_REL * scale
    assert np.max(np.abs(fast_mj - ref_mj)) < SIMD_REL * scale
    # the angle-acting columns carry the sample-interval slope, made of SIMD torques
    col = np.max(np.abs(ref_J), axis=0)
    assert np.all(np.max(np.abs(fast_J - ref_J), axis=0) <= SIMD_REL * np.where(col > 0, col, 1.0))
