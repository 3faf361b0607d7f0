"""Tail probabilities and quantiles of the test statistics' distributions, and the sampled keys'
distributions (`Marginal`), from scipy.special.

The same functions scipy.stats evaluates for these distributions (bit for bit), without importing
scipy.stats: that import costs ~0.5 s of every command that fits, diagnoses or samples. scipy.special
itself (~0.1 s) is imported on first use, so that a module which only names these functions costs
a command's start nothing."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def _special():
    from scipy import special

    return special


def norm_sf(z):
    """P(Z > z) for a standard normal Z."""
    return _special().ndtr(-z)


def chi2_sf(q, dof):
    """P(X > q) for X ~ chi-squared with dof degrees of freedom."""
    return _special().chdtrc(dof, q)


def f_sf(x, dfn, dfd):
    """P(F > x) for F ~ F(dfn, dfd)."""
    return _special().fdtrc(dfn, dfd, x)


def t_sf(x, dof):
    """P(T > x) for T ~ Student's t with dof degrees of freedom."""
    return _special().stdtr(dof, -x)


def t_ppf(p, dof):
    """The p-quantile of Student's t with dof degrees of freedom."""
    return _special().stdtrit(dof, p)


@dataclass(frozen=True)
class Marginal:
    """One of scipy.stats' frozen `norm(loc, scale)`, `uniform(loc, scale)`, `lognorm(s, scale=scale)`
    or `truncnorm(a, b, loc, scale)` (shape: () or (s,) or (a, b)): its support and its quantile
    function at q in (0, 1), evaluated in scipy's own steps (rv_continuous.ppf: the standard
    distribution's quantile * scale + loc, on 1-D arrays), so the values are scipy's to the bit."""

    kind: str  # "norm", "uniform", "lognorm" or "truncnorm"
    loc: float
    scale: float
    shape: tuple = ()

    def support(self) -> tuple:
        lo, hi = {"norm": (-math.inf, math.inf), "uniform": (0.0, 1.0), "lognorm": (0.0, math.inf),
                  "truncnorm": self.shape}[self.kind]
        return (np.float64(lo) * self.scale + self.loc, np.float64(hi) * self.scale + self.loc)

    def ppf(self, q):
        q = np.asarray(q, dtype=float)
        if not np.all((q > 0) & (q < 1)):
            raise ValueError("Marginal.ppf takes probabilities in (0, 1)")
        flat = np.atleast_1d(q).ravel()
        shape = tuple(np.full_like(flat, s) for s in self.shape)
        out = (self._standard_ppf(flat, *shape) * self.scale + self.loc).reshape(q.shape)
        return out[()] if out.ndim == 0 else out

    def _standard_ppf(self, q, *shape):
        if self.kind == "uniform":
            return q  # (no scipy.special: a study of bounds alone is read without it)
        special = _special()
        if self.kind == "norm":
            return special.ndtri(q)
        if self.kind == "lognorm":
            return np.exp(shape[0] * special.ndtri(q))
        return _truncnorm_ppf(special, q, *shape)


# scipy.stats' truncnorm quantile (scipy/stats/_continuous_distns.py, BSD licence), step for step:
# the log of the normal mass below the quantile, from the side where it is accurate

def _truncnorm_ppf(sc, q, a, b):
    left = a < 0
    out = np.empty_like(q)
    if left.any():
        ql, al, bl = q[left], a[left], b[left]
        out[left] = sc.ndtri_exp(_log_sum(sc, sc.log_ndtr(al), np.log(ql) + _log_gauss_mass(sc, al, bl)))
    right = ~left
    if right.any():
        qr, ar, br = q[right], a[right], b[right]
        out[right] = -sc.ndtri_exp(_log_sum(sc, sc.log_ndtr(-br), np.log1p(-qr) + _log_gauss_mass(sc, ar, br)))
    return out


def _log_sum(sc, log_p, log_q):
    return sc.logsumexp([log_p, log_q], axis=0)


def _log_gauss_mass(sc, a, b):
    """Log of the standard normal's mass in [a, b]: worked in the left tail (the right mirrored), the
    central case as log1p of the two tails."""
    def left_case(a, b):
        return sc.logsumexp([sc.log_ndtr(b), sc.log_ndtr(a) + np.pi * 1j], axis=0)  # log(e^p - e^q)

    case_left, case_right = b <= 0, a > 0
    central = ~(case_left | case_right)
    out = np.full_like(a, fill_value=np.nan, dtype=np.complex128)
    if a[case_left].size:
        out[case_left] = left_case(a[case_left], b[case_left])
    if a[case_right].size:
        out[case_right] = left_case(-b[case_right], -a[case_right])
    if a[central].size:
        out[central] = sc.log1p(-sc.ndtr(a[central]) - sc.ndtr(-b[central]))
    return np.real(out)
