"""The gas model's openings and geometry against closed forms (spec §8): every opening's discharge
coefficient, the end-face leak length near top dead centre, the located peak current."""
import math

import numpy as np
import pytest

from pumpsim.pneumatics import pumpdown as pdm
from pumpsim.pneumatics import run
from pumpsim.kernels.pneumatic import kernels, parameter_vector
from tests.integration.test_gas_dynamics import textbook_flow
from tests.pneumatic_helpers import evp_config, speed_config
from tests.tolerances import (CLOSED_FORM_REL, HOSE_TIME_CONSTANT_REL, ORIFICE_REL,
                              PEAK_CURRENT_REL)

R_AIR, T0 = 287.05, 293.15


def _state(k, p, cfg, cells, p_in, p_ex, p_b, theta=0.5):
    """A state at rest temperature with the given cell, manifold, exhaust-port and booster pressures."""
    v = dict(zip([q for q in run._names(k.structure)], p))
    V = np.asarray(k["cell_geometry"](theta, p)[0]).ravel()
    RT = R_AIR * T0
    return np.concatenate([[theta, 300.0, 0.0], cells * V / RT, cells * V / (v["gas.gamma"] - 1),
                           [p_in * v["ports.inlet_volume"] / RT, p_ex * v["ports.exhaust_volume"] / RT,
                            p_b * v["booster.volume"] / RT, p_in * v["ports.inlet_volume"] / (v["gas.gamma"] - 1),
                            p_ex * v["ports.exhaust_volume"] / (v["gas.gamma"] - 1), 0.0, 0.0]])


def _flows(cfg, X, **over):
    k = kernels(cfg)
    p = parameter_vector(cfg, **over)
    return run.evaluate_outputs(k, X[None, :], p), p


FLOWS = ("hose_flow", "valve_flow", "inlet_flow", "exhaust_flow", "leak_flow")


@pytest.mark.parametrize("key,outputs", [
    ("ports.hose_discharge_coefficient", ("hose_flow",)),
    ("valve.discharge_coefficient", ("valve_flow",)),
    ("ports.discharge_coefficient", ("inlet_flow", "exhaust_flow")),
    ("leak.discharge_coefficient", ("leak_flow",)),
])
def test_each_opening_flows_with_its_own_discharge_coefficient(key, outputs):
    """Every opening is the orifice law through C_d x its area: the hose (check valve fully open,
    so the hose orifice controls) and the exhaust check valve (fully open) against the textbook
    law at C_d A, and each opening's flow scales linearly with its own C_d and with no other."""
    cfg = speed_config()
    k = kernels(cfg)
    p = parameter_vector(cfg)
    cells = np.array([3e4, 6e4, 1.6e5, 1.2e5])
    X = _state(k, p, cfg, cells, p_in=2e4, p_ex=1.3e5, p_b=8e4)
    base, _ = _flows(cfg, X)
    half, _ = _flows(cfg, X, **{key.replace(".", "__"): 0.35})
    for o in FLOWS:
        a, b = np.atleast_1d(base[o]).ravel(), np.atleast_1d(half[o]).ravel()
        if o in outputs:
            assert np.any(np.abs(a) > 0), o  # the opening carries flow in this state
            np.testing.assert_allclose(b, 0.5 * a, rtol=ORIFICE_REL, err_msg=o)
        else:  # the other openings do not move
            np.testing.assert_allclose(b, a, rtol=ORIFICE_REL, err_msg=o)
    a = np.atleast_1d(base[outputs[0]]).ravel()
    v = cfg.pneumatic.values
    if key == "ports.hose_discharge_coefficient":  # 6e4 Pa across: the check valve (full at 1.5 kPa) is wide open
        expected = textbook_flow(8e4, T0, 2e4, 0.7 * v["ports.hose_area"])
        assert a[0] == pytest.approx(expected, rel=ORIFICE_REL)
    if key == "valve.discharge_coefficient":  # 28.7 kPa over the atmosphere: past full_open (7 kPa)
        expected = textbook_flow(1.3e5, T0, v["gas.atmosphere"], 0.7 * v["valve.area"])
        assert a[0] == pytest.approx(expected, rel=ORIFICE_REL)


def test_a_partly_open_check_valve_controls_the_hose_path():
    """Below full lift the check valve's effective area C_d,check x lift x A_hose is the smaller
    one: the hose flow follows the check valve's C_d, not the hose's."""
    cfg = speed_config()
    k, p = kernels(cfg), parameter_vector(cfg)
    # 750 Pa across: cracking 500 + full_open 1000 -> lift 0.25
    X = _state(k, p, cfg, np.full(4, 5e4), p_in=7.925e4, p_ex=1e5, p_b=8e4)
    base, _ = _flows(cfg, X)
    hose, _ = _flows(cfg, X, ports__hose_discharge_coefficient=0.35)
    check, _ = _flows(cfg, X, ports__check_discharge_coefficient=0.35)
    expected = textbook_flow(8e4, T0, 7.925e4, 0.7 * 0.25 * cfg.pneumatic.values["ports.hose_area"])
    assert base["hose_flow"][0] == pytest.approx(expected, rel=ORIFICE_REL)
    assert hose["hose_flow"][0] == pytest.approx(base["hose_flow"][0], rel=ORIFICE_REL)
    assert check["hose_flow"][0] == pytest.approx(0.5 * base["hose_flow"][0], rel=ORIFICE_REL)


def _hose_time_constant(cd):
    """A small booster behind a 1 mm hose, pumped at constant speed: the hose chokes (the pump
    holds the manifold below 0.2 of the booster), so p_b = p0 exp(-t / tau) with
    tau = V_b / (C_d A sqrt(g R T) (2/(g+1))^((g+1)/(2(g-1)))). Returns (measured tau, law's tau)."""
    V_b, d = 2.0e-5, 1.0e-3
    cfg = speed_config(400.0, **{"booster.volume": V_b, "booster.leak": 0.0, "ports.hose_diameter": d,
                                 "ports.hose_discharge_coefficient": cd})
    g = 1.4
    A = math.pi * d * d / 4
    tau = V_b / (cd * A * math.sqrt(g * R_AIR * T0) * (2 / (g + 1)) ** ((g + 1) / (2 * (g - 1))))
    p0 = cfg.pneumatic.booster_start
    p1, p2 = 0.8 * p0, 0.5 * p0  # past the start transient (cells and manifold at the atmosphere)
    r = run.integrate(cfg, 3 * tau, 2000, until=p2, rtol=1e-6, atol=1e-8)
    pb = r.outputs["booster_pressure"]
    j = int(np.argmax(pb <= p1))
    t1 = np.interp(math.log(p1), np.log([pb[j], pb[j - 1]]), [r.time[j], r.time[j - 1]])
    assert np.max(r.outputs["inlet_pressure"][j:] / pb[j:]) < 0.5  # choked all along
    return (r.time_to_target - t1) / math.log(p1 / p2), tau


def test_halving_the_hose_discharge_coefficient_doubles_the_time_constant():
    tau_full, law_full = _hose_time_constant(0.7)
    tau_half, law_half = _hose_time_constant(0.35)
    assert tau_full == pytest.approx(law_full, rel=HOSE_TIME_CONSTANT_REL)
    assert tau_half == pytest.approx(law_half, rel=HOSE_TIME_CONSTANT_REL)
    assert tau_half / tau_full == pytest.approx(2.0, rel=HOSE_TIME_CONSTANT_REL)


def _geometry(k, p, theta):
    o = k["cell_geometry"](theta, p)
    return {n: np.asarray(o[i]).ravel() for i, n in enumerate(k["cell_geometry"].name_out())}


def test_end_face_leak_length_is_zero_where_the_flank_is_inside_the_rotor():
    """EVP example (circle housing 22.5 mm about (3 mm, 0), rotor 19 mm, full-round tips
    rho = h/2 = 1.5 mm, radial slots). At top dead centre nothing of the vane reaches past
    R_h - e = 19.5 mm, so the flank's end, rho below the tip, lies within 18 mm < R_r: the flank
    exposes nothing and only the tip cap protrudes. Away from it the exposed length follows from
    the vane's area outside the rotor: a trapezoid h x L (both flanks equal, radial slot) plus the
    half-disc tip, less the rotor circle's segment under the chord h."""
    cfg = evp_config()
    k, p = kernels(cfg), parameter_vector(cfg)
    v = dict(zip(run._names(k.structure), p))
    Rh, e, Rr = v["housing.a"], v["housing.center.0"], v["rotor.radius"]
    h, rho, W = v["vane.thickness"], v["vane.tip_radius"], v["rotor.width"]
    assert Rh - e - rho < Rr and rho == h / 2  # the precondition read from the config
    theta = np.linspace(0, 2 * math.pi, 145)
    s0 = [_geometry(k, p, t)["s"][0] for t in theta]
    tdc = float(theta[int(np.argmin(s0))])  # vane 0 at top dead centre: its smallest extension
    g = _geometry(k, p, tdc)
    assert g["exposed"][0] == 0.0
    segment = 0.5 * Rr * Rr * (2 * math.asin(h / (2 * Rr)) - math.sin(2 * math.asin(h / (2 * Rr))))
    outside = 0
    for t in theta:
        g = _geometry(k, p, t)
        assert np.all(g["exposed"] >= 0.0)
        for i in np.nonzero(g["exposed"] > 1e-5)[0]:  # flanks clearly outside the rotor
            area = g["vane_volume"][i] / W
            L = (area - math.pi * rho * rho / 2 + segment) / h
            assert g["exposed"][i] == pytest.approx(L, rel=CLOSED_FORM_REL)
            outside += 1
    assert outside > 0.7 * 4 * theta.size  # most vane positions were checked
    # the wall area beside it: sum over cells = both end faces of every cell + the housing circle
    # + the rotor circle less what the vanes cover of it + both exposed flanks of every vane. A
    # vane with its flank out covers the chord h; a retracted one the chord between the points
    # where its cap circle (centre rb + s + L - rho out along the radial slot) crosses the rotor
    # circle: the cells are bounded by the rotor circle, the slot mouth beside the cap is no cell's
    rb, L = v["rotor.slot_radius"], v["vane.length"]
    for t in (tdc, tdc + 0.3, tdc + 1.2):
        g = _geometry(k, p, t)
        d = rb + g["s"] + L - rho
        a = (Rr * Rr - rho * rho + d * d) / (2 * d)
        half = np.where(g["exposed"] > 0, h / 2, np.sqrt(np.maximum(Rr * Rr - a * a, 0.0)))
        rotor = 2 * math.pi * Rr - Rr * 2 * np.arcsin(half / Rr).sum()
        total = 2 * g["volume"].sum() / W + W * (2 * math.pi * Rh + rotor + 2 * g["exposed"].sum())
        assert g["wall_area"].sum() == pytest.approx(total, rel=CLOSED_FORM_REL)


def test_peak_current_is_located_between_samples():
    """The motor's inrush peak (L/R = 0.4 ms) at the default 2 kHz output against a run sampled
    every 2.5 us: the located peak agrees with the fine run's largest sample, which the coarse
    largest sample does not. (Tight tolerances: at the pump-down's default rtol 1e-4 the two runs'
    integration errors on the peak differ by ~2e-4 themselves.)"""
    cfg = evp_config()
    coarse = pdm.pumpdown(cfg, duration=0.004, rtol=1e-7, atol=1e-9)
    fine = pdm.pumpdown(cfg, duration=0.004, rate=4e5, rtol=1e-7, atol=1e-9)
    fine_peak = float(np.max(np.abs(fine.columns["current"])))
    sampled = float(np.max(np.abs(coarse.columns["current"])))
    assert coarse.summary["peak_current"] == pytest.approx(fine_peak, rel=PEAK_CURRENT_REL)
    assert abs(sampled - fine_peak) > 5 * PEAK_CURRENT_REL * fine_peak  # the test can tell
    assert fine.summary["peak_current"] == pytest.approx(fine_peak, rel=PEAK_CURRENT_REL)
    # an output every 0.1 s: the inrush lies inside the first interval, its largest sample is not

    sparse = pdm.pumpdown(cfg, duration=0.5, rate=10.0, rtol=1e-7, atol=1e-9)
    assert sparse.summary["peak_current"] == pytest.approx(fine_peak, rel=PEAK_CURRENT_REL)
