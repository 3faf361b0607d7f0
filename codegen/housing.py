"""The housing curve (spec §1), symbolic in its polar angle alpha about the housing centre.

r(alpha) = r0(alpha - psi) + sum_j A_j cos(k_j (alpha - psi - gamma_j)), with r0 the polar radius of
an ellipse with semi-axes a, b about its centre (a circle when a = b). The inward normal is
n = z x T/|T| with T = dC/dalpha (the curve runs counter-clockwise).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp


@dataclass(frozen=True)
class HousingCurve:
    alpha: sp.Symbol
    sym: dict  # parameter name -> Symbol
    harmonic_syms: tuple  # ((k, A, gamma), ...)
    radius: sp.Expr  # polar radius about the centre
    point: tuple  # C(alpha), inertial
    normal: tuple  # inward unit normal n(alpha)
    curvature_sign: sp.Expr  # T x T' (> 0 everywhere for a convex, counter-clockwise curve)


def derive_housing(harmonic_slots: int) -> HousingCurve:
    al = sp.Symbol("alpha", real=True)
    S = {n: sp.Symbol(n, real=True) for n in ("a", "b", "cx", "cy", "psi")}
    harm = tuple(sp.symbols(f"k{j} A{j} gamma{j}", real=True) for j in range(harmonic_slots))
    a, b, psi = S["a"], S["b"], S["psi"]
    r = a * b / sp.sqrt((b * sp.cos(al - psi)) ** 2 + (a * sp.sin(al - psi)) ** 2)
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
