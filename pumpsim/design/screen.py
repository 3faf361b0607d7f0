"""The geometric admissibility of a batch of designs (geometry.geometry_verdict is None) as array
operations, and the housing curve it reads.

Without harmonics the housing is the base ellipse, whose points are a closed form evaluated here
in NumPy over every design at once (codegen/housing.py: r0 = a b / sqrt((b cos)^2 + (a sin)^2) of
the polar angle about the centre, turned by housing.angle). Such a curve is convex (its curvature
sign r0^2 + 2 r0'^2 - r0 r0'' is positive for a, b > 0), so only the rotor circle's clearance is
tested -- with a margin of 1e-12 of the housing's size, far above the rounding (~1e-16) in which
these points and the compiled curve's may differ: a design within the margin is left undecided
and the caller takes it the exact way (the compiled curve, the config's own verdict).
"""
from __future__ import annotations

import math

import numpy as np

from ..tolerances import POSITION_TOL

CLEARANCE_REL = 1e-12  # of the housing's size: what the NumPy points may not decide alone


def housing_samples(P, index: dict, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(alpha (n,), points (B, 2, n), margin (B,)) of the base ellipse of B parameter vectors
    (index: parameter name -> column), at the polar angles housing_check_samples uses."""
    a, b, cx, cy, psi = (P[:, index[k]][:, None] for k in
                         ("housing.a", "housing.b", "housing.center.0", "housing.center.1", "housing.angle"))
    alpha = np.linspace(-math.pi, math.pi, n, endpoint=False)
    if np.all(psi == psi[0]):  # one orientation (the usual case): its angles' sines once
        psi = psi[:1]
    beta = alpha[None, :] - psi
    c, s = np.cos(beta), np.sin(beta)
    r = a * b / np.sqrt((b * c) ** 2 + (a * s) ** 2)
    cp, sp = np.cos(psi), np.sin(psi)
    pts = np.stack([cx + r * (c * cp - s * sp), cy + r * (s * cp + c * sp)], axis=1)
    margin = CLEARANCE_REL * (np.abs(a) + np.abs(b) + np.abs(cx) + np.abs(cy))[:, 0]
    return alpha, pts, margin


def ellipse_clear(P, index: dict, rr, n: int) -> np.ndarray:
    """(B,) bool: the base ellipse of each parameter vector, sampled at n polar angles as
    housing_samples does, surely holds the rotor axis inside its polygon and every sample farther
    than rr (+ the margin) from it -- decided from the ellipse's closed form, no samples. False:
    undecided (the caller tests the samples).

    In the ellipse's axes the rotor axis sits at (u, v) with rho^2 = (u/a)^2 + (v/b)^2. The map
    from the unit circle onto the ellipse stretches no length by less than m = min(a, b), so
    every point of the curve is at least m (1 - rho) from the axis. The samples at polar angles
    2 pi / n apart sit at eccentric anomalies at most 2 pi k / n apart (k = max(a, b) / m, the
    anomaly's largest rate), so their polygon holds the ellipse's copy scaled by cos(pi k / n)
    about its centre, hence the axis when rho < cos(pi k / n), at least m (cos(pi k / n) - rho)
    inside its edges."""
    a, b, cx, cy, psi = (P[:, index[k]] for k in
                         ("housing.a", "housing.b", "housing.center.0", "housing.center.1", "housing.angle"))
    cp, sp = np.cos(psi), np.sin(psi)
    u, v = -(cx * cp + cy * sp), cx * sp - cy * cp
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.sqrt((u / a) ** 2 + (v / b) ** 2)
        m = np.minimum(a, b)
        k = np.maximum(a, b) / m
        cos_gap = np.cos(np.minimum(math.pi * k / n, math.pi / 2))
    margin = CLEARANCE_REL * (np.abs(a) + np.abs(b) + np.abs(cx) + np.abs(cy))
    return (m > 0) & (m * (1.0 - rho) > rr + margin) & (m * (cos_gap - rho) > margin)


def vanes_ok(L, lm, s, res) -> np.ndarray:
    """geometry_verdict's tests of the vane positions over B designs (see geometry_ok)."""
    return extension_ok(L, lm, *position_checks(s, res))


def position_checks(s, res) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(res_ok, s_min, s_max) of B designs' vane extensions s and position residuals res (B, N, n):
    every residual finite and within POSITION_TOL; the extension's extremes."""
    with np.errstate(invalid="ignore"):
        res_ok = np.all(np.isfinite(res), axis=(1, 2)) & ~np.any(res > POSITION_TOL, axis=(1, 2))
    return res_ok, s.min(axis=(1, 2)), s.max(axis=(1, 2))


def extension_ok(L, lm, res_ok, s_min, s_max) -> np.ndarray:
    """vanes_ok from each design's positions verdict res_ok and its extension's extremes."""
    return res_ok & (s_min >= -POSITION_TOL) & (s_max < lm) & (s_min + L > lm)


def geometry_ok(rr, L, lm, pts, curv, s, res, margin=0.0) -> np.ndarray:
    """geometry.geometry_verdict is None, over B designs (rotor radius rr, vane length L, mouth
    depth lm (B,); pts (B, 2, n); curv (B, n), or None for a curve known to be convex; s and res
    (B, N, n), N may be one vane standing for alike ones): each of its tests as one array
    comparison, the rotor's clearance by more than `margin`. A design this rejects gets its
    reason from geometry_verdict itself."""
    return polygon_clear(rr, pts, curv, margin) & vanes_ok(L, lm, s, res)


def polygon_clear(rr, pts, curv, margin=0.0) -> np.ndarray:
    """geometry_verdict's tests of the housing samples over B designs (see geometry_ok)."""
    x, y = pts[:, 0], pts[:, 1]
    above = y > 0.0
    d, i = np.nonzero(above != np.roll(above, 1, axis=1))  # the edges (previous point, point) the x axis cuts
    x1, y1, x0, y0 = x[d, i], y[d, i], x[d, i - 1], y[d, i - 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = (x0 - x1) * (0.0 - y1) / (y0 - y1) + x1
    inside = np.bincount(d[0.0 < xc], minlength=len(x)) % 2 == 1  # geometry._point_in_polygon's rule
    convex = True if curv is None else ~np.any(curv <= 0, axis=1)
    return convex & inside & (np.hypot(x, y).min(axis=1) > rr + margin)


__all__ = ["housing_samples", "ellipse_clear", "vanes_ok", "extension_ok", "position_checks", "polygon_clear", "geometry_ok", "CLEARANCE_REL"]
