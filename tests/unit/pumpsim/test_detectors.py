"""Residual detectors against their null distributions: on white noise each test's rejection rate
at level 5 % must lie inside the binomial 99.9 % interval for its number of trials (a test with
a wrong null distribution -- too liberal or too conservative -- falls outside), and each detects
what it is for."""
import math

import numpy as np
import pytest
from scipy import stats

from pumpsim.signals import (broadband_sigma, combined_p, detectors, high_frequency_noise, kurtosis_test,
                                 ljung_box, runs_test, synchronous_f_test, synchronous_speed_scan, systematic_rms)
from tests.tolerances import BROADBAND_SIGMA_REL, HF_SIGMA_REL, NULL_KS_P, SPEED_SCAN_DRIFT_RAD, STRUCTURE_P, SYSTEMATIC_RMS_ABS

TRIALS = 400
N = 600
SPEED = 471.0
DT = 1e-4


def _angle(n=N, speed=SPEED):
    return 0.3 + speed * DT * np.arange(n)


def _binomial_bounds(trials=TRIALS, level=0.05, confidence=0.999):
    lo = stats.binom.ppf((1 - confidence) / 2, trials, level)
    hi = stats.binom.ppf(1 - (1 - confidence) / 2, trials, level)
    return lo, hi


@pytest.mark.parametrize("detector", ["runs", "ljung_box", "synchronous_f", "noise_level", "kurtosis"])
@pytest.mark.parametrize("noise", ["gauss", "uniform"])
def test_size_on_white_noise(detector, noise):
    """Rejections at 5 % over 400 white-noise records; Gaussian and uniform (quantisation-like)
    noise. The kurtosis test is one-sided (heavy tails), so light-tailed uniform noise never trips it."""
    rng = np.random.default_rng(11 if noise == "gauss" else 12)
    angle = _angle()
    rejected = 0
    for _ in range(TRIALS):
        x = rng.normal(size=N) if noise == "gauss" else rng.uniform(-1, 1, size=N)
        p = {"runs": lambda: runs_test(x)["p_value"], "ljung_box": lambda: ljung_box(x)["p_value"],
             "synchronous_f": lambda: synchronous_f_test(x, angle)["p_value"],
             "noise_level": lambda: high_frequency_noise(x)["p_value"],
             "kurtosis": lambda: kurtosis_test(x)["p_value"]}[detector]()
        rejected += p < 0.05
    if detector == "kurtosis" and noise == "uniform":
        assert rejected <= _binomial_bounds()[0]
        return
    lo, hi = _binomial_bounds()
    assert lo <= rejected <= hi, f"{detector}: {rejected} of {TRIALS} rejected at 5 %"


def test_synchronous_f_p_value_is_uniform_under_the_null():
    """Kolmogorov-Smirnov of 300 p-values against U(0, 1), including a record whose samples fall
    on the same angles every revolution (speed x dt a rational fraction of 2 pi)."""
    rng = np.random.default_rng(3)
    for speed in (SPEED, 2 * math.pi / (40 * DT)):
        ps = [synchronous_f_test(rng.normal(size=N), _angle(speed=speed))["p_value"] for _ in range(300)]
        assert stats.kstest(ps, "uniform").pvalue > NULL_KS_P


def test_noise_level_size_with_heavy_tailed_noise():
    """The variance's null spread is corrected by the kurtosis: with Laplace noise the test stays
    valid (at most its level; the sample kurtosis makes it somewhat conservative)."""
    rng = np.random.default_rng(5)
    rejected = sum(high_frequency_noise(rng.laplace(size=N))["p_value"] < 0.05 for _ in range(TRIALS))
    assert rejected <= _binomial_bounds()[1]


def test_spike_train_at_fixed_angles_is_white_to_runs_and_ljung_box_but_not_to_the_f_test():
    """Two one-sample spikes of 1.5 sigma per revolution at fixed rotor angles (moved friction
    reversals): runs and Ljung-Box barely see them; the synchronous average does."""
    rng = np.random.default_rng(8)
    n = 4000
    angle = _angle(n)
    a = np.mod(angle, 2 * math.pi)
    step = SPEED * DT
    spikes = 1.5 * ((np.abs(a - 1.0) < step / 2) | (np.abs(a - 4.0) < step / 2))
    found = {"runs": 0, "lb": 0, "f": 0}
    for _ in range(20):
        x = rng.normal(size=n) + spikes
        found["runs"] += runs_test(x)["p_value"] < 0.01
        found["lb"] += ljung_box(x)["p_value"] < 0.01
        found["f"] += synchronous_f_test(x, angle)["p_value"] < 0.01
    assert found["f"] >= 19 and found["runs"] <= 5 and found["lb"] <= 5, found


def test_noise_level_sees_low_frequency_structure_and_estimates_sigma():
    rng = np.random.default_rng(9)
    n = 4000
    t = DT * np.arange(n)
    x = rng.normal(0, 0.5, n)
    hf = high_frequency_noise(x)
    assert abs(hf["sigma"] / 0.5 - 1) < HF_SIGMA_REL
    drift = x + 0.5 * np.sin(2 * math.pi * 30 * t)
    assert high_frequency_noise(drift)["p_value"] < STRUCTURE_P


def test_systematic_rms_of_a_line_plus_noise():
    rng = np.random.default_rng(10)
    n = 6000
    t = DT * np.arange(n)
    line = 0.3 * math.sqrt(2) * np.sin(2 * math.pi * 37.3 * t)  # RMS 0.3, not shaft-locked
    x = rng.normal(0, 1, n) + line
    det = detectors(x, _angle(n))
    assert abs(systematic_rms(x, det) - 0.3) < SYSTEMATIC_RMS_ABS


def test_combined_p_is_bonferroni_over_measurements_and_detectors():
    rng = np.random.default_rng(1)
    per = [detectors(rng.normal(size=N), _angle()) for _ in range(3)]
    c = combined_p(per)
    assert c["runs_test"] == min(1.0, 3 * min(m["runs_test"]["p_value"] for m in per))
    assert c["family"] == min(1.0, 4 * min(c[d] for d in ("runs_test", "ljung_box", "synchronous_f", "noise_level")))


def test_speed_scan_finds_the_shaft_inside_the_band_and_ignores_a_hum():
    """A torque with a 4th-order content at 1.2 % above nominal and a stronger 37 Hz hum: the scan
    returns the shaft speed (within the refined grid), never the hum."""
    rng = np.random.default_rng(2)
    t = 1 / 20000 * np.arange(8000)
    w_true = 607.37 * 1.012
    y = (0.01 * np.cos(4 * w_true * t + 0.3) + 0.004 * np.sign(np.sin(w_true * t))
         + 0.03 * np.sin(2 * math.pi * 37.3 * t) + rng.normal(0, 0.005, t.size))
    r = synchronous_speed_scan(t, y, 607.37 * 0.98, 607.37 * 1.02, 607.37)
    assert r["refined"] and abs(r["speed"] - w_true) * t[-1] < SPEED_SCAN_DRIFT_RAD
    flat = synchronous_speed_scan(t, rng.normal(0, 0.005, t.size), 607.37 * 0.98, 607.37 * 1.02, 607.37)
    assert not flat["refined"] and flat["speed"] == 607.37


def test_speed_scan_over_vane_passages_ignores_a_pulse_train_aliased_to_another_order():
    """F16: on the concentric 4-vane rig (a constant pump torque) a pulse train at 1.27 x the shaft
    frequency repeats exactly 5 times a revolution at +1.6 % speed, inside the band: a scan over
    whole revolutions takes that speed; over vane passages (order=4: only the orders a 4-vane pump's
    torque has) the alias is not taken. A vane-passing content is still found there."""
    w0 = 607.37
    t = np.arange(5000) / 10000.0
    fp = 1.27 * w0 / (2 * math.pi)
    ph = np.mod(t * fp + 0.3, 1.0) - 0.5
    pulses = 4e-3 * np.exp(-0.5 * (ph / fp / 2e-4) ** 2)
    noise = np.random.default_rng(0).normal(0, 2e-4, t.size)
    alias = w0 * 1.27 * 4 / 5   # five pulses per revolution
    whole = synchronous_speed_scan(t, 0.0142 + pulses + noise, w0 * 0.98, w0 * 1.02, w0)
    assert whole["refined"] and abs(whole["speed"] - alias) * t[-1] < SPEED_SCAN_DRIFT_RAD
    vane = synchronous_speed_scan(t, 0.0142 + pulses + noise, w0 * 0.98, w0 * 1.02, w0, order=4)
    assert abs(vane["speed"] - alias) * t[-1] > 10 * SPEED_SCAN_DRIFT_RAD
    w_true = w0 * 1.004
    pump = 1e-3 * np.cos(4 * w_true * t + 0.2) + 4e-4 * np.cos(8 * w_true * t)
    r = synchronous_speed_scan(t, 0.0142 + pump + noise, w0 * 0.98, w0 * 1.02, w0, order=4)
    assert r["refined"] and abs(r["speed"] - w_true) * t[-1] < SPEED_SCAN_DRIFT_RAD


@pytest.mark.parametrize("seed", range(3))
def test_broadband_sigma_is_the_noise_sd_without_lines_whatever_its_colour(seed):
    """White noise: its sd; plus lines three times the noise (at a bin and between bins, as a named
    effect's misfit at a few orders leaves): still the noise's sd; AR(1) noise (phi 0.85), whose
    high-frequency level is well below its sd: its sd (F17)."""
    rng = np.random.default_rng(seed)
    t = np.arange(8000) / 16000.0
    white = rng.normal(0, 1.0, t.size)
    lines = 3 * np.sin(2 * math.pi * 224.0 * t) + 2 * np.sin(2 * math.pi * 675.3 * t + 1)
    e = rng.standard_normal(t.size)
    ar1 = np.empty(t.size)
    ar1[0] = e[0]
    for i in range(1, t.size):
        ar1[i] = 0.85 * ar1[i - 1] + math.sqrt(1 - 0.85 ** 2) * e[i]
    for x, sd in ((white, np.std(white)), (white + lines, np.std(white)), (ar1, np.std(ar1))):
        assert abs(broadband_sigma(x) / sd - 1) < BROADBAND_SIGMA_REL
    assert high_frequency_noise(ar1)["sigma"] < 0.6 * np.std(ar1)


def test_kurtosis_size_separates_a_lone_outlier_from_heavy_tails():
    """Independent finding F8: on 5000 Gaussian samples one 7-sigma outlier (a friction reversal a
    fit moved by part of a sample) makes the kurtosis test reject, but the tails add almost nothing
    (excess_rms ~ n^(-1/4) sigma); 2 % of samples as 6-sigma spikes add ~0.85 sigma. Under the null
    the excess stays below half the sigma in every one of 200 records."""
    rng = np.random.default_rng(8)
    x = rng.normal(size=5000)
    x[1234] = 7.0
    k = kurtosis_test(x)
    assert k["p_value"] < 0.01 and k["excess_rms"] < 0.5 * k["mad_sigma"]
    y = rng.normal(size=5000)
    y[rng.choice(5000, 100, replace=False)] += 6.0 * rng.choice([-1, 1], 100)
    k = kurtosis_test(y)
    assert k["p_value"] < 0.01 and k["excess_rms"] > 0.5 * k["mad_sigma"]
    worst = max(kurtosis_test(rng.normal(size=1000))["excess_rms"] for _ in range(200))
    assert worst < 0.5


def test_speed_scan_over_vane_passages_keeps_the_nominal_against_a_tone_at_another_order():
    """The independent concentric 4-vane rig with a 1.6 % order-2 speed ripple, no speed column:
    the vane orders carry nothing but the leakage of the strong order-2 torque, whose best lay at
    +1.45 %; the whole revolution is far more synchronous at the nominal, which is kept."""
    w0 = 607.37
    t = np.arange(20000) / 10000.0
    rng = np.random.default_rng(3)
    y = 0.25 * np.cos(2 * w0 * t + 0.5) + rng.normal(0, 0.035, t.size)
    vane = synchronous_speed_scan(t, y, w0 * 0.98, w0 * 1.02, w0, order=4)
    assert vane["speed"] == w0 and not vane["refined"]
