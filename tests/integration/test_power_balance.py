"""Spec §4 power balance at constant speed, and zero mean torque without friction."""
import numpy as np
import pytest

from pumpsim.model_spec import laws
from pumpsim.model_spec.parameters import friction_args
from pumpsim.kernels import inverse_dynamics
from tests.conftest import kernel_and_p, make_config, one_revolution
from tests.tolerances import POWER_BALANCE_REL, ZERO_MEAN_TORQUE_REL

CASES = {
    "ellipse": dict(base="ellipse_4vanes"),
    "eccentric-out-of-round-tilted": dict(base="test_rig", **{
        "housing.center": [0.0004, -0.0003], "housing.harmonics": [[3, 4e-5, 0.2], [5, 2e-5, 1.0]],
        "rotor.slot_tilt": 0.15, "rotor.slot_radius": 0.008, "vane.length": 0.0125}),
    "tip-radius-viscous": dict(base="ellipse_4vanes", **{
        "vane.tip_radius": 0.0015, "effects.viscous_tip_friction": 0.01, "housing.angle": 0.4}),
}


def friction_power(out, v):
    """sum_i mu_h N |v_t| + c v_t^2 + mu_r (|F1| + |F2|) |sdot|, with mu from the spec's law."""
    fh, fs = friction_args(v, "housing"), friction_args(v, "slot")
    mu_h = laws.friction_coefficient(out["tip_slip"], *fh)
    mu_r = laws.friction_coefficient(out["sdot"], *fs)
    return (np.abs(mu_h) * out["normal"] * np.abs(out["tip_slip"])
            + v["effects.viscous_tip_friction"] * out["tip_slip"] ** 2
            + np.abs(mu_r) * (np.abs(out["slot1"]) + np.abs(out["slot2"])) * np.abs(out["sdot"])).sum(0)


@pytest.mark.parametrize("case", list(CASES))
def test_mean_drive_power_equals_friction_power(case):
    kw = dict(CASES[case])
    cfg = make_config(kw.pop("base"), **kw)
    kern, p, pv = kernel_and_p(cfg)
    out = inverse_dynamics(kern, p, one_revolution(4096), cfg.speed, 0.0)
    assert np.all(out["normal"] > 0)
    drive = (out["torque"] * cfg.speed).mean()
    fric = friction_power(out, pv.values).mean()
    assert drive > 0
    assert abs(drive - fric) <= POWER_BALANCE_REL * fric


@pytest.mark.parametrize("case", list(CASES))
def test_frictionless_mean_torque_is_zero(case):
    kw = dict(CASES[case])
    zero = {f"friction.housing.{k}": 0.0 for k in ("static", "dynamic")}
    zero["effects.viscous_tip_friction"] = 0.0
    cfg = make_config(kw.pop("base"), **{**kw, **zero})
    kern, p, _ = kernel_and_p(cfg)
    out = inverse_dynamics(kern, p, one_revolution(4096), cfg.speed, 0.0)
    tq = out["torque"]
    rms = np.sqrt(np.mean(tq**2))
    assert rms > 0
    assert abs(tq.mean()) <= ZERO_MEAN_TORQUE_REL * rms
