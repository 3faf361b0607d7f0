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


def _marginals():
    """(scipy.stats frozen distribution, Marginal) pairs as design.sampling makes them: tight and wide
    spreads, means of either sign, truncations left of, right of and about the mean, far in a tail."""
    import math

    out = []
    for mean, sd in [(0.2, 0.02), (45e-3, 4e-6), (1.5e-3, 3e-5), (-3.0, 2.0)]:
        out.append((stats.norm(mean, sd), d.Marginal("norm", mean, sd)))
        out.append((stats.uniform(mean - sd, 2 * sd), d.Marginal("uniform", mean - sd, 2 * sd)))
        if mean > 0:
            s = math.sqrt(math.log1p((sd / mean) ** 2))
            scale = mean * math.exp(-s * s / 2)
            out.append((stats.lognorm(s, scale=scale), d.Marginal("lognorm", 0.0, scale, (s,))))
        for lo, hi in [(-4, 4), (-0.5, 3), (0.5, 3), (-30, -1), (1, 40), (-50, 0.1), (-1e-3, 1e-3)]:
            a, b = ((mean + lo * sd) - mean) / sd, ((mean + hi * sd) - mean) / sd
            out.append((stats.truncnorm(a, b, loc=mean, scale=sd), d.Marginal("truncnorm", mean, sd, (a, b))))
    return out


def test_the_sampled_distributions_are_scipy_stats_ones_to_the_bit():
    """Marginal's quantiles (the design matrix, the plausibility ends) and support (the implied
    bounds) are scipy.stats', for scalars (type included) and for a sampler's arrays."""
    u = np.clip(np.random.default_rng(11).random(4096), 1e-12, 1 - 1e-12)
    for ref, m in _marginals():
        for q in (0.001, 0.999, 0.5, 1e-12, 1 - 1e-12):
            got, want = m.ppf(q), ref.ppf(q)
            assert got == want and type(got) is type(want), (m, q, got, want)
        assert np.array_equal(m.ppf(u), ref.ppf(u)), m
        assert np.array_equal(m.ppf(u[:7].reshape(7, 1)), ref.ppf(u[:7].reshape(7, 1))), m
        assert m.support() == ref.support(), m


def test_a_design_matrix_is_the_one_scipy_stats_distributions_give():
    """A study's designs (Sobol' points through each key's quantile) are those of the frozen
    scipy.stats distributions design.sampling held before."""
    from pumpsim.design.sampling import unit_points
    from pumpsim.design.study import load_study
    from tests.conftest import ROOT

    study = load_study(ROOT / "examples" / "studies" / "test_rig_tolerances.toml")
    refs = {"norm": lambda m: stats.norm(m.loc, m.scale),
            "truncnorm": lambda m: stats.truncnorm(*m.shape, loc=m.loc, scale=m.scale)}
    u = unit_points("sobol", 512, len(study.variables), study.seed)
    for j, v in enumerate(study.variables):
        ref = refs[v.dist.kind](v.dist)
        assert np.array_equal(v.ppf(u[:, j]), ref.ppf(np.clip(u[:, j], 1e-12, 1 - 1e-12))), v.key


def test_reading_a_study_imports_no_scipy_stats():
    import subprocess
    import sys

    from tests.conftest import ROOT

    code = ("import sys; from pumpsim.design.study import load_study; "
            f"load_study({str(ROOT / 'examples' / 'studies' / 'test_rig_tolerances.toml')!r}); "
            "print(sorted(m for m in ('scipy.stats', 'pandas', 'dask') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT).stdout
    assert out.strip() == "[]"


def test_the_speed_trends_f_test_is_scipy_stats_one():
    """data.trend's F-test p-value (distributions.f_sf, before scipy.stats.f.sf) over its range:
    degree 1-20 against up to 10^7 samples, F from 0 (no gain) to far past any threshold."""
    for dfn in (1, 2, 7, 20):
        for dfd in (18, 150, 4_979, 1_000_000, 10_000_000):
            for f in (0.0, 1e-9, 0.3, 1.0, 2.7, 11.0, 140.0, 3e4, 1e12):
                assert d.f_sf(f, dfn, dfd) == stats.f.sf(f, dfn, dfd), (f, dfn, dfd)
