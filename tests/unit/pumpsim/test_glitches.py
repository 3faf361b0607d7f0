"""A logger's glitches and rounding: isolated spikes found (and only they: not an inrush, a step,
an aliased ripple), the grid a channel is rounded to, and the noise that rounding adds."""
import math

import numpy as np
import pytest

from pumpsim.benchlog import read_bench_log
from pumpsim.signals import isolated_spikes, measured_noise, noise_sigma, quantization_step


def _pumpdown_like(n=2000, rate=1000.0, seed=0):
    t = np.arange(n) / rate
    rng = np.random.default_rng(seed)
    current = 6.0 + 45.0 * np.exp(-t / 0.02) + 0.05 * np.sin(2 * np.pi * 280 * t)  # inrush + aliased ripple
    current[0] = 0.0  # switched on at the second sample: a step, not a spike
    return t, current + 0.02 * rng.standard_normal(n)


def test_spikes_are_found_and_nothing_else():
    t, x = _pumpdown_like()
    assert isolated_spikes(x, 12.0).size == 0
    y = x.copy()
    at = np.array([57, 400, 401 + 500, 1733])
    y[at] += np.array([3.0, -2.5, 4.0, 1.5])
    np.testing.assert_array_equal(isolated_spikes(y, 12.0), at)
    nyquist = np.where(np.arange(500) % 2, 1.0, -1.0) + 0.01 * np.random.default_rng(1).standard_normal(500)
    assert isolated_spikes(nyquist, 12.0).size == 0  # the noise estimate holds the alternation itself


@pytest.mark.parametrize("step", [0.1, 0.01, 250.0])
def test_quantization_step_and_its_noise(step):
    rng = np.random.default_rng(2)
    smooth = 93_000 + 4_000 * np.cos(np.linspace(0, 3, 3000)) + 2.0 * rng.standard_normal(3000)
    q = np.round(smooth / step) * step
    assert quantization_step(q) == pytest.approx(step, rel=1e-6)
    assert quantization_step(smooth) == 0.0  # not on a grid
    # the rounding is white-ish noise of q^2/12 that first differences of a slow signal miss
    assert measured_noise(q) == pytest.approx(math.hypot(noise_sigma(q), step / math.sqrt(12)))
    if step == 250.0:
        assert noise_sigma(q) < 0.1 * step / math.sqrt(12) <= measured_noise(q)


def test_a_bench_log_reads_with_its_spikes_replaced_and_said(tmp_path):
    t, i = _pumpdown_like(n=600)
    i[[100, 333]] += [3.0, -3.0]
    f = tmp_path / "log.csv"
    f.write_text("time,voltage,current,booster_pressure [kPa]\n"
                 + "\n".join(f"{a:.6f},13.5,{b:.6f},{101.3 - 5 * a:.5f}" for a, b in zip(t, i)) + "\n")
    log = read_bench_log(f)
    assert any("current: 2 isolated spike(s)" in n and "row 102, row 335" in n for n in log.notes), log.notes
    # the file holds 6 decimals
    assert abs(log.current[100] - 0.5 * (i[99] + i[101])) < 2e-6 and abs(log.current[99] - i[99]) < 1e-6


def test_a_rounded_channel_is_noise_of_its_rounding_not_a_model_error():
    """The bench-log detectors on a residual that is a pressure's rounding staircase (the channel
    moves less than a step per sample): with the rounding's sigma as the channel's floor they read
    it as noise and name the channel rounded; without it the same residual is far from white."""
    from pumpsim.diagnosis.pump_workflow import BenchDetection

    step, sigma = 250.0, 5.0  # Pa: rounding step, the sensor's noise
    rng = np.random.default_rng(4)
    true = 100_000 - 27.0 * np.arange(600) + sigma * rng.standard_normal(600)
    rounded = np.round(true / step) * step
    residual = (rounded - (100_000 - 27.0 * np.arange(600))) / measured_noise(rounded)
    current = rng.standard_normal(300)
    floor = quantization_step(rounded) / math.sqrt(12) / measured_noise(rounded)
    sizes, names = [600, 300], ["booster_pressure", "current"]
    with_floor = BenchDetection(np.concatenate([residual, current]), sizes, names, 2,
                                floors={"booster_pressure": floor, "current": 0.0})
    assert with_floor.rounded == ["booster_pressure"] and with_floor.consistent()
    without = BenchDetection(np.concatenate([residual, current]), sizes, names, 2)
    assert without.rounded == [] and not without.consistent()
