"""Standard errors that do not assume a white residual: a Newey-West (Bartlett kernel) sandwich
covariance per channel, from the Jacobian and the residual the fit already has (no model runs).

The white-noise covariance sigma^2 (J'J)^-1 assumes independent errors of one size. A residual that
is correlated from sample to sample -- coloured sensor noise, or a model that does not describe the
measurement to its noise level -- carries fewer independent samples than it has rows, and those
standard errors are too small. The sandwich (J'J)^-1 S (J'J)^-1 replaces sigma^2 J'J by S, the
long-run covariance of the scores g_t = J_t r_t: a Bartlett-weighted sum of their autocovariances up
to a bandwidth chosen from each channel's lag-1 autocorrelation (Andrews 1991, AR(1) plug-in).
Channels (pressure, current, speed of a bench log; the measurements of a joint torque fit) have
their own time axes: lags stay inside a channel, channels add (their cross-covariance is taken as
zero). With a bandwidth that is a large part of the record the long-run covariance is itself
uncertain; the 95 % multiplier is then the fixed-b quantile of Kiefer and Vogelsang (2005) instead
of t's.

What it does not do: a model-form difference (an effect the model lacks, another implementation
of the physics) biases the estimates by a fixed amount. The sandwich treats the misfit as if it
were a random, stationary process; where the systematic residual is larger than the noise, the
interval says so (Intervals.note) rather than claiming to bound that bias.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ..signals import noise_sigma

RHO_MAX = 0.999  # a lag-1 autocorrelation is clipped below 1 (the AR(1) plug-in diverges there)
# a white residual's lag-1 autocorrelation scatters by 1/sqrt(n): above 3.09 of that (one-sided
# p = 0.001) the residual is called structured
STRUCTURE_Z = 3.09
NOTABLE_WIDENING = 1.1  # the note speaks of a widening from this factor on


def lag1(r) -> float:
    """Lag-1 autocorrelation of r about its mean (0 for fewer than 3 samples or a constant)."""
    rc = np.asarray(r, dtype=float)
    rc = rc - rc.mean() if rc.size else rc
    den = float(rc @ rc)
    if rc.size < 3 or den <= 0:
        return 0.0
    return float(np.clip(rc[1:] @ rc[:-1] / den, -RHO_MAX, RHO_MAX))


def bartlett_bandwidth(rho: float, n: int) -> int:
    """Andrews' (1991) AR(1) plug-in lag for the Bartlett kernel: 1.1447 (alpha n)^(1/3) with
    alpha = 4 rho^2 / ((1 - rho)^2 (1 + rho)^2), at most n - 1."""
    if n < 2:
        return 0
    rho = min(abs(rho), RHO_MAX)
    alpha = 4 * rho**2 / ((1 - rho) ** 2 * (1 + rho) ** 2)
    return int(min(n - 1, math.floor(1.1447 * (alpha * n) ** (1 / 3))))


def long_run_covariance(G, lag: int) -> np.ndarray:
    """sum_|l|<=lag (1 - |l|/(lag+1)) Gamma_l of the rows of G (n x k scores): the Bartlett
    triangle is a box convolved with itself, so it is (1/(lag+1)) sum_t B_t B_t' over the sums B_t
    of every window of lag+1 rows (partial windows at the ends included): O(n k^2) at any lag."""
    G = np.asarray(G, dtype=float)
    w = lag + 1
    padded = np.vstack([np.zeros((w, G.shape[1])), G, np.zeros((lag, G.shape[1]))])
    c = np.cumsum(padded, axis=0)
    B = c[w:] - c[:-w]
    return B.T @ B / w


def fixed_b_quantile(b: float) -> float:
    """The 97.5 % quantile of a Bartlett-kernel t statistic with bandwidth b = lag / n (Kiefer and
    Vogelsang 2005, their cubic in b; 1.96 at b = 0)."""
    b = min(max(b, 0.0), 1.0)
    return 1.96 + 2.9694 * b + 0.4160 * b**2 - 0.5324 * b**3


@dataclass
class ChannelStructure:
    """What one channel's residual says about the white-noise assumption."""

    channel: str
    samples: int
    lag1: float  # lag-1 autocorrelation of the residual
    durbin_watson: float  # sum (r_t - r_t-1)^2 / sum r_t^2: 2 for white, towards 0 for smooth
    effective_samples: float  # n (1 - rho) / (1 + rho): the independent samples an AR(1) residual carries
    bandwidth: int  # Bartlett lags of the sandwich
    noise_rms: float  # white floor: robust sigma of the residual's first differences
    residual_rms: float
    systematic_rms: float  # sqrt(residual_rms^2 - noise_rms^2), 0 within the noise
    systematic_share: float  # systematic_rms / RMS of the measured channel about its mean
    structured: bool  # lag-1 autocorrelation above STRUCTURE_Z / sqrt(n)

    @property
    def misses_signal(self) -> bool:
        """The systematic residual is larger than the noise: the model does not describe the channel."""
        return self.structured and self.systematic_rms > self.noise_rms


@dataclass
class Intervals:
    """How the 95 % intervals were made: white-noise or residual-aware, the widening, per channel
    the residual's structure."""

    basis: str  # "white" | "residual-aware": which standard error the intervals use
    widening: float  # largest (residual-aware half-width / white half-width) over the parameters, >= 1
    channels: list = field(default_factory=list)  # [ChannelStructure]
    quantile: dict = field(default_factory=dict)  # parameter -> the multiplier of its interval's s.e.

    def to_json(self) -> dict:
        d = asdict(self)
        d["note"] = self.note()
        return d

    def note(self) -> str | None:
        """What the intervals mean when the residual is not white (None when it is)."""
        parts = []
        structured = [c for c in self.channels if c.structured]
        if structured:
            what = ", ".join(f"{c.channel} (lag-1 autocorrelation {c.lag1:.2f}, Durbin-Watson {c.durbin_watson:.2f},"
                             f" {c.effective_samples:.0f} effective of {c.samples} samples)" for c in structured)
            parts.append(f"the residual is correlated from sample to sample in {what}")
        if self.widening >= NOTABLE_WIDENING:
            why = ("the residual is not independent noise (the model does not describe the data to its noise level, "
                   "or the noise is coloured)" if structured else
                   "the residual's size varies along the record where these parameters act (no correlation found)")
            parts.append(f"the ± and the 95 % intervals use the Newey-West (residual-aware) standard errors, up to "
                         f"{self.widening:.2g}x wider than the white-noise ones: {why}")
        missed = [c for c in self.channels if c.misses_signal]
        if missed:
            parts.append("the residual holds a slow part larger than its white-noise floor in " + ", ".join(
                f"{c.channel} ({c.systematic_rms / max(c.noise_rms, 1e-300):.2g}x the floor, "
                f"{100 * c.systematic_share:.2g} % of its variation)" for c in missed)
                + ": coloured noise, or an effect the model lacks -- for the latter the intervals cover the "
                "misfit only as if it were random, and the bias it leaves in the estimates is bounded by no "
                "interval from this data (the model misses that share of the signal)")
        return "; ".join(parts) if parts else None


def channel_structure(name, r, y) -> ChannelStructure:
    r, y = np.asarray(r, dtype=float), np.asarray(y, dtype=float)
    n = r.size
    rho = lag1(r)
    den = float(r @ r)
    dw = float(np.sum(np.diff(r) ** 2) / den) if den > 0 else 2.0
    noise = noise_sigma(r) if n > 2 else 0.0
    rms = math.sqrt(den / n) if n else 0.0
    sys_rms = math.sqrt(max(rms**2 - noise**2, 0.0))
    spread = float(np.sqrt(np.mean((y - y.mean()) ** 2))) if n else 0.0
    rho_pos = max(rho, 0.0)
    return ChannelStructure(name, n, rho, dw, n * (1 - rho_pos) / (1 + rho_pos), bartlett_bandwidth(rho, n),
                            noise, rms, sys_rms, sys_rms / spread if spread > 0 else 0.0,
                            bool(n > 2 and rho * math.sqrt(n) > STRUCTURE_Z))


def residual_aware(J, r, y, bread, channels=None) -> tuple:
    """The Newey-West sandwich covariance bread S bread (bread = (J'J)^-1 at the fit) with S summed
    over the channels [(name, rows)] in row order (None: one), scaled by n / (n - k); and per
    parameter the fixed-b bandwidth share of the channel that contributes most to its variance.
    Returns (covariance, [ChannelStructure], b per parameter)."""
    J, r, y = np.asarray(J, dtype=float), np.asarray(r, dtype=float), np.asarray(y, dtype=float)
    n, k = J.shape
    channels = list(channels) if channels else [("residual", n)]
    if sum(m for _, m in channels) != n:
        raise ValueError(f"channels hold {sum(m for _, m in channels)} rows, the residual {n}")
    parts, found, lo = [], [], 0
    for name, m in channels:
        sl = slice(lo, lo + m)
        lo += m
        cs = channel_structure(name, r[sl], y[sl])
        found.append(cs)
        S = long_run_covariance(J[sl] * r[sl, None], cs.bandwidth)
        parts.append((bread @ S @ bread, cs.bandwidth / max(m, 1)))
    scale = n / max(n - k, 1)
    cov = sum(p for p, _ in parts) * scale
    diag = np.array([np.diag(p) for p, _ in parts])  # channels x parameters
    b = np.array([parts[int(np.argmax(diag[:, i]))][1] for i in range(k)]) if parts else np.zeros(k)
    return cov, found, b
