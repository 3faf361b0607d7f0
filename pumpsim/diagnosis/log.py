"""The step log of a diagnosis: what each step decided beside the effects it named, as typed
records. The result's `notes` are their sentences, in the order the steps made them."""
from __future__ import annotations

import time
from dataclasses import dataclass


class Note:
    """One record of the step log."""

    def text(self) -> str:
        raise NotImplementedError


class Budgeted:
    """A diagnosis run with a time budget: `deadline` (perf_counter() after which no new step or
    refit starts; None: no limit) and `budget` ({"seconds", "bound", "cut"})."""

    def out_of_time(self, what: str) -> bool:
        """True (and `what` listed as cut) once the time budget is spent."""
        if self.deadline is None or time.perf_counter() < self.deadline:
            return False
        self.budget["bound"] = True
        self.budget["cut"].append(what)
        return True


@dataclass(frozen=True)
class DataNote(Note):
    """What the data's own checks found worth saying (a sentence made where the check is)."""

    sentence: str

    def text(self) -> str:
        return self.sentence


@dataclass(frozen=True)
class SpeedColumnDrift(Note):
    measurement: int
    relative_change: float

    def text(self) -> str:
        return (f"speed column of measurement {self.measurement} drifts ({100 * self.relative_change:.2g} % over "
                "the record): the model's angle and speed follow its smoothed trend")


@dataclass(frozen=True)
class SpeedHeld(Note):
    """The baseline fit did not determine a measurement's speed: held where the evidence put it."""

    measurement: int
    why: str
    held_at: str
    value: float

    def text(self) -> str:
        return (f"speed of measurement {self.measurement} not determined by the fit ({self.why}): held at the "
                f"{self.held_at} value {self.value:.6g} rad/s")


@dataclass(frozen=True)
class SpeedRefined(Note):
    """A held speed refined in its band: once an effect made the torque depend on the angle
    (band None), or because at the held speed an effect's segments disagreed (band named)."""

    band: str | None = None

    def text(self) -> str:
        if self.band is None:
            return "speed refined in its band once the named effect made the torque depend on the angle"
        return (f"speed refined in {self.band}: at the held speed the effect's parameters disagreed between "
                "segments of the record")


@dataclass(frozen=True)
class BaselineImplausible(Note):
    reason: str

    def text(self) -> str:
        return f"baseline: {self.reason} -- check the config and the data's units"


@dataclass(frozen=True)
class MismatchExplained(Note):
    """The baseline missed its own shaft orders (identify's 'a config that is not this pump'), and
    the one named effect accounts for them: the final model describes its own orders and leaves
    nothing unexplained, so the name stands."""

    misfit_before: float  # the share of the model's own shaft orders left in the residual
    misfit_after: float | None

    def text(self) -> str:
        after = "" if self.misfit_after is None else f" ({100 * self.misfit_after:.0f} % left)"
        return (f"baseline: {100 * self.misfit_before:.0f} % of the model's own shaft orders stayed in its residual, "
                "as with a config of another pump; the one named effect accounts for them" + after + " and leaves "
                "nothing unexplained, so it is reported -- a defect this large should be plain on the part: "
                "check the named size against its measurement")


@dataclass(frozen=True)
class BaselineRestarted(Note):
    """The baseline fit stalled at its start, which the start test found NOT a minimum, and was
    fitted again from where its Gauss-Newton step pointed; the better of the two (by RMS) is kept."""

    rms_before: float
    rms_after: float | None  # None: the model is not finite where the step pointed (no second fit)
    kept_again: bool  # the fit from where the step pointed is the baseline

    def text(self) -> str:
        if self.rms_after is None:
            return ("baseline: no step left its start, which is not the fit's minimum, and its slope points out of "
                    "the pump's geometry (the model is not finite there): the first fit kept")
        change = f"RMS {self.rms_before:.6g} -> {self.rms_after:.6g}"
        return ("baseline: no step left its start, which is not the fit's minimum (its slope points many standard "
                f"errors away); fitted again from where the slope points ({change}): "
                + ("that fit is the baseline" if self.kept_again else "the first fit kept, the second not better"))


@dataclass(frozen=True)
class Rejected(Note):
    """A contender refused for physical reasons (a range, a measured speed column)."""

    label: str
    reasons: tuple
    by_speed_column: bool = False  # refuted by a measured speed column (the next contenders get their chance)

    def text(self) -> str:
        return f"{self.label} rejected: " + "; ".join(self.reasons)

    def to_json(self) -> dict:
        return {"effect": self.label, "reasons": list(self.reasons)}


@dataclass(frozen=True)
class TooSmall(Note):
    """A significant contender whose torque change is below the naming size."""

    label: str
    size: float
    factor: float
    scatter: float
    unit: str = "N m"
    quantity: str = "the torque"

    def text(self) -> str:
        return (f"{self.label} not named: it changes (explains) {self.quantity} by {self.size:.3g} {self.unit} RMS, "
                f"below {self.factor:g} x the noise's scatter {self.scatter:.3g} {self.unit}")


@dataclass(frozen=True)
class NotStationary(Note):
    label: str
    statistic: float
    dof: int
    p_value: float
    alpha: float

    def text(self) -> str:
        return (f"{self.label} not named: not stationary -- its parameters fitted on segments of the record "
                f"disagree (chi2 {self.statistic:.3g} on {self.dof} dof, p {self.p_value:.2g} < {self.alpha:g}): "
                "the synchronous shadow of a disturbance that is not shaft-fixed")


@dataclass(frozen=True)
class Dropped(Note):
    effect: str
    by: str
    reason: str

    def text(self) -> str:
        return f"{self.effect} dropped once {self.by} was added: {self.reason}"


@dataclass(frozen=True)
class Rivals(Note):
    first: str
    second: str
    decisive: float

    def text(self) -> str:
        return (f"{self.first} and {self.second} explain the remaining residual equally well "
                f"(within {self.decisive:g} BIC): neither is named")


@dataclass(frozen=True)
class SmallRemainder(Note):
    systematic: float
    relevant: float
    sigma: float
    unit: str = "N m"

    def text(self) -> str:
        return (f"a systematic residual of {self.systematic:.3g} {self.unit} remains, below {self.relevant:g} x the "
                f"noise sigma ({self.sigma:.3g} {self.unit}): not claimed as a discrepancy")


@dataclass(frozen=True)
class HeavyTails(Note):
    excess_rms: float
    sigma: float
    unit: str = "N m"

    def text(self) -> str:
        return (f"heavy-tailed residual (kurtosis test): spikes or non-Gaussian noise add {self.excess_rms:.3g} "
                f"{self.unit} RMS above the noise sigma {self.sigma:.3g} {self.unit}")


@dataclass(frozen=True)
class Collinear(Note):
    """A confounded pair: whether a second speed would separate it (None: not known)."""

    first: str
    second: str
    measurements: int
    separable: bool | None

    def text(self) -> str:
        pair = f"{self.first} and {self.second} have nearly collinear effects"
        if self.measurements > 1:
            return f"{pair} even on these {self.measurements} measurements"
        if self.separable is False:
            return f"{pair} on this data, and would at any speed"
        return f"{pair} on this data: a measurement at a second speed would separate them"


@dataclass(frozen=True)
class VaneMultiples(Note):
    vanes: int

    def text(self) -> str:
        return (f"with {self.vanes} identical, equally spaced vanes, housing-fixed defects appear only at "
                f"multiples of {self.vanes} shaft orders")


@dataclass(frozen=True)
class Drifting(Note):
    finding: str  # the drift's own sentence (identification.drift.Drift.text)
    segments: int
    p_value: float

    def text(self) -> str:
        return (f"{self.finding} (a straight line through {self.segments} segment fits, p {self.p_value:.2g}): the "
                "model's constant value is its mean over the record")


@dataclass(frozen=True)
class NotConverged(Note):
    """A fit of the diagnosis that did not converge (the optimiser's why), and what that leaves
    open: the baseline's, the final model's (the torque workflow: its whole-record fit) or an
    effect's refit (the bench-log workflow). `data`: what the baseline's advice fits again."""

    fit: str  # "baseline", "final", or the effect whose refit it is
    why: str
    data: str = "log"
    # the baseline's: its remaining step's worth in noise variances and the least BIC gain of a named
    # step, where that gain outweighs it (result.stall_outweighed): the verdict does not rest on it
    outweighed_by: tuple | None = None

    def text(self) -> str:
        if self.fit == "baseline" and self.outweighed_by:
            left, gain = self.outweighed_by
            return (f"the baseline fit is NOT converged ({self.why}): its figures are not the fit's minimum, but its "
                    f"remaining step is worth ~{left:.3g} noise variances against a BIC gain of at least {gain:.4g} "
                    "for each named effect -- its stall cannot have decided them, and the verdict does not rest on it")
        if self.fit == "baseline":
            return (f"the baseline fit is NOT converged ({self.why}): its figures are not the fit's minimum, and the "
                    "residual tests and the search start from them -- the verdict may be wrong; check the config's "
                    f"values against the pump (the vane COF first), or fit the {self.data} with pumpsim identify")
        if self.fit == "final":
            return (f"the final model's fit is NOT converged ({self.why}): its figures (the named effects' "
                    "parameters, the final RMS, the residual tests behind the verdict) are not the fit's minimum "
                    "-- the verdict may be wrong and a named effect's size misstated; check the config's values "
                    "against the pump (the vane COF first) and diagnose again; until a diagnosis converges, read "
                    "the named effects as candidates, not findings")
        return (f"the refit of {self.fit} is NOT converged ({self.why}): its figures are not the fit's minimum and "
                "what it explains (likelihood ratio, BIC, size) is understated -- the verdict may miss it, name a "
                "rival in its place, or misstate its size")


def unconverged_fits(log, fits) -> tuple:
    """The fits among `fits` whose NotConverged note in `log` leaves the verdict provisional: all
    but a baseline whose stall the named effects outweigh (NotConverged.outweighed_by)."""
    return tuple(n.fit for n in log if isinstance(n, NotConverged) and n.fit in fits and not n.outweighed_by)


@dataclass(frozen=True)
class BudgetReached(Note):
    seconds: float
    cut: tuple

    def text(self) -> str:
        return (f"time budget of {self.seconds:g} s reached: not done -- " + "; ".join(self.cut)
                + " (a larger time budget does them)")
