"""The torque identify's residual-aware intervals on twin records: white noise leaves the intervals
as they were, AR(1) noise with a known rho widens them to the spread the estimates really have."""
import dataclasses
import math

import numpy as np
import pytest

import pumpsim
from pumpsim.data import Dataset
from pumpsim.identification import identify
from tests.conftest import make_config
from tests.unit.pumpsim.identification.test_uncertainty import ar1 as noise  # unit-variance AR(1)

MU, THETA0 = 0.17, 0.15


def cof(mu, ratio=0.18 / 0.17):
    return {"friction.housing.dynamic": mu, "friction.housing.static": mu * ratio}


@pytest.fixture(scope="module")
def clean():
    """The four-vane ellipse's torque (0.1 s at 10 kHz), its noise sigma 5 % of its RMS, and the
    config fitted from mu = 0.15."""
    truth = make_config("ellipse_4vanes", **cof(MU))
    r = pumpsim.simulate(dataclasses.replace(truth, angle=THETA0), duration=0.1, rate=10000)
    return r.time, r.torque.copy(), 0.05 * math.sqrt(float(np.mean(r.torque**2))), make_config("ellipse_4vanes", **cof(0.15))


def fit(clean, rho, seed):
    t, y, sigma, cfg = clean
    return identify(cfg, Dataset(t, y + sigma * noise(y.size, rho, seed)), ["mu", "theta0"], adequacy=False)


def test_white_noise_keeps_the_intervals_and_coloured_noise_widens_them(clean):
    white, coloured = fit(clean, 0.0, 11), fit(clean, 0.8, 11)
    w, c = white.estimates["mu"], coloured.estimates["mu"]
    # white: lag 0-2, the sandwich within a few % of sigma^2 (J'J)^-1 (its scatter ~sqrt(2/n) = 1.4 %)
    assert white.intervals.widening < 1.1 and white.intervals.note() is None
    assert w.stderr_residual_aware == pytest.approx(w.stderr_white, rel=0.06)
    # AR(1) 0.8: sqrt((1 + rho) / (1 - rho)) = 3 times the white s.e. for a slowly varying column
    ch = coloured.intervals.channels[0]
    assert ch.channel == "torque" and ch.lag1 == pytest.approx(0.8, abs=0.05) and ch.structured
    assert 2.2 < c.stderr_residual_aware / c.stderr_white < 3.5 and c.stderr == c.stderr_residual_aware
    assert coloured.intervals.basis == "residual-aware" and coloured.intervals.widening > 2
    js = coloured.to_json()
    assert js["params"]["mu"]["stderr_white"] == c.stderr_white and js["intervals"]["note"]
    assert js["params"]["mu"]["ci95"] == [c.lower95, c.upper95]
    assert "Newey-West" in str(coloured) and f"lag-1 autocorrelation {ch.lag1:.2f}" in str(coloured)
    assert f"white-noise ± {c.stderr_white:.3g}" in str(coloured)


@pytest.mark.slow
@pytest.mark.parametrize("rho", [0.0, 0.8])
def test_coverage_and_spread_over_seeds(clean, rho):
    """200 fits (~15 CPU s). The s.e.s against the estimates' real spread (the sample sd of 200 has
    ~5 % scatter; Bartlett's bias at Andrews' lag ~3-10 %): the residual-aware one within 15 %.
    Coverage of the 95 % interval: binomial sd 1.5 % at 200, so >= 0.90 (and <= 0.99); the white
    intervals under AR(1) 0.8 cover about half (the test has teeth). White noise: the intervals
    widen by < 3 % on average."""
    fits = [fit(clean, rho, seed).estimates["mu"] for seed in range(200)]
    values = np.array([e.value for e in fits])
    spread = float(np.std(values, ddof=1))
    aware = float(np.mean([e.stderr_residual_aware for e in fits]))
    assert aware == pytest.approx(spread, rel=0.15)
    covered = np.mean([e.lower95 <= MU <= e.upper95 for e in fits])
    covered_white = np.mean([abs(e.value - MU) <= 1.96 * e.stderr_white for e in fits])
    assert 0.90 <= covered <= 0.99, covered
    ratio = np.mean([(e.upper95 - e.lower95) / (2 * 1.96 * e.stderr_white) for e in fits])
    if rho == 0:
        assert ratio < 1.03 and covered_white >= 0.90
    else:
        assert covered_white < 0.7 and ratio > 2.5


def test_bench_log_fit_reports_both_standard_errors_and_widens_for_coloured_pressure_noise(tmp_path):
    """A 0.3 s twin log of the small booster: white noise keeps the intervals (both s.e.s in the
    JSON, the channels' rows the residual's); the same log with AR(1) (rho 0.9) noise on the pressure
    instead is called correlated in the pressure, and its intervals are widened and say so."""
    from pumpsim.config import load_config
    from pumpsim.identification.pumpdown_fit import identify_bench, twin_log
    from tests.integration.test_bench_identify import small_booster

    cfg = load_config(small_booster(tmp_path))
    white = twin_log(cfg, 0.3, 1000, values={"mu": 0.165}, noise=0.002, seed=1)
    fit = identify_bench(cfg, white, ["mu"], ripple=False)
    js = fit.to_json()
    iv = js["intervals"]
    assert [c["channel"] for c in iv["channels"]] == ["booster_pressure", "current"]
    assert sum(c["samples"] for c in iv["channels"]) == sum(v.size for v in fit.measured.values())
    for name, p in js["params"].items():
        assert p["stderr_white"] > 0 and p["stderr_residual_aware"] > 0
        assert p["stderr"] == max(p["stderr_white"], p["stderr_residual_aware"]) or iv["quantile"][name] > 1.97
    assert not any(c["structured"] for c in iv["channels"] if c["channel"] == "booster_pressure")

    clean = twin_log(cfg, 0.3, 1000, values={"mu": 0.165}, noise=0.0)
    pb = clean.booster_pressure + 0.002 * np.ptp(clean.booster_pressure) * noise(clean.n, 0.9, 2)
    coloured = dataclasses.replace(white, booster_pressure=pb)
    fit_c = identify_bench(cfg, coloured, ["mu"], ripple=False)
    ch = {c.channel: c for c in fit_c.result.intervals.channels}
    assert ch["booster_pressure"].structured and ch["booster_pressure"].lag1 > 0.5
    assert fit_c.result.intervals.widening > 1.5
    note = [n for n in fit_c.notes if n.startswith("intervals:")]
    assert note and "booster_pressure (lag-1 autocorrelation" in note[0] and "Newey-West" in note[0]
    assert "intervals:" in str(fit_c)
