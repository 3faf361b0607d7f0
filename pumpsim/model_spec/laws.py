"""Friction and contact laws (spec §3), written once for any backend.

`ops` supplies fmin, fmax, fabs, sign, if_else, sqrt, power: NumPy for the runtime and tests
(`NUMPY_OPS`), CasADi for the generated kernels (codegen builds its table with `make_ops`).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np


def make_ops(fmin, fmax, fabs, sign, sqrt, power, if_else) -> SimpleNamespace:
    """The operations the laws use, from one backend."""
    return SimpleNamespace(fmin=fmin, fmax=fmax, fabs=fabs, sign=sign, sqrt=sqrt, power=power,
                           if_else=if_else)


NUMPY_OPS = make_ops(np.minimum, np.maximum, np.abs, np.sign, np.sqrt, np.power, np.where)


def step(x, x0, h0, x1, h1, ops=NUMPY_OPS):
    """Cubic STEP(x, x0, h0, x1, h1) = h0 + (h1-h0) D^2 (3 - 2D), D = (x-x0)/(x1-x0) clamped to [0,1]."""
    d = ops.fmin(ops.fmax((x - x0) / (x1 - x0), 0.0), 1.0)
    return h0 + (h1 - h0) * d * d * (3.0 - 2.0 * d)


def friction_coefficient(v, mu_s, mu_d, v_s, v_d, ops=NUMPY_OPS):
    """Adams-style mu(v), odd in v (report §5.5.5)."""
    av = ops.fabs(v)
    inner = step(v, -v_s, -mu_s, v_s, mu_s, ops)
    middle = ops.sign(v) * step(av, v_s, mu_s, v_d, mu_d, ops)
    outer = ops.sign(v) * mu_d
    return ops.if_else(av <= v_s, inner, ops.if_else(av <= v_d, middle, outer))


def contact_force(law, delta, delta_dot, k, e, c, d_max, m, ops=NUMPY_OPS):
    """Penalty contact force for penetration delta (> 0 is interference), clamped so it never pulls.

    law: linear (k d + c d'), hunt-crossley (k d^n + c d^n d', n = e), impact (k d^e + STEP(d, 0, 0,
    d_max, c) d'), report-nonlinear (k d^4 + 2 m sqrt(k d^3 / m) d', report §8.1 with p1 = k).
    """
    dp = ops.fmax(delta, 0.0)
    if law == "linear":
        f = k * dp + c * delta_dot
    elif law == "hunt-crossley":
        f = k * ops.power(dp, e) + c * ops.power(dp, e) * delta_dot
    elif law == "impact":
        f = k * ops.power(dp, e) + step(dp, 0.0, 0.0, d_max, c, ops) * delta_dot
    elif law == "report-nonlinear":
        f = k * dp**4 + 2.0 * m * ops.sqrt(k * dp**3 / m) * delta_dot
    else:
        raise ValueError(f"unknown contact law {law!r}")
    return ops.if_else(delta > 0, ops.fmax(f, 0.0), 0.0 * f)
