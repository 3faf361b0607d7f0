"""Geometric admissibility (spec §1): rotor inside a convex housing, every vane reaches it with its
bottom end inside the slot and its tip outside the rotor, at every rotor angle."""
from __future__ import annotations

import math

import numpy as np

from .config import PumpConfig, as_array
from .errors import ConfigError
from .kernels import load_kernels
from .tolerances import POSITION_TOL

HOUSING_SAMPLES = 2048
ANGLE_SAMPLES = 720


def housing_samples(kern, p, n=HOUSING_SAMPLES):
    alpha = np.linspace(-math.pi, math.pi, n, endpoint=False)
    pt, _, _, curv = kern.mapped("housing_curve", n)(alpha[None, :], p.reshape(-1, 1))
    return alpha, np.asarray(pt), np.asarray(curv).ravel()


def vane_positions(kern, p, theta):
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    s, alpha, res = kern.mapped("positions", theta.size)(theta[None, :], p.reshape(-1, 1))
    N = kern.structure.vanes
    return (np.asarray(s).reshape(N, -1, order="F"), np.asarray(alpha).reshape(N, -1, order="F"),
            np.asarray(res).reshape(N, -1, order="F"))


def mouth_depth(values) -> float:
    rb, beta, Rr = values["rotor.slot_radius"], values["rotor.slot_tilt"], values["rotor.radius"]
    return -rb * math.cos(beta) + math.sqrt(Rr**2 - rb**2 * math.sin(beta) ** 2)


def slot_room(R, vanes: int):
    """The widest slot a rotor of radius R holds: neighbouring slots' mouths on its surface are
    2 R sin(pi/N) apart (the rotor's diameter for one vane); scalars or arrays."""
    return 2 * R * np.sin(np.pi / vanes) if vanes > 1 else 2 * R


def slots_verdict(v, vanes: int) -> str | None:
    """Why the slots do not fit the rotor (None if they do): slots vane.thickness wide whose mouths
    overlap leave no rotor between them."""
    h, R = v["vane.thickness"], v["rotor.radius"]
    room = float(slot_room(R, vanes))
    if h >= room:
        where = (f"the mouths of the {vanes} slots on the rotor's surface are {room:.4g} m apart"
                 if vanes > 1 else f"the rotor is {room:.4g} m across")
        return (f"vane.thickness {h:g} m does not fit: {where}, so slots that wide leave no rotor "
                "between them (check vane.thickness and rotor.radius)")
    return None


def check_geometry(cfg: PumpConfig) -> None:
    pv = cfg.parameters("constrained")
    kern = load_kernels(pv.structure)
    p = as_array(pv)
    alpha, pts, curv = housing_samples(kern, p)
    theta = np.linspace(0, 2 * math.pi, ANGLE_SAMPLES, endpoint=False)
    s, _, res = vane_positions(kern, p, theta)
    verdict = geometry_verdict(pv.values, alpha, pts, curv, theta, s, res)
    if verdict:
        raise ConfigError(verdict)


def geometry_verdict(v, alpha, pts, curv, theta, s, res) -> str | None:
    """Why the geometry is not admissible (None if it is), from housing samples (polar angles
    alpha, points pts (2, n), curvature) and the vane positions s, residuals res (N, len(theta))."""
    slots = slots_verdict(v, s.shape[0])
    if slots:
        return slots
    if np.any(curv <= 0):
        i = int(np.argmin(curv))
        return (f"housing is not convex at housing polar angle {alpha[i]:.3f} rad "
                "(reduce housing.harmonics amplitudes)")
    dist = np.hypot(pts[0], pts[1])
    i = int(np.argmin(dist))
    # the rotor axis must be inside and the rotor circle strictly inside the housing
    inside = _point_in_polygon(0.0, 0.0, pts[0], pts[1])
    if not inside or dist[i] <= v["rotor.radius"]:
        return (f"rotor circle (rotor.radius {v['rotor.radius']:.4f} m) must lie strictly "
                f"inside the housing; the housing comes to {dist[i]:.4g} m from the rotor axis "
                f"at housing polar angle {alpha[i]:.3f} rad (check housing.center)")
    lm, L = mouth_depth(v), v["vane.length"]
    if np.any(~np.isfinite(res)) or np.nanmax(res) > POSITION_TOL:
        j = np.unravel_index(np.nanargmax(np.where(np.isfinite(res), res, np.inf)), res.shape)
        return f"vane {j[0]} does not reach the housing at rotor angle {theta[j[1]]:.3f} rad"
    if s.min() < -POSITION_TOL:  # s = 0 (on the slot bottom) is allowed; its rounding is not a verdict
        j = np.unravel_index(np.argmin(s), s.shape)
        return (f"vane.length {L:.4f} m is too long: at rotor angle {theta[j[1]]:.3f} rad "
                f"vane {j[0]} would need s = {s[j]:.5f} m < 0 (below the slot bottom) "
                "to fit inside the housing")
    if s.max() >= lm:
        j = np.unravel_index(np.argmax(s), s.shape)
        return (f"vane.length {L:.4f} m is too short: at rotor angle {theta[j[1]]:.3f} rad "
                f"vane {j[0]} needs s = {s[j]:.5f} m >= slot depth {lm:.5f} m (its bottom end "
                "would leave the slot)")
    if (s + L).min() <= lm:
        j = np.unravel_index(np.argmin(s), s.shape)
        return (f"vane tip does not stand out of the rotor: at rotor angle {theta[j[1]]:.3f} rad "
                f"vane {j[0]} has s + vane.length = {s[j] + L:.5f} m <= slot depth {lm:.5f} m")
    return None


def _point_in_polygon(x, y, px, py) -> bool:
    """Even-odd rule: count the polygon edges a ray from (x, y) towards +x crosses."""
    px, py = np.asarray(px), np.asarray(py)
    qx, qy = np.roll(px, 1), np.roll(py, 1)  # the previous vertex of each edge
    spans = (py > y) != (qy > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = (qx - px) * (y - py) / (qy - py) + px
    return bool(np.count_nonzero(spans & (x < xc)) % 2)
