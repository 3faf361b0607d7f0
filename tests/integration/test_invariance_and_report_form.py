"""Invariance under turning the housing, and the report's linear system as a cross-check."""
import math

import numpy as np

from pumpsim.kernels import inverse_dynamics
from tests.conftest import kernel_and_p, make_config, one_revolution
from tests.tolerances import (CONSTRAINT_ABS, DRIVE_ROW_REL, REPORT_FORM_REL,
                              ROTATION_INVARIANCE_REL, SDDOT_FLOOR_ABS)

BASE = {"housing.center": [0.0004, 0.0002], "housing.harmonics": [[3, 3e-5, 0.3]],
        "rotor.slot_tilt": 0.1}


def _torque(delta_housing, delta_slots, theta):
    c = BASE["housing.center"]
    cr = [c[0] * math.cos(delta_housing) - c[1] * math.sin(delta_housing),
          c[0] * math.sin(delta_housing) + c[1] * math.cos(delta_housing)]
    cfg = make_config("ellipse_4vanes", **{**BASE, "housing.center": cr,
                                           "housing.angle": delta_housing,
                                           "rotor.first_slot_angle": delta_slots})
    kern, p, _ = kernel_and_p(cfg)
    return inverse_dynamics(kern, p, theta, cfg.speed, 0.0)["torque"]


def test_turning_housing_and_slots_together_only_shifts_the_torque_in_angle():
    theta = one_revolution(360)
    ref = _torque(0.0, 0.0, theta)
    d = 0.7
    both = _torque(d, d, theta)  # the whole pump turned: same torque at the same rotor angle
    np.testing.assert_allclose(both, ref, rtol=ROTATION_INVARIANCE_REL, atol=0)
    housing_only = _torque(d, 0.0, theta + d)  # housing turned: the torque shifts by d
    np.testing.assert_allclose(housing_only, ref, rtol=ROTATION_INVARIANCE_REL, atol=0)


def test_report_linear_system_reproduces_the_fast_kernel():
    cfg = make_config("ellipse_4vanes", **BASE)
    kern, p, _ = kernel_and_p(cfg)
    N = cfg.vanes
    rng = np.random.default_rng(1)
    for th in rng.uniform(0, 2 * math.pi, 5):
        wd = rng.normal() * 1e3
        o = inverse_dynamics(kern, p, [th], cfg.speed, wd)
        q = np.concatenate([[th], o["s"][:, 0], o["alpha"][:, 0]])
        qd = np.concatenate([[cfg.speed], o["sdot"][:, 0], o["alphadot"][:, 0]])
        sig = np.ravel(np.column_stack([np.sign(o["slot1"][:, 0]), np.sign(o["slot2"][:, 0])]))
        K, rhs = kern["dynamic_system"](q, qd, sig, wd, p)
        x = np.linalg.solve(np.asarray(K), np.asarray(rhs).ravel())
        # unknowns: qdd (theta, s_i, alpha_i), eps (N_i, F1_i, F2_i), tau
        np.testing.assert_allclose(x[0], wd, rtol=DRIVE_ROW_REL)
        np.testing.assert_allclose(x[1:1 + N], o["sddot"][:, 0], rtol=REPORT_FORM_REL, atol=SDDOT_FLOOR_ABS)
        eps = x[1 + 2 * N:1 + 5 * N].reshape(N, 3)
        for col, name in enumerate(("normal", "slot1", "slot2")):
            np.testing.assert_allclose(eps[:, col], o[name][:, 0], rtol=REPORT_FORM_REL)
        np.testing.assert_allclose(x[-1], o["torque"][0], rtol=REPORT_FORM_REL)
        # Phi(q) = 0 at the solved positions
        assert np.max(np.abs(np.asarray(kern["constraint"](q, p)))) < CONSTRAINT_ABS
