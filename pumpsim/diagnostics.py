"""Residual diagnostics: runs test, Ljung-Box, order spectrum, angle-domain synchronous average."""
from __future__ import annotations

import math

import numpy as np
from scipy import stats


def runs_test(x) -> dict:
    """Wald-Wolfowitz runs test about the median (as MATLAB's runstest), normal approximation."""
    x = np.asarray(x, dtype=float)
    d = x - np.median(x)
    d = d[d != 0]
    signs = d > 0
    n1, n2 = int(signs.sum()), int((~signs).sum())
    runs = 1 + int(np.count_nonzero(signs[1:] != signs[:-1])) if d.size else 0
    n = n1 + n2
    if n1 == 0 or n2 == 0:
        return {"runs": runs, "expected": float("nan"), "z": float("nan"), "p_value": 0.0}
    mu = 2.0 * n1 * n2 / n + 1
    var = 2.0 * n1 * n2 * (2.0 * n1 * n2 - n) / (n * n * (n - 1))
    z = (runs - mu) / math.sqrt(var)
    return {"runs": runs, "expected": mu, "z": z, "p_value": float(2 * stats.norm.sf(abs(z)))}


def ljung_box(x, lags: int | None = None, fitted: int = 0) -> dict:
    x = np.asarray(x, dtype=float) - np.mean(x)
    n = x.size
    m = lags or max(1, min(20, n // 5))
    denom = np.dot(x, x)
    if denom == 0:  # an exactly zero residual has no autocorrelation to test
        return {"q": 0.0, "lags": m, "p_value": 1.0}
    rho = np.array([np.dot(x[:-k], x[k:]) / denom for k in range(1, m + 1)])
    q = n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, m + 1)))
    dof = max(1, m - fitted)
    return {"q": float(q), "lags": m, "p_value": float(stats.chi2.sf(q, dof))}


def order_spectrum(x, dt: float, speed: float, peaks: int = 6) -> dict:
    """Amplitude spectrum of x against shaft order (frequency / shaft frequency); the largest
    peaks labelled with their order."""
    x = np.asarray(x, dtype=float) - np.mean(x)
    n = x.size
    win = np.hanning(n)
    amp = 2 * np.abs(np.fft.rfft(x * win)) / win.sum()
    f = np.fft.rfftfreq(n, dt)
    shaft = speed / (2 * math.pi)
    orders = f / shaft
    found = []
    if n > 8:
        loc = np.nonzero((amp[1:-1] > amp[:-2]) & (amp[1:-1] >= amp[2:]))[0] + 1
        floor = 5 * np.median(amp[1:]) if amp.size > 2 else 0
        loc = loc[amp[loc] > floor]
        for i in loc[np.argsort(amp[loc])[::-1][:peaks]]:
            found.append({"frequency": float(f[i]), "order": float(orders[i]), "amplitude": float(amp[i])})
    return {"frequency": f, "order": orders, "amplitude": amp, "peaks": found, "shaft_hz": shaft}


def synchronous_average(x, angle, bins: int = 180) -> dict:
    """Angle-domain average of x over revolutions (time-synchronous averaging)."""
    a = np.mod(np.asarray(angle, dtype=float), 2 * math.pi)
    idx = np.minimum((a / (2 * math.pi) * bins).astype(int), bins - 1)
    s = np.bincount(idx, weights=x, minlength=bins)
    c = np.bincount(idx, minlength=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        avg = s / c
    return {"angle": (np.arange(bins) + 0.5) * 2 * math.pi / bins, "average": avg, "counts": c}


def residual_report(res, dt, speed, fitted=0) -> dict:
    spec = order_spectrum(res, dt, speed)
    rt = runs_test(res)
    lb = ljung_box(res, fitted=fitted)
    return {"runs_test": rt, "ljung_box": lb,
            "spectrum_peaks": spec["peaks"], "white_at_5pct": bool(rt["p_value"] > 0.05 and lb["p_value"] > 0.05)}
