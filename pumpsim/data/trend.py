"""The measured speed's slow variation (a drifting motor): a Legendre trend chosen by BIC and
kept when an F-test finds it significant against the column's noise."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..distributions import f_sf

TREND_MAX_DEGREE = 20  # Legendre degrees tried for the speed column's trend (BIC chooses; a run-up needs ~18)
TREND_ALPHA = 1e-3  # F-test level at which the trend counts as significant against the column's noise
TREND_REVOLUTIONS_PER_DEGREE = 2.0  # a degree per two revolutions at most: the trend stays below order 1


@dataclass(frozen=True)
class SpeedTrend:
    """The slow part of a measured speed column: omega_s(t) = sum c_j P_j(x), x = 2 t / span - 1
    (Legendre polynomials, t from the first sample), fitted by least squares. `mean` is the mean of
    the column (= the mean of omega_s over the samples: the fit has a constant term); `degree` was
    chosen by BIC and `p_value` is the F-test of that fit against a constant.

    Assumptions: the column is the shaft speed plus noise that is white and much faster than the
    trend, and any shaft-synchronous speed ripple (orders >= 1) is left to the model's ripple --
    a polynomial of at most one degree per two revolutions cannot follow it."""

    coef: np.ndarray
    span: float
    mean: float
    degree: int
    p_value: float

    def _x(self, t):
        return 2.0 * np.asarray(t, dtype=float) / self.span - 1.0

    def speed(self, t) -> np.ndarray:
        return np.polynomial.legendre.legval(self._x(t), self.coef)

    def acceleration(self, t) -> np.ndarray:
        return np.polynomial.legendre.legval(self._x(t), np.polynomial.legendre.legder(self.coef)) * 2 / self.span

    def warped_time(self, t) -> np.ndarray:
        """tau(t) = integral_0^t omega_s / mean dt': the time at which a rotor at the constant mean
        speed reaches the drifting rotor's angle (tau = t for a constant speed)."""
        integral = np.polynomial.legendre.legint(self.coef, lbnd=-1.0) * self.span / 2
        return np.polynomial.legendre.legval(self._x(t), integral) / self.mean

    def change(self) -> float:
        """Largest minus smallest trend speed over the record, relative to the mean."""
        w = self.speed(np.linspace(0.0, self.span, 201))
        return float((w.max() - w.min()) / abs(self.mean))


def speed_trend(time, speed) -> SpeedTrend | None:
    """The speed column's slow trend if it is significant against the column's own noise (F-test
    at TREND_ALPHA of the BIC-chosen Legendre fit against a constant), else None: the column is
    constant within its noise and its mean is the speed."""
    if speed is None or len(time) < 20:
        return None
    t = np.asarray(time, dtype=float) - time[0]
    w = np.asarray(speed, dtype=float)
    span, mean = float(t[-1]), float(np.mean(w))
    revolutions = abs(mean) * span / (2 * math.pi)
    top = int(min(TREND_MAX_DEGREE, revolutions / TREND_REVOLUTIONS_PER_DEGREE, (t.size - 2) // 10))
    if top < 1 or span <= 0 or mean == 0 or np.ptp(w) <= 1e-12 * abs(mean):  # a constant column (rounding aside)
        return None
    V = np.polynomial.legendre.legvander(2 * t / span - 1, top)
    fits = [np.linalg.lstsq(V[:, :d + 1], w, rcond=None)[0] for d in range(top + 1)]
    rss = np.array([float(np.sum((w - V[:, :d + 1] @ c) ** 2)) for d, c in enumerate(fits)])
    n = t.size
    bic = n * np.log(np.maximum(rss, 1e-300) / n) + np.arange(1, top + 2) * math.log(n)
    d = int(np.argmin(bic))
    if d == 0:
        return None
    f = ((rss[0] - rss[d]) / d) / (max(rss[d], 1e-300) / (n - d - 1))
    p = float(f_sf(f, d, n - d - 1))  # scipy.stats.f.sf's value, without its ~0.5 s import
    if p >= TREND_ALPHA:
        return None
    return SpeedTrend(fits[d], span, mean, d, p)
