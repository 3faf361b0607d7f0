"""The residual-aware (Newey-West) covariance: its algebra, its bandwidth, its fixed-b quantile, and
its standard errors against the known ones of linear models with white and AR(1) errors."""
import math

import numpy as np
import pytest

from pumpsim.identification.result import fit_estimates
from pumpsim.identification.uncertainty import (bartlett_bandwidth, fixed_b_quantile, lag1, long_run_covariance,
                                                residual_aware)


def ar1(n, rho, seed):
    """Unit-variance AR(1) noise (stationary from the first sample)."""
    w = np.random.default_rng(seed).standard_normal(n)
    e = np.empty(n)
    e[0] = w[0]
    for i in range(1, n):
        e[i] = rho * e[i - 1] + math.sqrt(1 - rho**2) * w[i]
    return e


def test_window_sums_equal_the_bartlett_weighted_lag_sum():
    G = np.random.default_rng(0).standard_normal((300, 3))
    for lag in (0, 1, 17, 299):
        S = G.T @ G
        for k in range(1, lag + 1):
            Gk = G[k:].T @ G[:-k]
            S += (1 - k / (lag + 1)) * (Gk + Gk.T)
        assert np.allclose(long_run_covariance(G, lag), S, rtol=1e-12, atol=1e-9)


def test_bandwidth_grows_with_the_correlation_and_stays_inside_the_record():
    assert bartlett_bandwidth(0.0, 1000) == 0
    lags = [bartlett_bandwidth(rho, 1000) for rho in (0.1, 0.5, 0.8, 0.95)]
    assert lags == sorted(lags) and lags[0] < lags[-1]
    # Andrews' AR(1) plug-in at rho = 0.5, n = 1000: 1.1447 (4 0.25 / (0.25 2.25) 1000)^(1/3) = 13.9
    assert bartlett_bandwidth(0.5, 1000) == 13
    assert bartlett_bandwidth(0.999, 50) == 49


def test_fixed_b_quantile_matches_a_simulation():
    """The Kiefer-Vogelsang cubic against the 95 % quantile of |t| for the mean of iid normals with
    the Bartlett long-run variance at lag b n: 10000 records, the quantile's own scatter ~1.5 %."""
    rng = np.random.default_rng(1)
    n, reps = 200, 10000
    X = rng.standard_normal((reps, n))
    m = X.mean(axis=1)
    r = X - m[:, None]
    for b in (0.1, 0.5, 1.0):
        lag = min(int(b * n), n - 1)
        w = lag + 1
        c = np.cumsum(np.concatenate([np.zeros((reps, w)), r, np.zeros((reps, lag))], axis=1), axis=1)
        lrv = ((c[:, w:] - c[:, :-w]) ** 2).sum(axis=1) / w / n
        q = np.quantile(np.abs(m) / np.sqrt(lrv / n), 0.95)
        assert q == pytest.approx(fixed_b_quantile(b), rel=0.04), b
    assert fixed_b_quantile(0.0) == 1.96


@pytest.mark.parametrize("rho", [0.0, 0.8])
def test_standard_error_of_a_mean_under_white_and_ar1_errors(rho):
    """One long record, a constant and a trend fitted: the residual-aware s.e. of the constant
    against the exact one, sqrt((1 + rho) / (1 - rho) / n) for unit-variance AR(1) errors at the
    trend's centre. Its scatter at n = 20000 (Andrews' lag ~85 at rho 0.8) is ~4 %, the Bartlett
    bias -3 %: 12 % is 2.5 scatters beyond the bias. White: the two s.e.s agree within 5 %."""
    n = 20000
    t = np.linspace(-1, 1, n)
    J = np.column_stack([np.ones(n), t])
    e = ar1(n, rho, seed=3)
    coef = np.linalg.lstsq(J, e, rcond=None)[0]
    r = e - J @ coef
    est, _, intervals = fit_estimates(["a", "b"], coef, [0.0, 0.0], r, J)
    exact = math.sqrt((1 + rho) / (1 - rho) / n)
    assert est["a"].stderr_residual_aware == pytest.approx(exact, rel=0.12)
    assert est["a"].stderr_white == pytest.approx(math.sqrt(1 / n), rel=0.03)
    if rho == 0:
        assert est["a"].stderr_residual_aware == pytest.approx(est["a"].stderr_white, rel=0.05)
        assert not intervals.channels[0].structured and intervals.note() is None
    else:
        assert intervals.basis == "residual-aware" and intervals.widening > 2.5
        assert est["a"].stderr == est["a"].stderr_residual_aware
        assert intervals.channels[0].lag1 == pytest.approx(rho, abs=0.02)
        assert intervals.channels[0].effective_samples == pytest.approx(n * (1 - rho) / (1 + rho), rel=0.1)
        note = intervals.note()
        assert "lag-1 autocorrelation 0.8" in note and "Newey-West" in note
        # first differences see AR(1) noise as a white floor sqrt(1 - rho) of its size and a slow part
        # above it: one record cannot tell coloured noise from a missing effect, and the note says both
        assert intervals.channels[0].misses_signal and "coloured noise, or an effect the model lacks" in note


def test_interval_is_the_wider_one_and_uses_the_fixed_b_quantile():
    n = 2000
    J = np.column_stack([np.ones(n), np.linspace(0, 1, n)])
    r = ar1(n, 0.9, seed=5)
    r -= J @ np.linalg.lstsq(J, r, rcond=None)[0]
    est, _, iv = fit_estimates(["a", "b"], np.array([1.0, 2.0]), [0.0, 0.0], r, J)
    for name, e in est.items():
        half = (e.upper95 - e.lower95) / 2
        assert half == pytest.approx(iv.quantile[name] * e.stderr)
        assert half >= 1.96 * e.stderr_white and iv.quantile[name] > 1.96


def test_channels_keep_their_own_lags():
    """Two channels: the covariance is the sum of each channel's own sandwich (no lag crosses
    from the end of one into the start of the next), each with its own bandwidth."""
    rng = np.random.default_rng(7)
    n1, n2 = 400, 300
    J = rng.standard_normal((n1 + n2, 2))
    r = np.concatenate([ar1(n1, 0.9, 8), rng.standard_normal(n2)])
    bread = np.linalg.inv(J.T @ J)
    cov, found, b = residual_aware(J, r, r, bread, [("pressure", n1), ("current", n2)])
    parts = [bread @ long_run_covariance(J[s] * r[s, None], c.bandwidth) @ bread
             for s, c in zip((slice(0, n1), slice(n1, None)), found)]
    assert np.allclose(cov, (parts[0] + parts[1]) * (n1 + n2) / (n1 + n2 - 2))
    assert found[0].structured and not found[1].structured and found[0].bandwidth > found[1].bandwidth
    with pytest.raises(ValueError, match="rows"):
        residual_aware(J, r, r, bread, [("pressure", n1)])


def test_a_misfit_larger_than_the_noise_is_named_as_such():
    """A slow sine 5x the noise left in the residual: the note says the intervals cover the noise
    and the misfit only as if it were random, and what share of the channel's variation is missed."""
    n = 1000
    t = np.linspace(0, 1, n)
    rng = np.random.default_rng(9)
    y = 100 * t + rng.standard_normal(n)
    r = 5 * np.sin(2 * np.pi * 3 * t) + rng.standard_normal(n)
    J = np.column_stack([np.ones(n), t])
    _, _, iv = fit_estimates(["a", "b"], np.zeros(2), [0.0, 0.0], r, J, y, [("pressure", n)])
    c = iv.channels[0]
    assert c.misses_signal and c.systematic_rms == pytest.approx(5 / math.sqrt(2), rel=0.1)
    assert c.durbin_watson < 0.5 and lag1(r) > 0.9
    note = iv.note()
    assert "as if it were random" in note and "misses that share of the signal" in note
    assert f"pressure ({c.systematic_rms / c.noise_rms:.2g}x the floor, {100 * c.systematic_share:.2g} % of its" in note


def test_a_residual_whose_size_varies_widens_without_being_called_correlated():
    """Independent errors 4x larger where the slope's column is large: the sandwich (lag ~0) is
    wider than the pooled sigma^2 (J'J)^-1 and the note blames the size, not a correlation."""
    n = 4000
    t = np.linspace(-1, 1, n)
    J = np.column_stack([np.ones(n), t])
    r = np.random.default_rng(4).standard_normal(n) * np.where(np.abs(t) > 0.5, 4.0, 1.0)
    r -= J @ np.linalg.lstsq(J, r, rcond=None)[0]
    est, _, iv = fit_estimates(["a", "b"], np.zeros(2), [0.0, 0.0], r, J)
    assert not iv.channels[0].structured and iv.widening > 1.1
    assert est["b"].stderr_residual_aware > 1.1 * est["b"].stderr_white
    note = iv.note()
    assert "size varies along the record" in note and "autocorrelation" not in note
