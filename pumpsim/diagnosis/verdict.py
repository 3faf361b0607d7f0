"""The verdict's notes: confounded pairs, a drifting COF, and the method line."""
from __future__ import annotations


import numpy as np

from ..data import Dataset
from ..identification import base_name
from ..identification.drift import parameter_drift

from .effects import candidates, owner_of
from .options import COLLINEAR, CONTENDERS, LR_ALPHA, UNEXPLAINED_ALPHA
from .state import State, identify


def drift_findings(run, state) -> list:
    """The COF's drift over a single measurement's record (identification.drift), at the final
    model's other values; [] with several measurements or no fitted mu."""
    if len(run.datasets) > 1 or "mu" not in state.names or run.out_of_time("the drift test"):
        return []
    data = run.datasets[0]
    speed = state.values.get("speed", data.mean_speed() if data.speed is not None else state.cfg.speed)

    def fit(seg, names, init):
        held = {k: v for k, v in state.values.items() if k not in names}
        return identify(state.cfg, seg, names, initial=init, multistart=False, ripple_order=state.ripple_order,
                        extra=held)

    found = parameter_drift(fit, data, "mu", state.values, speed)
    return [found] if found is not None else []


METHOD = ("detectors: runs, Ljung-Box, synchronous-average F-test, high-frequency noise level "
          f"(family {UNEXPLAINED_ALPHA:g}, Bonferroni over detectors and measurements); candidates: "
          "prewhitened score tests (second order where symmetry cancels the first) and one-step "
          f"nonlinear fits ranked by BIC; the {CONTENDERS} best refitted, physical ranges enforced, "
          f"acceptance by prewhitened likelihood ratio (p < {LR_ALPHA:g}) and BIC on the whole record")


def _separable_at_another_speed(state, effect, partner):
    """Would a second measurement at 0.6 x this speed separate `effect` from `partner`? The pair's
    sensitivities at both speeds stacked: still collinear means no speed separates them."""
    cand = next((c for c in candidates(state.cfg, set()) if c.effect == effect), None)
    partner_names = [n for n in state.names if owner_of(n, state.cfg) == partner]  # a fitted effect: all its names
    if cand is None or not partner_names or isinstance(state.data, (list, tuple)):
        return None
    d = state.data
    w = d.mean_speed() if d.speed is not None else state.values.get("speed", state.cfg.speed)
    other = Dataset(d.time, d.torque, speed=np.full(d.n, 0.6 * w))
    cols = []
    for data in (Dataset(d.time, d.torque, speed=np.full(d.n, w)), other):
        held = {k: v for k, v in state.values.items() if base_name(k) != "speed"}  # the data's speed
        st = State(state.cfg, data, partner_names, held, state.ripple_order)
        prob = cand.problem(st)
        cols.append(prob.model_and_jacobian(prob.x0)[1])
    J = np.vstack(cols)
    P, B = J[:, :len(partner_names)], J[:, len(partner_names):]
    P = P[:, np.linalg.norm(P, axis=0) > 0]
    if not P.size:
        return None
    Q = np.linalg.qr(P)[0]
    for j in range(B.shape[1]):  # a candidate direction inside the partner's span at both speeds
        b = B[:, j]
        if np.linalg.norm(Q.T @ b) > COLLINEAR * (np.linalg.norm(b) + 1e-300):
            return False
    return True


def confounded_notes(confounded, state, screen_data, measurements):
    notes = []
    scr = state.on(screen_data)
    for a, b in confounded:
        if measurements > 1:
            notes.append(f"{a} and {b} have nearly collinear effects even on these {measurements} measurements")
            continue
        sep = _separable_at_another_speed(scr, a, b)
        if sep is False:
            notes.append(f"{a} and {b} have nearly collinear effects on this data, and would at any speed")
        else:
            notes.append(f"{a} and {b} have nearly collinear effects on this data: a measurement at a "
                         "second speed would separate them")
    N = state.cfg.vanes
    notes.append(f"with {N} identical, equally spaced vanes, housing-fixed defects appear only at "
                 f"multiples of {N} shaft orders")
    return notes
