"""The verdict: exactly one of three, its notes (confounded pairs, heavy tails, a drifting COF)
and the method line."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data import Dataset
from ..identification import base_name
from ..identification.drift import parameter_drift

from .effects import candidates, owner_of
from .log import Collinear, HeavyTails, SmallRemainder, VaneMultiples
from .options import OPTIONS, DiagnosisOptions
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


def method_text(opts: DiagnosisOptions = OPTIONS) -> str:
    """The method in one sentence (the result's `method`)."""
    return ("detectors: runs, Ljung-Box, synchronous-average F-test, high-frequency noise level "
            f"(family {opts.unexplained_alpha:g}, Bonferroni over detectors and measurements); candidates: "
            "prewhitened score tests (second order where symmetry cancels the first) and one-step "
            f"nonlinear fits ranked by BIC; the {opts.contenders} best, the 2 best by p and every significant "
            "out-of-round order refitted, physical ranges enforced, "
            f"acceptance by prewhitened likelihood ratio (p < {opts.lr_alpha:g}) and BIC on the whole record")


def _separable_at_another_speed(state, effect, partner, opts: DiagnosisOptions = OPTIONS):
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
        if np.linalg.norm(Q.T @ b) > opts.collinear * (np.linalg.norm(b) + 1e-300):
            return False
    return True


def confounded_notes(confounded, state, screen_data, measurements, opts: DiagnosisOptions = OPTIONS) -> list:
    """Per confounded pair, whether a second speed would separate it; and where housing-fixed
    defects can appear at all."""
    notes = []
    scr = state.on(screen_data)
    for a, b in confounded:
        sep = None if measurements > 1 else _separable_at_another_speed(scr, a, b, opts)
        notes.append(Collinear(a, b, measurements, sep))
    notes.append(VaneMultiples(state.cfg.vanes))
    return notes


@dataclass(frozen=True)
class Verdict:
    """Exactly one of: consistent with noise (possibly after named effects, possibly with a
    remainder below the relevance bar, said with its size); named effects and an unexplained
    remainder; nothing named and unexplained -- and a drift, when one was found."""

    consistent: bool
    text: str
    drifts: tuple  # identification.drift.Drift per drifting parameter


def verdict_of(detection, effects, drifts, opts: DiagnosisOptions = OPTIONS, unit: str = "N m",
               unconverged=()) -> Verdict:
    """The verdict of a detection (consistent(), p["family"], systematic); `unit`: the residual's;
    `unconverged`: the reported fits ("baseline", "final") that did not converge -- the verdict
    then says it is provisional, in its own words and not only in a note above it."""
    consistent = detection.consistent()
    # never "consistent with noise" while a detector rejects: a remainder below the relevance bar is
    # still said, with its size
    quiet = ("consistent with noise" if detection.p["family"] >= opts.unexplained_alpha else
             f"a systematic remainder of {detection.systematic:.3g} {unit} below the relevance bar")
    text = (quiet + (" after the named effects" if effects else "")) if consistent else \
        ("named effects and an unexplained remainder" if effects else "nothing named; unexplained")
    if drifts:
        text += "; " + ", ".join(d.text() for d in drifts)
    if unconverged:
        text += (f"; provisional: the {' and the '.join(unconverged)} fit{'s' if len(unconverged) > 1 else ''} "
                 "did NOT converge")
    return Verdict(consistent, text, tuple(drifts))


def verdict_notes(detection, kurtosis: dict, consistent: bool, opts: DiagnosisOptions = OPTIONS,
                  unit: str = "N m") -> list:
    """What the verdict adds to the log: a remainder below the relevance bar, heavy tails."""
    notes = []
    if consistent and detection.p["family"] < opts.unexplained_alpha:
        notes.append(SmallRemainder(detection.systematic, opts.relevant, detection.floor_sigma, unit))
    # claimed like a systematic residual: significant AND relevant (the tails add at least
    # `relevant` x the noise sigma in RMS; a lone sample a fit's moved reversal leaves is not)
    if kurtosis["p_value"] < opts.unexplained_alpha and kurtosis["excess_rms"] >= opts.relevant * kurtosis["mad_sigma"]:
        notes.append(HeavyTails(kurtosis["excess_rms"], kurtosis["mad_sigma"], unit))
    return notes
