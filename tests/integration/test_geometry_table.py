"""The pump-down's cell geometry from a table over one revolution (pneumatics.geometry_table):
the table against the compiled geometry at random angles, the tabulated right-hand side and
Jacobian against the exact kernels, and the pump-down's figures with the table against the exact
kernel, on a circular housing, an ellipse with a harmonic, and the reed valve."""
import numpy as np
import pytest

from pumpsim.kernels.pneumatic import kernels, parameter_vector
from pumpsim.pneumatics import geometry_table as gt
from pumpsim.pneumatics import pumpdown as pdm
from pumpsim.pneumatics import run
from tests.pneumatic_helpers import evp_config, speed_config
from tests.tolerances import TABLE_EVENT_ABS, TABLE_FIGURE_REL, TABLE_KERNEL_REL, TABLE_SLOPE_REL

ELLIPSE = {"housing.shape": "ellipse", "housing.radius": None, "housing.a": 0.0226, "housing.b": 0.0223,
           "housing.harmonics": [[3, 3e-5, 0.2]]}
REED = {"valve.type": "reed", "valve.area": None, "valve.cracking": None, "valve.full_open": None,
        "valve.mass": 2e-4, "valve.stiffness": 300.0, "valve.damping": 0.01, "valve.preload": 0.05,
        "valve.lift_max": 4e-4, "valve.diameter": 0.005}
HOUSINGS = {"circle": {}, "ellipse_harmonic": ELLIPSE}


@pytest.mark.parametrize("housing", list(HOUSINGS))
def test_table_matches_the_compiled_geometry_at_random_angles(housing):
    cfg = evp_config(**HOUSINGS[housing])
    kern, p = kernels(cfg), parameter_vector(cfg)
    tab = gt.build(kern, p)
    assert tab.max_error <= gt.TABLE_TOL
    theta = np.random.default_rng(7).uniform(-40.0, 40.0, 5000)
    g, dg = gt.exact(kern, p, theta)
    gi, dgi = tab(theta)
    assert np.max(np.abs(gi - g) / tab.scale) <= gt.TABLE_TOL
    slope_size = np.abs(tab.slopes).max(axis=0)
    slope_scale = np.maximum(slope_size, gt.NOISE * slope_size.max())  # as the values' (gt.build)
    assert np.max(np.abs(dgi - dg) / slope_scale) <= TABLE_SLOPE_REL
    # one turn on: the same geometry (alpha is tabulated as its periodic offset)
    g2, _ = gt.exact(kern, p, theta + 2 * np.pi)
    assert np.max(np.abs(g2 - g) / tab.scale) <= gt.TABLE_TOL


def test_tabulated_kernels_equal_the_exact_ones_with_the_exact_geometry():
    cfg = evp_config(**ELLIPSE)
    kern, p = kernels(cfg), parameter_vector(cfg)
    states = run.integrate(cfg, 0.005, 2000.0).states
    rng = np.random.default_rng(3)
    for x in states:
        x = x.copy()
        x[0] = rng.uniform(-30.0, 30.0)
        g, dg = kern["geometry_table"](x[0], p)
        f = np.concatenate([np.asarray(v).ravel() for v in kern["pump_rhs"](x, p)])
        ft = np.concatenate([np.asarray(v).ravel() for v in kern["pump_rhs_tab"](x, g, p)])
        assert np.max(np.abs(ft - f) / np.maximum(np.abs(f), 1e-12)) <= TABLE_KERNEL_REL
        J = np.asarray(kern["pump_rhs_jac"](x, p)[0])
        Jt = np.asarray(kern["pump_rhs_tab_jac"](x, g, dg, p)[0])
        assert np.max(np.abs(Jt - J) / np.maximum(np.abs(J).max(axis=0), 1e-300)) <= TABLE_KERNEL_REL


def _pumpdown(cfg, monkeypatch, geometry):
    monkeypatch.setenv(gt.ENV, geometry)
    r = pdm.pumpdown(cfg, until=95000.0, rtol=1e-8, atol=1e-9)
    return r.summary


@pytest.mark.parametrize("housing", list(HOUSINGS))
def test_pumpdown_figures_with_the_table_match_the_exact_kernel(housing, monkeypatch):
    cfg = evp_config(**HOUSINGS[housing])
    exact, table = _pumpdown(cfg, monkeypatch, "exact"), _pumpdown(cfg, monkeypatch, "table")
    assert exact["solver"]["geometry"] == "exact"
    assert table["solver"]["geometry"] == ("table" if table["solver"]["driver"] == "cvodes (direct)" else "exact")
    for name in ("time_to_target", "energy", "mean_current", "peak_current"):
        assert table[name] == pytest.approx(exact[name], rel=TABLE_FIGURE_REL), name
    # the table's slope feeds the Jacobian: a wrong one would cost Newton failures and steps
    # (measured within 0.3 % of the exact run's steps and Jacobians)
    for name in ("nsteps", "njevals", "nncfails"):
        assert table["solver"][name] <= 1.03 * exact["solver"][name] + 10, name


def test_reed_valve_events_and_states_with_the_table_match_the_exact_kernel(monkeypatch):
    cfg = speed_config(300.0, **REED)
    out = {}
    for geometry in ("exact", "table"):
        monkeypatch.setenv(gt.ENV, geometry)
        out[geometry] = run.integrate(cfg, 0.03, 20000, rtol=1e-8, atol=1e-10)
    a, b = out["exact"], out["table"]
    assert [e["kind"] for e in a.events] == [e["kind"] for e in b.events] and a.events
    for ea, eb in zip(a.events, b.events):
        assert eb["time"] == pytest.approx(ea["time"], abs=TABLE_EVENT_ABS)
    scale = np.abs(a.states).max(axis=0)
    scale[scale == 0] = 1.0
    assert np.max(np.abs(b.states - a.states) / scale) <= TABLE_FIGURE_REL
    assert b.quad[-1, 0] == pytest.approx(a.quad[-1, 0], rel=TABLE_FIGURE_REL)


def test_exact_geometry_stays_available(monkeypatch):
    cfg = evp_config()
    kern, p = kernels(cfg), parameter_vector(cfg)
    monkeypatch.setenv(gt.ENV, "exact")
    assert run.PumpIntegrator(kern, p).driver_geometry == "exact"
    monkeypatch.delenv(gt.ENV)
    integ = run.PumpIntegrator(kern, p)
    assert integ.driver_geometry == ("table" if integ.direct is not None else "exact")
    assert run.PumpIntegrator(kern, p, geometry_table=False).driver_geometry == "exact"


def test_a_geometry_the_table_cannot_resolve_runs_on_the_exact_one(monkeypatch):
    # a flat vane tip (vane.tip_radius = 0): the housing contact jumps from one tip corner to the
    # other, which no Hermite table follows; the run takes the exact geometry instead of failing
    cfg = evp_config(**{"vane.tip_radius": 0.0})
    kern, p = kernels(cfg), parameter_vector(cfg)
    with pytest.raises(gt.SolverError, match="does not converge"):
        gt.build(kern, p)
    with pytest.raises(gt.SolverError, match="does not converge"):  # remembered, not rebuilt
        gt.build(kern, p)
    assert run.PumpIntegrator(kern, p).driver_geometry == "exact"
    monkeypatch.setenv(gt.ENV, "exact")
    exact = pdm.pumpdown(cfg, duration=0.05).summary
    monkeypatch.delenv(gt.ENV)
    fallback = pdm.pumpdown(cfg, duration=0.05).summary
    assert fallback["final_pressure"] == exact["final_pressure"] and fallback["energy"] == exact["energy"]
