"""Which fitted parameters the data cannot determine: those without effect on the model, and
those in a near-null direction of the column-scaled Jacobian (J'J near-singular)."""
from __future__ import annotations

import numpy as np

from ..tolerances import NO_EFFECT_REL, SINGULAR_COND
from .optimiser import scaled_svd
from .problem import base_name


def to_fix(names, J, x, model):
    """(parameters without effect, parameters in a flat direction) to fix before fitting. A flat
    direction that involves the speed and others fixes the speed alone: its nominal value (config
    or speed column) is known, and the others (e.g. the COF) are what the fit is for."""
    dead = no_effect(names, J, x, model)
    flat = collinear(names, J, x, model)
    speeds = [n for n in flat if base_name(n) == "speed"]
    if speeds and len(flat) > len(speeds):
        flat = speeds
    return dead, flat


def no_effect(names, J, x, model) -> list:
    """The parameters that do not act on the model at all."""
    col = np.linalg.norm(J, axis=0)
    size = np.maximum(np.abs(x), 1.0)
    return [n for n, c, sz in zip(names, col, size) if c * sz <= NO_EFFECT_REL * max(np.linalg.norm(model), 1e-300)]


def collinear(names, J, x, model) -> list:
    """The parameters that act, but only in combinations the data cannot tell apart."""
    dead = no_effect(names, J, x, model)
    live = [i for i, n in enumerate(names) if n not in dead]
    bad = []
    if len(live) > 1:  # near-null directions among the parameters that do act
        scale, U, s, Vt = scaled_svd(J[:, live])
        for j in range(len(s)):
            if s[j] < s[0] / SINGULAR_COND:
                v = np.abs(Vt[j])
                bad += [names[live[i]] for i in np.nonzero(v > 0.3 * v.max())[0]]
    return sorted(set(bad), key=names.index)
