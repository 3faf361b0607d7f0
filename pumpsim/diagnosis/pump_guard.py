"""The bench-log diagnosis's guard against a model that cannot describe the log: the final model's
fitted parameters (the vane COF and every named effect's) estimated on consecutive parts of the
log must agree.

A greedy search names whatever lowers the misfit most, so a change outside the library (another
booster volume, a sensor's span error) is read as a sum of library effects, each step passing its
likelihood ratio and BIC. Such a sum fits the log on average, not everywhere: the effects it names
have pressure and time dependences of their own, and the change they stand in for has another, so
the values each part of the log asks for differ. A model that describes the log asks for the same
values everywhere, up to the noise. The test is the torque workflow's stationarity test
(stationarity.homogeneity: per-part linearised estimates at the fit, their spread against their
covariance, chi-square), on time thirds of the log (a pump-down: falling pressure ranges), and
the disagreement must be relevant: worth a quarter noise sigma (RMS) of model change, as a named
effect must, or a share (NAMED_SHARE) of what the named effects explain. The second measure is the
named effects': a gap of the model's form confined to one channel and one pressure range (the
current at high pressure) is diluted by every sample of the log in an RMS, yet a pair of fitted
parameters trading against each other (the vane COF and the motor friction) can take it up, and be
named for the part of it their trade can reach. It costs no model run: the fit's residual and
Jacobian are reused.

When it fires, no library effect is named: the verdict is `model inadequate` with the parameter
whose parts disagree most, its value on each part, and their times and booster pressures.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .log import Note
from .options import OPTIONS, DiagnosisOptions
from .stationarity import homogeneity

GUARD_PARTS = 3  # time thirds: a pump-down's high, middle and low pressures
# a disagreement worth this share of the residual sum of squares the named effects removed is
# relevant: the named model leaves a structure of the size of what it claims to have found
NAMED_SHARE = 0.1


@dataclass(frozen=True)
class Inconsistent(Note):
    """The final model's parameters disagree between parts of the log: its names are withdrawn."""

    model: tuple  # the model's fitted names
    withdrawn: tuple  # the effects the search had named
    statistic: float
    dof: int
    p_value: float
    alpha: float
    worst: dict  # {"name", "parts": [{"time", "pressure", "value", "stderr"}]}

    def text(self) -> str:
        parts = "; ".join(f"{p['value']:.4g} +- {p['stderr']:.2g} at t {p['time'][0]:.3g}-{p['time'][1]:.3g} s "
                          f"({p['pressure'][1] / 1e3:.4g}-{p['pressure'][0] / 1e3:.4g} kPa)"
                          for p in self.worst["parts"])
        named = (f"the named effects ({', '.join(self.withdrawn)}) are withdrawn" if self.withdrawn else
                 "nothing is named")
        return (f"model inadequate: the model fitted with {', '.join(self.model)} does not describe the whole log -- "
                f"its parameters fitted on the log's {len(self.worst['parts'])} time parts disagree (chi2 "
                f"{self.statistic:.3g} on {self.dof} dof, p {self.p_value:.2g} < {self.alpha:g}); most "
                f"{self.worst['name']}: {parts}. {named}: a change outside the library (a booster volume, a "
                "sensor's offset or span) or several at once")


def part_labels(times: list, parts: int = GUARD_PARTS) -> np.ndarray:
    """Per stacked residual value (`times`: each channel's sample times, in the stacking order),
    the index of the time part of the log it falls in."""
    t0 = min(float(t[0]) for t in times)
    span = max(max(float(t[-1]) for t in times) - t0, 1e-300)
    return np.concatenate([np.minimum(np.floor(parts * (np.asarray(t, float) - t0) / span), parts - 1)
                           for t in times]).astype(int)


def consistency(names, values, residual, jacobian, times, pressure, opts: DiagnosisOptions = OPTIONS,
                parts: int = GUARD_PARTS, explained: float = 0.0) -> dict:
    """The guard's test of a fitted model: `names` its fitted names at `values`, `residual` and
    `jacobian` at the fit in noise sigmas (stacked channels), `times` each channel's sample times,
    `pressure` (times, booster pressures) to say where a part lies. The parts' intervals are the
    noise's (the residual is in noise sigmas): a remainder the model leaves counts against it, as it
    should -- scaling by the residual's own scatter would excuse the worst models most. `explained`:
    the residual sum of squares the named effects removed from the baseline fit (noise sigmas
    squared; 0: none named). JSON-ready: {"fires", "statistic", "dof", "p_value", "alpha", "size",
    "relevant", "excess", "explained", "parts", "worst"}."""
    r = np.asarray(residual, float)
    J = np.asarray(jacobian, float)
    labels = part_labels(times, parts)
    used = np.any(J != 0.0, axis=1)  # values left out of the fit (zero weight) carry nothing
    h = homogeneity(J[used], r[used], labels[used], 1.0)
    tp, pb = pressure
    t0 = min(float(t[0]) for t in times)
    span = max(float(t[-1]) for t in times) - t0
    bounds = {k: (t0 + k * span / parts, t0 + (k + 1) * span / parts) for k in range(parts)}
    where = {k: {"time": list(b), "pressure": [float(np.interp(b[0], tp, pb)), float(np.interp(b[1], tp, pb))]}
             for k, b in bounds.items()}
    est = np.array(h.estimates) if h.estimates else np.zeros((0, len(names)))
    se = np.array(h.stderrs) if h.stderrs else np.zeros((0, len(names)))
    worst = None
    if est.shape[0] >= 2:
        # the parameter whose parts lie furthest apart in their joint standard errors
        spread = [(est[:, j].max() - est[:, j].min()) / np.sqrt(se[est[:, j].argmax(), j] ** 2 +
                                                                  se[est[:, j].argmin(), j] ** 2) for j in range(len(names))]
        j = int(np.argmax(spread))
        worst = {"name": names[j], "spread_sigmas": float(spread[j]),
                 "parts": [{**where[k], "value": float(values[names[j]] + est[i, j]), "stderr": float(se[i, j])}
                           for i, k in enumerate(h.labels)]}
    alpha = opts.stationary_alpha
    # claimed as an effect is: significant and relevant -- letting the parameters differ between the
    # parts must change the model by at least the naming size (RMS, noise sigmas; the statistic is
    # the residual sum of squares it removes, its expectation under agreement subtracted)
    excess = max(h.statistic - h.dof, 0.0)
    size = float(np.sqrt(excess / max(int(used.sum()), 1)))
    relevant = size >= opts.named_size or (explained > 0.0 and excess >= NAMED_SHARE * explained)
    return {"fires": bool(h.dof and h.p_value < alpha and relevant), "statistic": h.statistic,
            "dof": h.dof, "p_value": h.p_value, "alpha": alpha, "size": size, "relevant": opts.named_size,
            "excess": float(excess), "explained": float(explained), "parts": len(h.labels), "worst": worst}
