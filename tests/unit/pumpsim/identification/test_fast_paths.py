"""The fits' shortcuts where the general formula would only add zeros or build a list: the numeric
parameter map, the angle without a speed ripple and the drive tangents without a fitted ripple
give the general path's numbers bit for bit (a diagnosis's polar fits amplify any rounding change
into a different valley, so "close" would not do)."""
import casadi as ca
import numpy as np

from pumpsim.config import load_config
from pumpsim.data import Dataset
from pumpsim.identification import make_problem
from pumpsim.identification.problem import parameter_map
from pumpsim.identification.sampled import drive_tangents
from pumpsim.motion import ripple_motion
from tests.conftest import ROOT


def _problem(names, initial=None):
    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml").with_harmonics([[4, 1e-5, 0.3]])
    t = np.arange(2001) / 20000.0
    return make_problem(cfg, Dataset(t, np.zeros(t.size)), names, initial=initial)


def test_the_numeric_parameter_map_is_the_expression_path_bit_for_bit():
    prob = _problem(["mu", "theta0", "housing.harmonics.0.amplitude", "rotor.radius"])
    val = {"mu": 0.1234567, "housing.harmonics.0.amplitude": 1.7e-5, "rotor.radius": 0.0187654,
           "theta0": 0.3}
    fast = parameter_map(prob._index, prob.p0, val, prob.fixed["mu_slot"], prob._ratios, prob._follow)
    general = parameter_map(prob._index, ca.DM(prob.p0), val, prob.fixed["mu_slot"], prob._ratios,
                            prob._follow)
    assert isinstance(fast, np.ndarray) and fast.shape == (prob.p0.size, 1)
    np.testing.assert_array_equal(fast, np.asarray(general, dtype=float))
    assert not np.array_equal(fast.ravel(), prob.p0)  # the values went in


def test_the_angle_without_ripple_is_the_ripple_formula_at_zero_bit_for_bit():
    prob = _problem(["mu", "theta0", "speed"], initial={"theta0": 0.77})
    x = prob.x0
    theta, J = prob.angle_and_jacobian(x)
    d = prob._values(x)
    thn = d["theta0"] + d["speed"] * (prob.tau - d["delay"])
    ref, g, _ = ripple_motion(thn, d["theta0"], 1.0, 0.0, 0.0, prob.ripple_order)
    np.testing.assert_array_equal(theta, ref)
    np.testing.assert_array_equal(J[:, 1], g - 0.0 * np.cos(0.77) + 0.0 * np.sin(0.77))
    np.testing.assert_array_equal(J[:, 2], (prob.tau - d["delay"]) * g)


def test_drive_tangents_without_a_fitted_ripple_are_the_general_columns_bit_for_bit():
    n, rng = 500, np.random.default_rng(1)
    tau, g, gd = np.arange(n) / 1e4, 1 + 0.01 * rng.random(n), 0.1 * rng.standard_normal(n)
    zs = (0.4, 150.0, 1e-5, 0.0, 0.0, 0.0)
    seeds = np.zeros((6, 3))
    seeds[0, 0] = seeds[1, 1] = seeds[2, 2] = 1.0  # theta0, speed, delay: no ripple seed
    with_ripple = np.column_stack([seeds, np.eye(6)[:, 4]])  # a ripple column: the general path
    fast = drive_tangents(tau, zs, 3, g, gd, seeds)
    general = drive_tangents(tau, zs, 3, g, gd, with_ripple)
    for a, b in zip(fast, general):
        assert a.shape == (n, 3)
        np.testing.assert_array_equal(a, b[:, :3])
