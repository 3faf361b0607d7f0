"""The reed exhaust valve (spec §8): it opens when the port pressure exceeds atmosphere plus its
preload, at the located event time, and its stop is an event: the lift never exceeds x_max."""
import numpy as np
import pytest

from pumpsim.pneumatics import run
from pumpsim.kernels.pneumatic import kernels, parameter_vector
from tests.pneumatic_helpers import speed_config
from tests.tolerances import REED_FORCE_REL, REED_STOP_REL

REED = {"valve.type": "reed", "valve.area": None, "valve.cracking": None, "valve.full_open": None,
        "valve.mass": 2e-4, "valve.stiffness": 300.0, "valve.damping": 0.01, "valve.preload": 0.05,
        "valve.lift_max": 4e-4, "valve.diameter": 0.005}


def test_reed_opens_at_atmosphere_plus_preload_and_never_passes_its_stop():
    cfg = speed_config(300.0, **REED)
    k, p = kernels(cfg), parameter_vector(cfg)
    r = run.integrate(cfg, 0.06, 20000, p=p, rtol=1e-8, atol=1e-10)
    kinds = [e["kind"] for e in r.events]
    assert "reed_opens" in kinds and "reed_stop" in kinds
    lift = r.states[:, -2]
    assert lift.max() <= 4e-4 * (1 + REED_STOP_REL) and lift.min() >= 0.0
    if "reed_stop" in kinds:
        assert lift.max() == pytest.approx(4e-4, rel=REED_STOP_REL)
    # at each located opening the net opening force (p_ex - p_atm) A - preload is zero: re-integrate
    # from the output sample before it (seated) to the event time
    integ = run.PumpIntegrator(k, p, 1e-10, 1e-12, run.state_scale(r.states[0], p, k.structure))
    area = np.pi * 0.005**2 / 4
    for e in [e for e in r.events if e["kind"] == "reed_opens"][:3]:
        j = int(np.searchsorted(r.time, e["time"])) - 1
        x_e, _ = integ.step(r.states[j], 1.0, e["time"] - r.time[j])
        o = run.evaluate_outputs(k, x_e[None, :], p, ["reed_force", "exhaust_pressure"])
        assert abs(o["reed_force"][0]) < REED_FORCE_REL * 0.05
        # the same located zero read as a pressure: the force's tolerance over the valve's area
        assert o["exhaust_pressure"][0] == pytest.approx(101325.0 + 0.05 / area, abs=REED_FORCE_REL * 0.05 / area)
