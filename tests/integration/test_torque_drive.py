"""Torque drive of the constrained model: energy conservation and dissipation."""
import dataclasses
import math

import numpy as np

import pumpsim
from tests.conftest import make_config
from tests.tolerances import (ENERGY_REL, ENERGY_RTOL, FORWARD_INVERSE_REL, FORWARD_INVERSE_RTOL,
                              FRICTION_ENERGY_KEPT_MAX, GRADIENT_FLOOR, GRADIENT_REL, MONOTONE_ENERGY_REL,
                              MONOTONE_ENERGY_RTOL, POSITION_ATOL, REVOLUTIONS_SHARE, VANE_ENERGY_SWING_MIN)


def total_kinetic_energy(res):
    return 0.5 * res.parameters["rotor.inertia"] * res.speed**2 + res.extra["kinetic_energy"].sum(0)


def spinning(cfg, omega0, torque=0.0):
    return dataclasses.replace(cfg, mode="torque", torque=torque, speed=omega0, angle=0.3)


def test_frictionless_energy_is_conserved_over_100_revolutions():
    zero = {f"friction.housing.{k}": 0.0 for k in ("static", "dynamic")}
    cfg = spinning(make_config("ellipse_4vanes", **zero), omega0=300.0)
    duration = 100 * 2 * math.pi / 300.0
    res = pumpsim.simulate(cfg, duration=duration, rate=200.0, rtol=ENERGY_RTOL, atol=POSITION_ATOL)
    assert res.angle[-1] - res.angle[0] > 100 * 2 * math.pi * REVOLUTIONS_SHARE
    ke = total_kinetic_energy(res)
    # the vanes really exchange energy with the rotor: each vane's energy swings by > 1 %
    vane_ke = res.extra["kinetic_energy"]
    assert np.all(np.ptp(vane_ke, axis=1) > VANE_ENERGY_SWING_MIN * vane_ke.mean(axis=1))
    assert np.max(np.abs(ke - ke[0])) <= ENERGY_REL * ke[0]


def test_with_friction_and_no_torque_energy_only_decreases():
    cfg = spinning(make_config("ellipse_4vanes"), omega0=200.0)
    res = pumpsim.simulate(cfg, duration=0.05, rate=4000.0, rtol=MONOTONE_ENERGY_RTOL, atol=POSITION_ATOL)
    ke = total_kinetic_energy(res)
    assert ke[-1] < FRICTION_ENERGY_KEPT_MAX * ke[0]
    assert np.all(np.diff(ke) <= MONOTONE_ENERGY_REL * ke[0])
    assert res.stats["nsteps"] > 0 and "integrator_calls" in res.stats


def test_torque_drive_matches_inverse_dynamics():
    """Forward and inverse dynamics are each other's inverse: the torque needed for the integrated
    motion (from the inverse kernel at the integrated omegadot) equals the applied torque."""
    cfg = spinning(make_config("ellipse_4vanes"), omega0=150.0, torque=0.05)
    res = pumpsim.simulate(cfg, duration=0.02, rate=2000.0, rtol=FORWARD_INVERSE_RTOL, atol=POSITION_ATOL)
    from pumpsim.kernels import evaluate, inverse_dynamics
    from tests.conftest import kernel_and_p

    kern, p, _ = kernel_and_p(cfg)
    fwd = evaluate(kern, "forward_dynamics", [res.angle, res.speed, res.torque], p, res.time.size)
    inv = inverse_dynamics(kern, p, res.angle, res.speed, fwd["omegadot"])
    np.testing.assert_allclose(inv["torque"], 0.05, rtol=FORWARD_INVERSE_REL)
    # and omegadot is the derivative of the integrated speed
    dw = np.gradient(res.speed, res.time)
    np.testing.assert_allclose(dw[2:-2], fwd["omegadot"][2:-2], rtol=GRADIENT_REL, atol=GRADIENT_FLOOR * np.abs(dw).max())
