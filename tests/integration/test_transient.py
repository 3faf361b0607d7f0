"""Identification on a transient (torque-driven run) with CVODES forward sensitivities."""
import numpy as np
import pytest

from pumpsim.data import Dataset
from pumpsim.errors import DataError
from pumpsim.identification import TransientProblem, identify_transient
from tests.conftest import transient_start_config as start_config
from tests.tolerances import (SENSITIVITY_ATOL, SENSITIVITY_REL, SENSITIVITY_RTOL, SENSITIVITY_THETA0_REL,
                              TRANSIENT_MU_REL, TRANSIENT_SPEED0_ABS)


@pytest.fixture
def run(transient_run):
    return transient_run


def test_transient_fit_recovers_cof(run):
    ds = Dataset(run.time, run.torque, run.speed + np.random.default_rng(0).normal(0, 0.01, run.time.size))
    res = identify_transient(start_config(), ds, ["mu", "speed0", "theta0"], initial={"theta0": 0.25})
    assert res.converged
    assert res.value("mu") == pytest.approx(0.17, rel=TRANSIENT_MU_REL)
    assert abs(res.value("speed0") - 150.0) < TRANSIENT_SPEED0_ABS
    assert res.diagnostics["white_at_5pct"]
    # its residual is the speed's: labelled by that channel, not as a torque
    assert str(res).splitlines()[0].endswith(f"residual RMS {res.rms:.6g} rad/s") and "N m" not in repr(res)
    assert res.to_json()["rms_unit"] == "rad/s"


def test_a_transient_fit_refuses_samples_interpolated_across_a_gap(run):
    measured = np.ones(run.time.size, bool)
    measured[10:15] = False  # resampling drew a straight line there: it would drive the model
    ds = Dataset(run.time, run.torque, run.speed, measured=measured)
    with pytest.raises(DataError, match="cannot leave out a gap in time.*cut the record"):
        TransientProblem(start_config(), ds, ["mu"])


def test_sensitivities_match_finite_differences_in_four_directions(run):
    """casadi issue 4383: CVODES Jacobians went wrong with three or more parameter directions."""
    prob = TransientProblem(start_config(), Dataset(run.time, run.torque, run.speed),
                            ["mu", "speed0", "theta0", "vane.mass"], initial={"theta0": 0.2}, rtol=SENSITIVITY_RTOL,
                            atol=SENSITIVITY_ATOL)
    x = prob.x0
    _, J = prob.model_and_jacobian(x)
    # FD step well above the integration error (1e-12 x 150 rad/s) and below the curvature scale
    for j, name in enumerate(prob.names):
        h = 1e-4 * max(abs(x[j]), 1e-2)
        e = np.zeros_like(x)
        e[j] = h
        fd = (prob.model(x + e) - prob.model(x - e)) / (2 * h)
        tol = SENSITIVITY_THETA0_REL if name == "theta0" else SENSITIVITY_REL
        assert np.max(np.abs(J[:, j] - fd)) <= tol * np.abs(fd).max(), name


def test_transient_needs_speed_and_uniform_time(run):
    with pytest.raises(DataError, match="needs a measured speed column"):
        TransientProblem(start_config(), Dataset(run.time, run.torque), ["mu"])
    t = run.time.copy()
    t[5] += 1e-5
    with pytest.raises(DataError, match="uniformly sampled"):
        TransientProblem(start_config(), Dataset(t, run.torque, run.speed), ["mu"])
