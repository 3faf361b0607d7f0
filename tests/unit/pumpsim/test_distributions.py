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
