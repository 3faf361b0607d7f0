"""Analytic functions with known answers, run through the same study machinery as a pump
(`[study] function = "ishigami"` instead of `config`): they verify the samplers, the execution, the
result tables and the sensitivity analysis independently of the pump model."""
from __future__ import annotations

import math

import numpy as np


class AnalyticFunction:
    def __init__(self, name, inputs, outputs, fn, doc=""):
        self.name, self.inputs, self.outputs, self.fn, self.doc = name, inputs, outputs, fn, doc

    def __call__(self, X):
        return self.fn(np.asarray(X, dtype=float))


def _ishigami(X, a=7.0, b=0.1):
    x1, x2, x3 = X[:, 0], X[:, 1], X[:, 2]
    return (np.sin(x1) + a * np.sin(x2) ** 2 + b * x3**4 * np.sin(x1))[:, None]


def ishigami_indices(a=7.0, b=0.1):
    """Closed-form first-order and total Sobol indices of Ishigami on [-pi, pi]^3."""
    pi = math.pi
    v1 = 0.5 * (1 + b * pi**4 / 5) ** 2
    v2 = a**2 / 8
    v13 = b**2 * pi**8 * (1 / 18 - 1 / 50)
    v = v1 + v2 + v13
    return {"x1": (v1 / v, (v1 + v13) / v), "x2": (v2 / v, v2 / v), "x3": (0.0, v13 / v)}


FUNCTIONS = {
    "ishigami": AnalyticFunction("ishigami", ("x1", "x2", "x3"), ("y",), _ishigami,
                                 "sin x1 + 7 sin² x2 + 0.1 x3⁴ sin x1"),
}
