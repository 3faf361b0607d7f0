"""The housing curve (spec §1), symbolic in its polar angle alpha about the housing centre: the one
base curve the kernels compile, in one place.

r(alpha) = r0(alpha - psi) + sum_j A_j cos(k_j (alpha - psi - gamma_j)), with r0 the polar radius of
an ellipse with semi-axes a, b about its centre (a circle when a = b). The inward normal is
n = z x T/|T| with T = dC/dalpha (the curve runs counter-clockwise).

Every housing shape of the registry (pumpsim/model_spec/housings.py) sets this curve's parameters;
the base curve's closed forms (its radius, its sector area, where a ray meets it) are the functions
below, written once for SymPy and CasADi alike (`ops` is the `sympy` or the `casadi` module).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import sympy as sp

# the curve's symbols and the compiled parameters they stand for, in the kernels' order
CURVE_PARAMETERS = {"a": "housing.a", "b": "housing.b", "cx": "housing.center.0",
                    "cy": "housing.center.1", "psi": "housing.angle"}
HARMONIC_FIELDS = ("order", "amplitude", "phase")  # k_j, A_j, gamma_j
TWO_PI = 2 * math.pi


def parameter_names(harmonic_slots: int) -> list[str]:
    """The compiled parameters of the curve, in the order of `HousingCurve.symbols`."""
    names = list(CURVE_PARAMETERS.values())
    for j in range(harmonic_slots):
        names += [f"housing.harmonics.{j}.{f}" for f in HARMONIC_FIELDS]
    return names


def base_radius(a, b, alpha, psi, ops):
    """The base ellipse's polar radius about its centre at polar angle alpha."""
    return a * b / ops.sqrt((b * ops.cos(alpha - psi)) ** 2 + (a * ops.sin(alpha - psi)) ** 2)


def base_sector_area(a, b, psi, alpha0, alpha1, full_turn, ops):
    """1/2 int r0^2 dalpha over [alpha0, alpha1] (counter-clockwise) of the base ellipse: the sector
    area (ab/2) [atan2(a sin beta, b cos beta)], beta = alpha - psi; a full turn is 2 pi."""
    def angle(al):
        return ops.atan2(a * ops.sin(al - psi), b * ops.cos(al - psi))

    d_theta = angle(alpha1) - angle(alpha0)
    d_theta = d_theta - TWO_PI * ops.floor(d_theta / TWO_PI)
    if full_turn:
        d_theta = TWO_PI + 0.0 * d_theta
    return 0.5 * a * b * d_theta


def base_ray(dx, dy, ux, uy, a, b, ops):
    """lambda >= 0 where the ray d + lambda u (in the ellipse's own axes, from its centre) meets
    the base ellipse: the larger root of the quadratic (clamped to a tangent ray)."""
    ia2, ib2 = 1 / a ** 2, 1 / b ** 2
    qa = ux * ux * ia2 + uy * uy * ib2
    qb = dx * ux * ia2 + dy * uy * ib2
    qc = dx * dx * ia2 + dy * dy * ib2 - 1
    return (-qb + ops.sqrt(ops.fmax(qb * qb - qa * qc, 0.0))) / qa


@dataclass(frozen=True)
class HousingCurve:
    alpha: sp.Symbol
    sym: dict  # curve symbol (CURVE_PARAMETERS' keys) -> Symbol
    harmonic_syms: tuple  # ((k, A, gamma), ...)
    radius: sp.Expr  # polar radius about the centre
    point: tuple  # C(alpha), inertial
    normal: tuple  # inward unit normal n(alpha)
    curvature_sign: sp.Expr  # T x T' (> 0 everywhere for a convex, counter-clockwise curve)

    @property
    def symbols(self) -> list:
        """The curve's parameter symbols in the order of `parameter_names`."""
        return [self.sym[n] for n in CURVE_PARAMETERS] + [x for t in self.harmonic_syms for x in t]


def derive_housing(harmonic_slots: int) -> HousingCurve:
    al = sp.Symbol("alpha", real=True)
    S = {n: sp.Symbol(n, real=True) for n in CURVE_PARAMETERS}
    harm = tuple(sp.symbols(f"k{j} A{j} gamma{j}", real=True) for j in range(harmonic_slots))
    a, b, psi = S["a"], S["b"], S["psi"]
    r = base_radius(a, b, al, psi, sp)
    for k, A, g in harm:
        r += A * sp.cos(k * (al - psi - g))
    # cos(alpha), sin(alpha) by angle addition: only trig of (alpha - psi) varies per evaluation,
    # cos(psi) and sin(psi) are shared by every evaluation in a kernel (common subexpressions)
    ca_, sa_ = sp.cos(al - psi), sp.sin(al - psi)
    Cx = S["cx"] + r * (ca_ * sp.cos(psi) - sa_ * sp.sin(psi))
    Cy = S["cy"] + r * (sa_ * sp.cos(psi) + ca_ * sp.sin(psi))
    Tx, Ty = sp.diff(Cx, al), sp.diff(Cy, al)
    Tn = sp.sqrt(Tx**2 + Ty**2)
    normal = (-Ty / Tn, Tx / Tn)
    curv = Tx * sp.diff(Ty, al) - Ty * sp.diff(Tx, al)
    return HousingCurve(al, S, harm, r, (Cx, Cy), normal, curv)
