"""The supply voltage as samples (pneumatics.drive): the same function on both integration paths,
and its stops where the voltage steps, not at its noise."""
import numpy as np

from pumpsim.pneumatics.drive import VoltageDrive


def test_the_drive_is_casadis_linear_interpolant_inside_and_beyond_the_grid():
    rng = np.random.default_rng(4)
    d = VoltageDrive(1e-3, 13.5 + rng.standard_normal(50))
    t = np.r_[-2e-3, rng.uniform(0.0, 0.049, 200), 0.049, 0.06]
    ref = np.array([float(d.function(s)) for s in t])
    assert np.max(np.abs(d(t) - ref)) < 1e-12
    assert d(0.0205) == 0.5 * (d.values[20] + d.values[21])


def test_stops_at_a_step_of_the_voltage_and_not_at_its_noise():
    for seed in range(3):  # 0.5 % noise: second differences 1.2 % rms, their largest of 5000 up to 5.3 %
        v = 13.5 * (1 + 0.005 * np.random.default_rng(seed).standard_normal(5001))
        assert VoltageDrive(1e-3, v).stops.size == 0
        v[1001:] -= 3.5  # a dip to 10 V within one sample interval: the slope jumps at samples 1000 and 1001
        assert VoltageDrive(1e-3, v).stops.tolist() == [1000, 1001]
    clean = np.r_[np.full(100, 13.5), np.linspace(13.5, 10.0, 101)[1:]]  # a kink in a noise-free log
    assert VoltageDrive(1e-3, clean).stops.tolist() == [99]
    assert VoltageDrive(1e-3, np.full(50, 13.5)).stops.size == 0
