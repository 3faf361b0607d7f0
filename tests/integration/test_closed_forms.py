"""Spec §4 closed forms."""
import math

import numpy as np
import pytest

from pumpsim.kernels import inverse_dynamics
from tests.conftest import kernel_and_p, make_config, one_revolution
from tests.tolerances import CLOSED_FORM_REL


@pytest.mark.parametrize("vanes,tip_radius", [(4, 0.0), (1, 0.0), (3, 0.001)])
def test_concentric_circle_torque(vanes, tip_radius):
    cfg = make_config(**{"rotor.vanes": vanes, "vane.tip_radius": tip_radius})
    kern, p, pv = kernel_and_p(cfg)
    v = pv.values
    w, R, L, m, rb = cfg.speed, v["housing.a"], v["vane.length"], v["vane.mass"], v["rotor.slot_radius"]
    out = inverse_dynamics(kern, p, one_revolution(64), w, 0.0)
    expected = vanes * v["friction.housing.dynamic"] * m * w**2 * (R - L / 2) * R
    np.testing.assert_allclose(out["torque"], expected, rtol=CLOSED_FORM_REL)
    np.testing.assert_allclose(out["s"], R - L - rb, rtol=CLOSED_FORM_REL)


@pytest.mark.parametrize("e,direction", [(0.0008, 0.0), (0.0011, 2.1)])
def test_eccentric_circle_vane_extension(e, direction):
    cfg = make_config(**{"housing.center": [e * math.cos(direction), e * math.sin(direction)],
                         "rotor.slot_radius": 0.009, "rotor.first_slot_angle": 0.3})
    kern, p, pv = kernel_and_p(cfg)
    v = pv.values
    R, L, rb = v["housing.a"], v["vane.length"], v["rotor.slot_radius"]
    theta = one_revolution(256)
    out = inverse_dynamics(kern, p, theta, cfg.speed, 0.0)
    for i in range(cfg.vanes):
        th = theta + 0.3 + 2 * math.pi * i / cfg.vanes - direction
        r = e * np.cos(th) + np.sqrt(R**2 - e**2 * np.sin(th) ** 2)
        np.testing.assert_allclose(out["s"][i], r - L - rb, rtol=CLOSED_FORM_REL)
