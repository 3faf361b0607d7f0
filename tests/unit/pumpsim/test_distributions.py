"""pumpsim.distributions evaluates the same functions scipy.stats does, bit for bit (the verdicts'
p-values must not move when the import is avoided)."""
import numpy as np
from scipy import stats

from pumpsim import distributions as d


def test_the_same_values_as_scipy_stats():
    rng = np.random.default_rng(7)
    for _ in range(500):
        x, z, p = rng.uniform(0, 60), rng.normal() * 6, rng.uniform(0.5, 0.9999)
        k, m = int(rng.integers(1, 50)), int(rng.integers(1, 20000))
        assert d.chi2_sf(x, k) == stats.chi2.sf(x, k)
        assert d.f_sf(x / 10, k, m) == stats.f.sf(x / 10, k, m)
        assert d.norm_sf(z) == stats.norm.sf(z)
        assert d.t_sf(abs(z), m) == stats.t.sf(abs(z), m)
        assert d.t_ppf(p, m) == stats.t.ppf(p, m)


def test_the_fitting_and_diagnosis_modules_do_not_import_scipy_stats():
    import subprocess
    import sys

    code = ("import sys, pumpsim.api, pumpsim.diagnosis.workflow, pumpsim.identification; "
            "print('scipy.stats' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_the_kurtosis_test_is_scipy_stats_one():
    """signals.kurtosis_test's statistic, one-sided p and excess are scipy.stats.kurtosistest's
    and kurtosis's (the same formulas, now without the import): Gaussian, heavy- and light-tailed
    samples from n = 20, and a constant offset far above the spread."""
    from pumpsim.signals import kurtosis_test

    rng = np.random.default_rng(3)
    for n in (20, 21, 57, 1000, 20000):
        for x in (rng.normal(size=n), rng.standard_t(4, size=n), rng.uniform(size=n), 5 + 1e-3 * rng.normal(size=n)):
            got = kurtosis_test(x)
            z, p = stats.kurtosistest(x, alternative="greater")
            assert abs(got["statistic"] - z) <= 1e-12 * max(1.0, abs(z))
            assert abs(got["p_value"] - p) <= 1e-12
            assert abs(got["excess"] - stats.kurtosis(x)) <= 1e-12 * max(1.0, abs(stats.kurtosis(x)))


def test_a_diagnosis_with_a_sensor_lag_and_the_detectors_imports_neither_scipy_stats_nor_signal():
    """The lagged model's filter and the kurtosis detector are what pulled scipy.signal and
    scipy.stats (~1-2 s) into every `pumpsim diagnose`."""
    import subprocess
    import sys

    code = ("import sys, numpy as np; from pumpsim.sensor import first_order_lag; "
            "from pumpsim.signals import detectors; x = np.random.default_rng(0).normal(size=500); "
            "first_order_lag(np.column_stack([x, x]), 1e-4, 2e-4); detectors(x, np.arange(500) * 0.1); "
            "print(sorted(m for m in ('scipy.stats', 'scipy.signal') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
