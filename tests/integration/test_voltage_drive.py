"""Voltage-driven pump-down runs (a bench log's measured supply voltage) on the direct CVODES
driver with the tabulated geometry, against CasADi's CVODES plugin on the exact geometry: the
bench-log model's grid runs (identification.bench_sens.DirectRuns) and the runtime's
event-locating integration (pneumatics.run, with a reed valve), on a log whose voltage steps."""
import numpy as np
import pytest

from pumpsim import cvodes_driver
from pumpsim.identification.bench_model import BenchModel
from pumpsim.identification.pumpdown_fit import fit_map, values_vector
from pumpsim.kernels.pneumatic import kernels
from pumpsim.pneumatics import geometry_table as gt
from pumpsim.pneumatics import run
from tests.integration.test_geometry_table import REED
from tests.pneumatic_helpers import evp_config
from tests.tolerances import DRIVE_CHANNEL_REL, FIT_SHIFT_SE, TABLE_EVENT_ABS

pytestmark = pytest.mark.skipif(not cvodes_driver.available()[0], reason="no direct CVODES driver on this machine")

RTOL, ATOL = 1e-8, 1e-9
RATE = 1000.0


def _stepped_log(duration, step_at=0.1005, low=10.0):
    """Times and a 13.5 V supply that dips to `low` within one sample interval at `step_at`."""
    t = np.arange(int(round(duration * RATE)) + 1) / RATE
    return t, np.where(t < step_at, 13.5, low)


def _both_paths(monkeypatch, fn):
    """fn() on the direct driver with the table, then on CasADi's plugin with the exact geometry."""
    monkeypatch.delenv(cvodes_driver.ENV, raising=False)
    monkeypatch.delenv(gt.ENV, raising=False)
    direct = fn()
    monkeypatch.setenv(cvodes_driver.ENV, "casadi")
    monkeypatch.setenv(gt.ENV, "exact")
    return direct, fn()


def _channels(bm, X, p):
    return {"booster_pressure": run.booster_pressure(bm.kern.structure, p)(X), "current": X[:, 2], "speed": X[:, 1]}


def test_a_voltage_step_on_the_direct_driver_with_the_table_matches_casadis_exact_path(monkeypatch):
    """0.3 s from rest with the supply dipping 13.5 -> 10 V at 0.1 s: the log's grid runs and the
    runtime's integration, each path at rtol 1e-8, agree sample by sample on the booster pressure,
    current and speed (DRIVE_CHANNEL_REL of each channel's range)."""
    cfg = evp_config()
    t, volt = _stepped_log(0.3)
    p = values_vector(cfg, {"mu": 0.165})

    def runs():
        bm = BenchModel(cfg, t, volt, 101300.0, rtol=RTOL, atol=ATOL)
        grid = bm.samples(p)
        r = run.integrate(cfg, t[-1] * (1 + 1e-12), RATE, p=p, x0=bm.start_state(p), rtol=RTOL, atol=ATOL,
                          kern=bm.kern, drive=bm.drive)
        return bm, grid, r

    (bm, grid_d, r_d), (_, grid_c, r_c) = _both_paths(monkeypatch, runs)
    assert bm.drive.stops.tolist() == [100, 101]
    assert bm._grid_runs.geometry == "table"
    assert (r_d.stats["driver"], r_d.stats["geometry"]) == ("cvodes (direct)", "table")
    assert r_c.stats["driver"] == "cvodes (casadi)"
    runtime_d, runtime_c = _channels(bm, r_d.states[:t.size], p), _channels(bm, r_c.states[:t.size], p)
    for c in grid_c:
        size = np.ptp(grid_c[c])
        assert np.max(np.abs(grid_d[c] - grid_c[c])) <= DRIVE_CHANNEL_REL * size, c
        assert np.max(np.abs(runtime_d[c] - runtime_c[c])) <= DRIVE_CHANNEL_REL * size, c
        assert np.max(np.abs(runtime_d[c] - grid_d[c])) <= DRIVE_CHANNEL_REL * size, c
    # the step is seen: the speed falls after it (the no-load speed goes 5160 -> 3820 rpm)
    assert grid_d["speed"][200] < grid_d["speed"][100] - 50.0


def test_reed_events_of_a_voltage_driven_run_match_casadis_exact_path(monkeypatch):
    """A reed exhaust valve (events located by re-integration from their interval's start, on the
    drive's own clock) under a stepping supply: the same events and states on both paths."""
    cfg = evp_config(**REED)
    t, volt = _stepped_log(0.04, step_at=0.0205)
    p = values_vector(cfg)

    def runs():
        bm = BenchModel(cfg, t, volt, 101300.0, rtol=RTOL, atol=ATOL)
        return bm, run.integrate(cfg, t[-1] * (1 + 1e-12), RATE, p=p, x0=bm.start_state(p), rtol=RTOL, atol=ATOL,
                                 kern=bm.kern, drive=bm.drive)

    (bm, a), (_, b) = _both_paths(monkeypatch, runs)
    assert a.stats["geometry"] == "table" and b.stats["driver"] == "cvodes (casadi)"
    assert [e["kind"] for e in a.events] == [e["kind"] for e in b.events] and len(a.events) >= 2
    assert max(abs(e["time"] - f["time"]) for e, f in zip(a.events, b.events)) <= TABLE_EVENT_ABS
    ca_, cb = _channels(bm, a.states, p), _channels(bm, b.states, p)
    for c in ca_:
        assert np.max(np.abs(ca_[c] - cb[c])) <= DRIVE_CHANNEL_REL * np.ptp(cb[c]), c


def test_the_sensitivities_keep_the_table_unless_a_direction_moves_the_geometry():
    """The fitted parameters (friction, leaks, valve, motor) leave the geometry bit for bit; a
    geometric one (rotor.radius) does not, and a sensitivity along it runs on the exact kernels."""
    cfg = evp_config()
    index, p, *_ = fit_map(cfg)
    kern = kernels(cfg)
    moved = lambda name, value: values_vector(cfg, {name: value}) - p  # noqa: E731
    fitted = [moved("mu", 0.2)] + [moved(n, 1.1 * p[index[n]]) for n in (
        "booster.leak", "leak.tip_gap", "leak.end_gap", "valve.cracking", "motor.resistance", "motor.constant",
        "motor.friction")]
    assert all(np.any(c != 0) for c in fitted)
    assert not gt.moves_geometry(kern, p, np.array(fitted))
    assert gt.moves_geometry(kern, p, moved("rotor.radius", 1.001 * p[index["rotor.radius"]]))


@pytest.mark.slow
def test_the_fit_on_the_table_ends_where_the_exact_geometrys_does(tmp_path, monkeypatch):
    """The twin fit (0.5 s log, mu, booster.leak, motor.resistance and the start pressure) with the
    tabulated and with the exact geometry: the estimates within FIT_SHIFT_SE of a standard error,
    the standard errors within 3 %. Measured here up to 0.05 se and 0.5 %; on the 5 s log of the
    bench, seeds 0-2, within 0.15 se and 1.4 % -- the integration's noise at rtol 1e-6, which
    moves the fit as far when its atol changes by 1e-9 of itself (docs/explanation/bench-log.md)."""
    from tests.integration.test_bench_identify import TWIN_TRUTH, small_booster
    from pumpsim.config import load_config
    from pumpsim.identification.pumpdown_fit import identify_bench, twin_log

    cfg = load_config(small_booster(tmp_path))
    log = twin_log(cfg, 0.5, 1000, values=TWIN_TRUTH, noise=0.005, seed=0)
    fits = {}
    for geometry in ("exact", "table"):
        monkeypatch.setenv(gt.ENV, geometry)
        fits[geometry] = identify_bench(cfg, log, list(TWIN_TRUTH)).result.estimates
    for n, e in fits["exact"].items():
        t = fits["table"][n]
        assert abs(t.value - e.value) <= FIT_SHIFT_SE * e.stderr, (n, t.value, e.value, e.stderr)
        assert t.stderr == pytest.approx(e.stderr, rel=0.03), n
