"""SymPy expressions -> CasADi expressions (SX or MX), through lambdify with a CasADi namespace."""
from __future__ import annotations

import casadi as ca
import sympy as sp

CASADI_NAMESPACE = {
    "sin": ca.sin, "cos": ca.cos, "tan": ca.tan, "sqrt": ca.sqrt, "atan2": ca.atan2,
    "exp": ca.exp, "log": ca.log, "Abs": ca.fabs, "sign": ca.sign, "root2": ca.sqrt,
}
_root2 = sp.Function("root2")  # a square root SymPy does not fold back into a power


def _half_powers(expr):
    """b**(k/2) for odd k -> b**((k-1)/2) * sqrt(b): C's pow() costs several sqrt()s, and the
    housing curvature terms (b**(3/2)) sit in every right-hand side evaluation."""
    def split(e):
        k = int(e.exp * 2)
        return e.base ** ((k - 1) // 2) * _root2(e.base) if k > 0 else 1 / (e.base ** ((-k - 1) // 2) * _root2(e.base))
    return expr.replace(lambda e: e.is_Pow and e.exp.is_Rational and e.exp.q == 2 and abs(e.exp.p) > 1, split)


def lambdify_casadi(args, exprs):
    """Return f(*casadi_args) -> list of CasADi expressions, one per SymPy expression."""
    exprs = [_half_powers(sp.sympify(e)) for e in exprs]
    f = sp.lambdify(list(args), exprs, modules=[CASADI_NAMESPACE], cse=True)

    def call(*values):
        return [ca.SX(v) if isinstance(v, (int, float)) else v for v in f(*values)]

    return call
