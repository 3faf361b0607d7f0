"""Tail probabilities and quantiles of the test statistics' distributions, from scipy.special.

The same functions scipy.stats evaluates for these distributions (bit for bit), without importing
scipy.stats: that import costs ~0.5 s of every command that fits or diagnoses."""
from __future__ import annotations

from scipy import special


def norm_sf(z):
    """P(Z > z) for a standard normal Z."""
    return special.ndtr(-z)


def chi2_sf(q, dof):
    """P(X > q) for X ~ chi-squared with dof degrees of freedom."""
    return special.chdtrc(dof, q)


def f_sf(x, dfn, dfd):
    """P(F > x) for F ~ F(dfn, dfd)."""
    return special.fdtrc(dfn, dfd, x)


def t_sf(x, dof):
    """P(T > x) for T ~ Student's t with dof degrees of freedom."""
    return special.stdtr(dof, -x)


def t_ppf(p, dof):
    """The p-quantile of Student's t with dof degrees of freedom."""
    return special.stdtrit(dof, p)
