"""Delta-method descriptions of fitted parameter pairs (amplitude and phase)."""
from __future__ import annotations

import math

import numpy as np




def to_polar(res, names, k):
    """(a, b) -> amplitude and phase of a cos(k x) + b sin(k x) = A cos(k x - k gamma) with
    standard errors by the delta method: the physical description of an out-of-round or ripple."""
    ea, eb = res.estimates[names[0]], res.estimates[names[1]]
    a, b = ea.value, eb.value
    A = math.hypot(a, b)
    S = covariance(res, names)
    gA = np.array([a, b]) / max(A, 1e-300)
    gP = np.array([-b, a]) / max(A * A, 1e-300)
    return ({"value": A, "stderr": float(math.sqrt(max(gA @ S @ gA, 0.0)))},
            {"value": math.atan2(b, a), "stderr": float(math.sqrt(max(gP @ S @ gP, 0.0)))})


def covariance(res, names):
    """Covariance of the estimates `names` (stderr x correlation x stderr)."""
    ids = [n for n in res.estimates if res.estimates[n].identifiable]
    se = np.array([res.estimates[n].stderr or 0.0 for n in names])
    C = np.eye(len(names))
    if res.correlation is not None and all(n in ids for n in names):
        idx = [ids.index(n) for n in names]
        C = res.correlation[np.ix_(idx, idx)]
    return np.outer(se, se) * C
