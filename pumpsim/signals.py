"""Signal statistics of a residual or a record: runs test, Ljung-Box, order spectrum, angle-domain
synchronous average, noise levels and the speed evidence in a torque record."""
from __future__ import annotations

import math

import numpy as np

from .distributions import chi2_sf, f_sf, norm_sf


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
    return {"runs": runs, "expected": mu, "z": z, "p_value": float(2 * norm_sf(abs(z)))}


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
    return {"q": float(q), "lags": m, "p_value": float(chi2_sf(q, dof))}


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


# --- Detectors of a systematic residual beyond whiteness (the discrepancy workflow's verdict) ------
# Each returns {"statistic", "p_value", ...}; each p-value is uniform on [0, 1] (or conservative)
# under its null hypothesis, tested in tests/unit/test_detectors.py over many noise seeds.

def revolution_bins(angle, bins: int | None = None) -> np.ndarray:
    """Bin index of every sample's rotor angle mod 2 pi; default bins: about one per sample and
    revolution (so a one-sample spike of the torque stays in one bin), 8 ... 720."""
    a = np.mod(np.asarray(angle, dtype=float), 2 * math.pi)
    if bins is None:
        revs = max((np.max(angle) - np.min(angle)) / (2 * math.pi), 1e-9)
        bins = int(np.clip(a.size / revs, 8, 720))
    return np.minimum((a / (2 * math.pi) * bins).astype(int), bins - 1), bins


def synchronous_f_test(x, angle, bins: int | None = None) -> dict:
    """Angle-domain synchronous-average F-test (one-way ANOVA of x over rotor-angle bins, the
    revolutions of the record being the replicates): between-bin against within-bin variance.

    Null: x is noise with one variance whatever the rotor angle, independent between samples
    (white); then F ~ F(B - 1, n - B). A deterministic shaft-synchronous residual -- smooth or a
    train of one-sample spikes at fixed angles, white-looking to runs and Ljung-Box -- puts its
    power between the bins. Needs two or more revolutions (replicates in every used bin)."""
    x = np.asarray(x, dtype=float)
    idx, B = revolution_bins(angle, bins)
    c = np.bincount(idx, minlength=B)
    used = c > 0
    k = int(used.sum())
    n = x.size
    if k < 2 or n - k < 2 or np.max(c) < 2:
        return {"statistic": float("nan"), "p_value": 1.0, "bins": k, "within_var": float(np.var(x)),
                "applicable": False}
    s = np.bincount(idx, weights=x, minlength=B)
    mean_b = np.where(used, s / np.maximum(c, 1), 0.0)
    within = float(np.sum((x - mean_b[idx]) ** 2))
    between = float(np.sum(c[used] * (mean_b[used] - x.mean()) ** 2))
    F = (between / (k - 1)) / max(within / (n - k), 1e-300)
    return {"statistic": float(F), "p_value": float(f_sf(F, k - 1, n - k)), "bins": k,
            "within_var": within / (n - k), "applicable": True,
            "average": np.where(used, mean_b, np.nan), "counts": c}


def high_frequency_noise(x, band=(0.2, 0.4)) -> dict:
    """White-noise variance from the residual's periodogram in the band `band` x sample rate
    (median of the raw periodogram / ln 2: a narrow line or a spike at a few frequencies does not
    move a median; the band stops short of Nyquist, where a DAQ's anti-alias filter cuts).
    Compared with the residual's variance: z = ln(var / sigma_hf^2) over its null standard
    deviation sqrt((kurtosis - 1)/n + 1/(m ln^2 2)); one-sided p.

    Null: the residual is white (flat spectrum), so both estimate one variance. Broadband model
    error concentrated below the band (shaft orders, drift) raises the variance only."""
    x = np.asarray(x, dtype=float) - np.mean(x)
    n = x.size
    P = np.abs(np.fft.rfft(x)) ** 2 / n
    f = np.fft.rfftfreq(n)
    sel = (f >= band[0]) & (f <= band[1])
    m = int(sel.sum())
    var = float(np.mean(x * x))
    if m < 8 or var == 0:
        return {"statistic": 0.0, "p_value": 1.0, "sigma": math.sqrt(var), "ratio": 1.0}
    s2 = float(np.median(P[sel]) / math.log(2))
    kurt = float(np.mean(x**4) / var**2)
    sd = math.sqrt(max(kurt - 1, 0.5) / n + 1.0 / (m * math.log(2) ** 2))
    z = math.log(var / max(s2, 1e-300)) / sd
    return {"statistic": z, "p_value": float(norm_sf(z)), "sigma": math.sqrt(s2),
            "ratio": var / max(s2, 1e-300)}


LINE_RATIO = 10.0  # a periodogram bin this many times its neighbourhood's median is a line
LINE_NEIGHBOURS = 25  # bins each side of the neighbourhood


def _neighbourhood_median(P):
    """Per periodogram bin, the median of its +-LINE_NEIGHBOURS bins (reflected at the ends)."""
    pad = np.pad(P, LINE_NEIGHBOURS, mode="reflect")
    return np.median(np.lib.stride_tricks.sliding_window_view(pad, 2 * LINE_NEIGHBOURS + 1), axis=1)


def broadband_sigma(x) -> float:
    """Standard deviation of x without its narrow spectral lines: the periodogram bins above
    LINE_RATIO x the median of their +-LINE_NEIGHBOURS bins are removed (a line -- a synchronous
    or non-synchronous sinusoid, a model misfit at a few orders -- stands out of its neighbours; a
    smooth noise spectrum, white or coloured (AR(1), 1/f, a damped resonance wider than the
    neighbourhood), does not). Under white Gaussian noise a bin exceeds 10 x the median (6.9 x the
    mean) with probability e^-6.9 = 0.1 %, so the estimate is low by ~0.4 % of sigma."""
    x = np.asarray(x, dtype=float) - np.mean(x)
    n = x.size
    win = np.hanning(n)   # a line between bins leaks into a few bins, not into all (rectangular: 1/k)
    P = np.abs(np.fft.rfft(x * win)) ** 2
    if P.size < 2 * LINE_NEIGHBOURS + 2:
        return float(np.std(x))
    keep = P <= LINE_RATIO * _neighbourhood_median(P)
    keep[:2] = True   # the mean was removed (the window spreads it over bins 0 and 1)
    w = np.where(np.arange(P.size) == 0, 1.0, 2.0)   # one-sided spectrum
    if n % 2 == 0:
        w[-1] = 1.0
    return float(math.sqrt(np.sum(w * P * keep) / (n * np.sum(win ** 2))))


def kurtosis_test(x) -> dict:
    """Heavy tails (positive excess kurtosis, D'Agostino's test, one-sided). Null: Gaussian noise
    (independent samples; valid from n = 20, and after a least-squares fit of a few parameters,
    which leaves the residual's shape unchanged to O(p/n)). Reported, not part of the verdict:
    heavy tails alone are spikes *or* non-Gaussian noise; a spike train that repeats with the
    shaft is what the synchronous F-test decides.

    On thousands of samples the test rejects at a single outlier (one friction reversal the fit
    moved by part of a sample), so its size is reported too: `excess_rms`, the RMS the tails add
    above the noise, sqrt(var - sigma_mad^2), sigma_mad = 1.4826 x the median absolute deviation
    (spikes inflate the variance, not the median). Under the null it is ~ n^(-1/4) sigma."""
    x = np.asarray(x, dtype=float)
    if x.size < 20 or np.var(x) == 0:
        return {"statistic": 0.0, "p_value": 1.0, "excess": 0.0, "excess_rms": 0.0, "mad_sigma": float(np.std(x))}
    b2 = _moment_ratio(x)
    z = _anscombe_glynn(b2, x.size)
    mad = 1.4826 * float(np.median(np.abs(x - np.median(x))))
    return {"statistic": z, "p_value": float(norm_sf(z)), "excess": b2 - 3.0,
            "excess_rms": math.sqrt(max(float(np.var(x)) - mad * mad, 0.0)), "mad_sigma": mad}


def _moment_ratio(x) -> float:
    """Pearson's kurtosis m4 / m2^2 (biased central moments; scipy.stats.kurtosis(fisher=False))."""
    d = x - np.mean(x)
    d2 = d * d
    m2, m4 = float(np.mean(d2)), float(np.mean(d2 * d2))
    return m4 / (m2 * m2)


def _anscombe_glynn(b2: float, n: int) -> float:
    """The normal deviate of Pearson's kurtosis b2 of n Gaussian samples (Anscombe & Glynn 1983,
    eqs. 1-5; scipy.stats.kurtosistest's statistic, here without importing scipy.stats: ~0.7 s of
    every diagnosis)."""
    E = 3.0 * (n - 1) / (n + 1)
    varb2 = 24.0 * n * (n - 2) * (n - 3) / ((n + 1) * (n + 1.0) * (n + 3) * (n + 5))
    x = (b2 - E) / math.sqrt(varb2)
    sqrtbeta1 = 6.0 * (n * n - 5 * n + 2) / ((n + 7) * (n + 9)) * math.sqrt(
        (6.0 * (n + 3) * (n + 5)) / (n * (n - 2) * (n - 3)))
    A = 6.0 + 8.0 / sqrtbeta1 * (2.0 / sqrtbeta1 + math.sqrt(1 + 4.0 / sqrtbeta1 ** 2))
    denom = 1 + x * math.sqrt(2 / (A - 4.0))
    if denom == 0:
        return float("nan")
    term2 = math.copysign(((1 - 2.0 / A) / abs(denom)) ** (1 / 3), denom)
    return (1 - 2 / (9.0 * A) - term2) / math.sqrt(2 / (9.0 * A))


VERDICT_DETECTORS = ("runs_test", "ljung_box", "synchronous_f", "noise_level")


def detectors(x, angle, fitted: int = 0) -> dict:
    """Every detector on one measurement's residual x with the fitted rotor angle."""
    return {"runs_test": runs_test(x), "ljung_box": ljung_box(x, fitted=fitted),
            "synchronous_f": synchronous_f_test(x, angle), "noise_level": high_frequency_noise(x),
            "kurtosis": kurtosis_test(x)}


def combined_p(per_measurement: list) -> dict:
    """Each verdict detector's p over several measurements (Bonferroni over them: each file is
    tested on its own, so concatenation seams and different noise levels raise no false alarm),
    and the family's p (Bonferroni over the detectors)."""
    K = len(per_measurement)
    out = {d: min(1.0, K * min(m[d]["p_value"] for m in per_measurement)) for d in VERDICT_DETECTORS}
    out["family"] = min(1.0, len(VERDICT_DETECTORS) * min(out[d] for d in VERDICT_DETECTORS))
    return out


def systematic_rms(x, det: dict) -> float:
    """RMS of the part of x that is not white noise: variance above the noise variance (the smaller
    of the within-angle-bin and the high-frequency estimates)."""
    x = np.asarray(x, dtype=float)
    noise = det["noise_level"]["sigma"] ** 2
    if det["synchronous_f"]["applicable"]:
        noise = min(noise, det["synchronous_f"]["within_var"])
    return math.sqrt(max(float(np.var(x)) - noise, 0.0))


def _synchronous_power(t, y, w, bins):
    """Between-bin sum of squares of y binned by the angle w t mod 2 pi (y has zero mean)."""
    idx = np.minimum((np.mod(w * t, 2 * math.pi) * (bins / (2 * math.pi))).astype(int), bins - 1)
    c = np.bincount(idx, minlength=bins)
    s = np.bincount(idx, weights=y, minlength=bins)
    return float(np.sum(s[c > 0] ** 2 / c[c > 0]))


NOMINAL_SYNCHRONY_RATIO = 2.0  # see _vane_scan_leaked


def _vane_scan_leaked(t, y, out, nominal, bins=32) -> bool:
    """Whether a vane-passage scan's speed is the leakage of a strong tone at another shaft order
    rather than vane-order content: the whole record is then far less shaft-synchronous at that
    speed than at the nominal (the revolution average's power, NOMINAL_SYNCHRONY_RATIO x less).
    The independent concentric 4-vane rig (its vane orders carry almost nothing) with a 1.6 %
    order-2 speed ripple: the scan took +1.45 % from leakage, where the revolution average holds
    0.1 % of the variance against 95 % at the nominal. A true speed 0.3 % off the nominal on the
    reduced grid's rigs (1001 samples): the nominal at most 1.10 x more synchronous (sampling and
    noise), never 2 x. t from 0, y centred (synchronous_speed_scan)."""
    at_scan = _synchronous_power(t, y, out["speed"], bins)
    return _synchronous_power(t, y, nominal, bins) > NOMINAL_SYNCHRONY_RATIO * at_scan


def synchronous_speed_scan(t, y, lower, upper, nominal, alpha=1e-3, order=1) -> dict:
    """The shaft speed in [lower, upper] that makes y most shaft-synchronous: the between-bin power
    of y averaged over revolutions in the angle domain, maximised over a grid fine enough that
    the phase of the highest resolved order drifts < pi/2 over the record, then refined with finer
    bins. The best speed is used only when its synchronous F-test beats alpha / (grid points)
    (Bonferroni over the scan); otherwise the nominal speed is returned. Assumes a constant speed
    over the record. A torque that does not depend on the rotor angle (concentric housing) gives
    no evidence and keeps the nominal.

    order: only shaft orders that are multiples of it count (the average is taken over 1/order of
    a revolution: the vane passage of `order` identical, equally spaced vanes)."""
    t = np.asarray(t, dtype=float) - t[0]
    y = np.asarray(y, dtype=float) - np.mean(y)
    if order != 1:
        out = synchronous_speed_scan(t, y, order * lower, order * upper, order * nominal, alpha)
        out = {**out, "speed": out["speed"] / order}
        if out["refined"] and _vane_scan_leaked(t, y, out, nominal):
            out = {**out, "speed": float(nominal), "refined": False}
        return out
    T = max(t[-1], 1e-12)
    n = y.size
    spr = n / max(nominal * T / (2 * math.pi), 1e-9)  # samples per revolution
    bins = 32
    step = math.pi / (bins * T)  # order bins/2 drifts by pi/2 from one grid point to the next
    grid = np.arange(lower, upper + 0.5 * step, step)
    grid = np.append(grid, nominal)
    power = np.array([_synchronous_power(t, y, w, bins) for w in grid])
    best = float(grid[int(np.argmax(power))])
    total = float(y @ y)
    k = bins - 1
    F = (power.max() / k) / max((total - power.max()) / max(n - bins, 1), 1e-300)
    p = float(f_sf(F, k, max(n - bins, 1)))
    if not np.isfinite(p) or p * grid.size >= alpha or spr < 8:
        return {"speed": float(nominal), "p_value": p, "grid": int(grid.size), "refined": False}
    top = min(int(spr), 720)
    while bins < top:  # finer bins resolve higher orders: narrower peaks
        bins, step = min(4 * bins, top), step / 4
        local = best + step * np.arange(-8, 9)
        local = local[(local >= lower) & (local <= upper)]
        best = float(local[int(np.argmax([_synchronous_power(t, y, w, bins) for w in local]))])
    return {"speed": best, "p_value": p, "grid": int(grid.size), "refined": True}



ORDER_LINE_SIGMAS = 3.0  # a line's frequency this many of its standard errors from k: not at k


def _line_frequency(y, S, R, k) -> tuple:
    """The frequency (orders) of the largest periodogram value of y (S samples per revolution, R
    revolutions) within one bin of order k, on a grid of an eighth of a bin refined by a parabola
    through the log powers; None when the largest lies at the window's edge (a line outside)."""
    f = k + np.arange(-8, 9) / (8.0 * R)
    n = np.arange(y.size)
    P = np.abs(np.exp(-2j * math.pi * np.outer(f, n) / S) @ y) ** 2
    j = int(np.argmax(P))
    if j in (0, f.size - 1):
        return None, float(P[j])
    lo, mid, hi = np.log(np.maximum(P[j - 1:j + 2], 1e-300))
    shift = 0.5 * (lo - hi) / min(lo - 2 * mid + hi, -1e-300)
    return float(f[j] + shift / (8.0 * R)), float(P[j])


SYNCHRONOUS_SHARE = 0.5  # see order_lines


def _synchronous_line_share(P, R) -> float:
    """The share of the narrow lines' power that lies at integer shaft orders (bins q R) in the
    periodogram P of a record of R whole revolutions; 1 when no bin is a line (nothing says that
    the record is not shaft-locked; an order's own test may still find a weaker line). A line: a bin above
    its +-LINE_NEIGHBOURS bins' median times ln(bins / 0.01) / ln 2 (white noise puts a bin there
    with probability 0.01 / bins: in 1 % of records one bin of the whole record), its power less
    that median."""
    if P.size < 2 * LINE_NEIGHBOURS + 2:
        return 1.0
    local = _neighbourhood_median(P)
    excess = np.where(P > math.log(P.size / 0.01) / math.log(2) * local, P - local, 0.0)
    excess[0] = 0.0  # the mean
    total = float(excess.sum())
    return float(excess[::R].sum()) / total if total > 0 else 1.0


def order_lines(x, angle, orders, alpha) -> dict:
    """Integer shaft orders at which x holds a line of its own: the detector that lets the discrepancy
    workflow try a speed ripple above the library's orders (motor cogging, commutation ripple).

    x is resampled (linear interpolation) on a uniform grid of the rotor angle over a whole number R
    of revolutions -- the speed may vary -- so order q falls on Fourier bin q R exactly, and the m
    bins within half an order of an integer order k are non-integer orders. A line AT order k:
    (1) its bin's power rho times the mean power of those neighbours, F = rho ~ F(2, 2m) under
    Gaussian noise with a locally flat spectrum (white, or coloured and smooth over an order), p
    below alpha / len(orders) (Bonferroni over the orders examined); (2) its bin is the largest
    within half an order, and (3) the line's own frequency, the periodogram's peak within one bin,
    lies within ORDER_LINE_SIGMAS of its standard error (Cramer-Rao for one sinusoid in white
    noise: sqrt(3) / (2 pi R sqrt(rho)) orders) plus a sixteenth of a bin (the peak search's
    resolution) of k. A non-integer line -- a gear ripple, hum, a pulse train's comb at 1.37 x shaft
    (order 10.96 on 9 revolutions: 0.36 bin from 11, 6 standard errors at SNR 5) -- fails (2) or
    (3), and (4) the record's narrow lines (periodogram bins above LINE_RATIO x their neighbourhood's
    median) hold at least SYNCHRONOUS_SHARE of their power at integer orders: a pulse train's comb
    has members within a bin of an integer order (1.374 x 8 = 10.993 on 9 revolutions: 0.06 bin,
    inside the line's own frequency error), a shaft-locked residual has (almost) only integer-order
    lines (cogging records: 0.996-1.000; pulse trains, hum, gear ripple, drift: 0.00). Assumes a monotonic angle and R >= 4; orders within an order of half the resampled rate
    are not examined."""
    x = np.asarray(x, dtype=float)
    a = np.asarray(angle, dtype=float)
    out = {"orders": [], "examined": [], "p_values": {}, "frequencies": {}, "revolutions": 0}
    if a.size > 1 and a[-1] < a[0]:
        a = -a  # reverse rotation: the same orders
    if x.size < 16 or a.size != x.size or not np.all(np.diff(a) > 0):
        return out
    turns = (a[-1] - a[0]) / (2 * math.pi)
    R = int(turns)
    S = int(x.size / turns)  # samples per revolution, about the record's own density
    if R < 4 or S < 8:
        return out
    y = np.interp(a[0] + np.arange(R * S) * (2 * math.pi / S), a, x)
    y -= y.mean()
    P = np.abs(np.fft.rfft(y)) ** 2
    J = R // 2  # bins within half an order
    examined = [int(k) for k in orders if (k + 1) * R + J < P.size]
    share = _synchronous_line_share(P, R)
    out.update(examined=examined, revolutions=R, synchronous_share=share)
    off = np.r_[-J:0, 1:J + 1]
    for k in examined:
        nb = P[k * R + off]
        rho = P[k * R] / max(float(nb.mean()), 1e-300)
        p = float(f_sf(rho, 2, 2 * off.size))
        out["p_values"][k] = p
        if p >= alpha / len(examined) or P[k * R] < nb.max() or share < SYNCHRONOUS_SHARE:
            continue
        f, peak = _line_frequency(y, S, R, k)
        out["frequencies"][k] = f
        tol = ORDER_LINE_SIGMAS * math.sqrt(3) / (2 * math.pi * R * math.sqrt(peak / nb.mean())) + 1 / (16 * R)
        if f is not None and abs(f - k) <= tol:
            out["orders"].append(k)
    return out


def noise_sigma(residual, order: int = 1) -> float:
    """Robust white-noise sigma of a residual: 1.4826 x the median absolute deviation of its
    differences of `order` / sqrt(binomial(2 order, order)) (a k-th difference of white noise has
    that many times its variance: 2 for first, 20 for third differences; a smooth systematic part
    hardly enters them -- a sinusoid n samples a period as (2 pi / n)^order of its size --; the
    few step spikes do not move a median)."""
    d = np.diff(np.asarray(residual, dtype=float), order)
    if d.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(math.comb(2 * order, order)))


def quantization_step(x) -> float:
    """The grid step the samples lie on (an ADC's counts, a logger's rounding), or 0.0: the
    smallest change between samples, when 99 % of the changes are whole multiples of it."""
    d = np.abs(np.diff(np.asarray(x, dtype=float)))
    d = d[d > 0]
    if d.size < QUANTIZATION_MIN_STEPS:
        return 0.0
    q = float(d.min())
    k = d / q
    on_grid = np.abs(k - np.round(k)) <= QUANTIZATION_TOL
    return q if on_grid.mean() >= QUANTIZATION_SHARE else 0.0


QUANTIZATION_MIN_STEPS = 10
QUANTIZATION_TOL = 1e-3  # of a step: the file's decimal rounding of the multiples
QUANTIZATION_SHARE = 0.99


def rounding_sigma(x) -> float:
    """The sigma of a channel's rounding to its grid (quantization_step^2 / 12); 0.0 off a grid."""
    return quantization_step(x) / math.sqrt(12.0)


def measured_noise(x) -> float:
    """The white-noise sigma a measured channel carries: the robust first-difference sigma
    (noise_sigma) and the rounding of its grid (q^2 / 12), which the differences miss when the
    channel changes by less than a step between samples (most differences then 0)."""
    return math.hypot(noise_sigma(x, order=1), rounding_sigma(x))


def isolated_spikes(x, sigmas: float) -> np.ndarray:
    """Indices of single samples more than `sigmas` noise sigmas (measured_noise, which holds what
    the sampling aliases of a ripple) off their neighbours' mean while the two neighbours agree
    (their difference under a quarter of the departure): a logger's glitch, not a transient (a
    step or an inrush moves a neighbour too). Empty when more than SPIKE_SHARE of the samples
    answer: then the signal itself has such features."""
    x = np.asarray(x, dtype=float)
    sigma = measured_noise(x)
    if x.size < 3 or sigma == 0.0:
        return np.zeros(0, dtype=int)
    dev = x[1:-1] - 0.5 * (x[:-2] + x[2:])
    hit = (np.abs(dev) > sigmas * sigma) & (np.abs(x[2:] - x[:-2]) < 0.25 * np.abs(dev))
    idx = np.nonzero(hit)[0] + 1
    return idx if idx.size <= SPIKE_SHARE * x.size else np.zeros(0, dtype=int)


SPIKE_SHARE = 0.05


def speed_column_disagreement(column, time, theta, speed, order, ripple, ripple_cov) -> dict | None:
    """Does a measured speed column agree with a hypothesised shaft-speed ripple? The ripple
    (rc, rs) makes omega = speed (1 + rc cos(k theta) - rs sin(k theta)) (theta the nominal angle
    at the samples); the column's own order-k coefficients come from a least-squares fit of its
    deviation from its mean, with the column noise taken as white (robust sigma of its third
    differences, which a smooth ripple hardly enters). chi-square of the difference on 2 dof with
    both covariances (the torque fit's and the column's). None without a usable column."""
    s = np.asarray(column, dtype=float)
    if s.size < 16 or not np.all(np.isfinite(s)):
        return None
    d = s - s.mean()
    kth = order * np.asarray(theta, dtype=float)
    X = speed * np.column_stack([np.cos(kth), -np.sin(kth)])
    X = X - X.mean(axis=0)
    beta, *_ = np.linalg.lstsq(X, d, rcond=None)
    sigma = noise_sigma(s, order=3)
    cov = sigma**2 * np.linalg.pinv(X.T @ X) + np.asarray(ripple_cov, dtype=float)
    delta = np.asarray(ripple, dtype=float) - beta
    chi2 = float(delta @ np.linalg.pinv(cov) @ delta) if np.any(cov) else (math.inf if np.any(delta) else 0.0)
    return {"statistic": chi2, "p_value": float(chi2_sf(chi2, 2)), "column": beta.tolist(),
            "column_sigma": float(sigma), "hypothesis": list(map(float, ripple))}
