"""A fitted speed (and phase) is found from the record, not assumed: the report's identification
cases from its own initial guesses, a start-speed grid from -30 % to +30 %, and the CLI path where
the configured speed is the wrong start."""
import dataclasses
import json
import math
import subprocess
import sys

import numpy as np
import pytest

import pumpsim
from pumpsim.data import Dataset
from pumpsim.identification import identify
from pumpsim.identification.start import model_order_scan
from tests.conftest import EXAMPLES, make_config
from tests.tolerances import FIT_SPEED_ABS, FIT_THETA0_ABS, NOISE_FREE_MU_REL, NOISY_MU_REL

RATIO = 0.18 / 0.17  # the examples' static/dynamic COF ratio


def cof(mu):
    return {"friction.housing.dynamic": mu, "friction.housing.static": mu * RATIO}


def record(base, mu, theta0, speed=471.0, duration=0.1, rate=10000, noise=0.0, seed=0):
    truth = make_config(base, **cof(mu), **{"operation.speed": speed})
    r = pumpsim.simulate(dataclasses.replace(truth, angle=theta0), duration=duration, rate=rate)
    y = r.torque.copy()
    if noise:
        y += np.random.default_rng(seed).normal(0, noise * np.std(y), y.size)
    return Dataset(r.time, y)


def test_report_signal_2_from_its_initial_guesses_with_the_configured_speed_wrong():
    # report 13.4, table 19: COF 0.05, speed 400 (the config's), phase 0.15; truth 0.17, 471, 0.15
    ds = record("ellipse_4vanes", 0.17, 0.15)
    cfg = make_config("ellipse_4vanes", **cof(0.05), **{"operation.speed": 400.0})
    res = identify(cfg, ds, ["mu", "theta0", "speed"], initial={"theta0": 0.15})
    assert res.converged
    assert res.value("mu") == pytest.approx(0.17, rel=NOISE_FREE_MU_REL)
    assert abs(res.value("speed") - 471.0) < FIT_SPEED_ABS
    assert abs(res.value("theta0") - 0.15) < FIT_THETA0_ABS


@pytest.mark.parametrize("base,truth_phase,vanes", [("ellipse_1vane", math.pi / 2, 1), ("ellipse_4vanes", 0.15, 4)])
def test_start_speed_grid_minus_30_to_plus_30_percent_is_recovered_every_time(base, truth_phase, vanes):
    """Every start from -30 % to +30 % of the true speed (7 starts; 2 % noise) reaches the truth:
    the speed within 3 standard errors, the COF within NOISY_MU_REL."""
    ds = record(base, 0.17, truth_phase, noise=0.02, seed=vanes)
    missed = []
    for rel in np.linspace(-0.3, 0.3, 7):
        cfg = make_config(base, **cof(0.1), **{"operation.speed": 471.0 * (1 + rel)})
        res = identify(cfg, ds, ["mu", "theta0", "speed"], initial={"theta0": 0.1})
        e = res.estimates["speed"]
        if not (abs(e.value - 471.0) < 3 * e.stderr + 1e-9
                and res.value("mu") == pytest.approx(0.17, rel=NOISY_MU_REL)):
            missed.append((round(rel, 2), e.value, res.value("mu")))
    assert not missed


def test_order_scan_keeps_the_start_when_the_record_holds_no_shaft_orders():
    rng = np.random.default_rng(3)
    t = np.arange(2000) / 1e4
    one_rev = np.cos(4 * np.linspace(0, 2 * math.pi, 720, endpoint=False))
    assert model_order_scan(t, rng.normal(size=t.size), one_rev, 300.0, 600.0) is None
    assert model_order_scan(t, np.zeros_like(t), np.ones(720), 300.0, 600.0) is None


def test_order_scan_ignores_a_line_the_model_does_not_have():
    """A strong non-shaft line (a gear mesh at 7.3 x the speed) beside the model's order 4: the scan
    finds the speed from order 4, not from the stronger foreign line: within the local fit's basin
    (order 4's phase drifts by less than pi/4 over the record; the line's leakage biases the peak)."""
    t = np.arange(5000) / 1e4
    w = 471.0
    y = 0.3 * np.cos(4 * w * t + 0.4) + 1.0 * np.cos(7.3 * w * t)
    one_rev = np.cos(4 * np.linspace(0, 2 * math.pi, 720, endpoint=False))
    best = model_order_scan(t, y, one_rev, 0.5 * w, 1.5 * w)
    assert abs(best - w) < math.pi / (4 * 4 * t[-1])


def test_cli_identify_fits_the_speed_from_a_wrong_configured_speed(tmp_path):
    ds = record("ellipse_4vanes", 0.17, 0.15)
    data = tmp_path / "signal2.csv"
    np.savetxt(data, np.column_stack([ds.time, ds.torque]), delimiter=",", header="time,torque", comments="")
    text = (EXAMPLES / "ellipse_4vanes.toml").read_text()
    cfg = tmp_path / "start400.toml"
    cfg.write_text(text.replace("speed = 471.0", "speed = 400.0"))
    assert "speed = 400.0" in cfg.read_text()
    out = tmp_path / "fit.json"
    run = subprocess.run([sys.executable, "-m", "pumpsim", "identify", str(cfg), str(data), "--params",
                          "mu,theta0,speed", "--json", str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    fit = json.loads(out.read_text())
    assert abs(fit["params"]["speed"]["value"] - 471.0) < FIT_SPEED_ABS
    assert fit["params"]["mu"]["value"] == pytest.approx(0.17, rel=NOISE_FREE_MU_REL)


@pytest.mark.slow  # ~40-55 s: make test-all
def test_a_harmonic_phase_fitted_from_anywhere_in_its_period_reaches_an_exact_fit():
    """An out-of-round's phase is an angle (its cost is periodic, not convex): from starts spread
    over the period, the start scan and the local fit reach the truth or one of its exact
    equivalents (the ellipse's symmetry: the phase modulo pi/3 with theta0 moved by pi)."""
    truth = make_config("ellipse_1vane", **{"housing.harmonics": [[3, 4e-5, 1.0]]})
    r = pumpsim.simulate(dataclasses.replace(truth, angle=0.2), duration=0.05, rate=10000)
    ds = Dataset(r.time, r.torque.copy())
    scale = float(np.sqrt(np.mean(r.torque ** 2)))
    for start in 1.0 + np.linspace(0, 2 * math.pi, 6, endpoint=False):
        cfg = dataclasses.replace(make_config("ellipse_1vane", **{"housing.harmonics": [[3, 4e-5, start]]}),
                                  angle=0.2)
        res = identify(cfg, ds, ["housing.harmonics.0.phase", "mu", "theta0"])
        off = (res.value("housing.harmonics.0.phase") - 1.0 + math.pi / 6) % (math.pi / 3) - math.pi / 6
        assert res.converged and res.rms < 1e-6 * scale and abs(off) < 1e-4, (start, res)
