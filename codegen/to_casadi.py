"""SymPy expressions -> CasADi expressions (SX or MX), through lambdify with a CasADi namespace."""
from __future__ import annotations

import casadi as ca
import sympy as sp

CASADI_NAMESPACE = {
    "sin": ca.sin, "cos": ca.cos, "tan": ca.tan, "sqrt": ca.sqrt, "atan2": ca.atan2,
    "exp": ca.exp, "log": ca.log, "Abs": ca.fabs, "sign": ca.sign,
}


def lambdify_casadi(args, exprs):
    """Return f(*casadi_args) -> list of CasADi expressions, one per SymPy expression."""
    f = sp.lambdify(list(args), list(exprs), modules=[CASADI_NAMESPACE], cse=True)

    def call(*values):
        return [ca.SX(v) if isinstance(v, (int, float)) else v for v in f(*values)]

    return call
