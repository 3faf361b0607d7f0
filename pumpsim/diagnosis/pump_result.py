"""What a bench-log diagnosis found: `BenchDiagnosis`, its JSON (spec §7's diagnosis JSON, §10)
and its step table; typed so that a report can draw the measured and fitted channels of each model."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..presentation import PLUS_MINUS, parameter_text
from .pump_effects import PumpEffect
from .result import NamedSteps

NOISE_UNIT = "noise sigmas"  # every residual RMS of a bench-log diagnosis: channels over their noise sigma


def estimates_json(estimates: dict) -> dict:
    """{name: {value, stderr}}; an estimate whose standard error exceeds its size is no result."""
    out = {}
    for n, e in estimates.items():
        if e.value is not None and e.stderr is not None and np.isfinite(e.stderr) and e.stderr <= max(abs(e.value), 0.0):
            out[n] = {"value": e.value, "stderr": e.stderr}
        else:
            out[n] = {"value": None, "stderr": None, "not_determined": {"estimate": e.value, "stderr": e.stderr}}
    return out


@dataclass(frozen=True)
class BenchModelFit:
    """One model of the diagnosis (the baseline, then after each named effect): its fitted values
    and its channels as compared (unscaled: Pa, A, rad/s)."""

    label: str
    rms: float  # residual RMS, noise sigmas
    params: dict  # {name: {value, stderr}}
    channels: dict  # channel -> model values at BenchDiagnosis.times[channel]


@dataclass(frozen=True)
class BenchStep:
    """A named effect: its parameter as fitted (and its change from the absent value), the RMS it
    left, its score test, likelihood-ratio test, BIC before and after, and the model change it made."""

    effect: PumpEffect
    params: dict  # {name: {value, stderr}} of the effect's parameter, plus "change" from absent
    rms_before: float
    rms_after: float
    p_value: float  # its score test's
    score: float
    lr_p_value: float
    bic_before: float
    bic_after: float
    size: float  # RMS of the model change it made, noise sigmas

    def to_json(self) -> dict:
        return {"effect": self.effect.name, "params": self.params, "rms_before": self.rms_before,
                "rms_after": self.rms_after, "p_value": self.p_value, "score": self.score,
                "lr_p_value": self.lr_p_value, "bic_before": self.bic_before, "bic_after": self.bic_after,
                "size": self.size}

    def parameter_texts(self) -> list[str]:
        return [parameter_text(n, v["value"], v["stderr"]) for n, v in self.params.items()
                if isinstance(v, dict) and "value" in v]


@dataclass(frozen=True)
class BenchDiagnosis(NamedSteps):
    """What `diagnose_bench` found. `to_json()` is the JSON (spec §7 names are its keys); the typed
    fields carry what a report draws: `measured`, `times` and each model's channels in `history`."""

    baseline: dict  # {"rms", "params"}
    steps: tuple  # BenchStep per named effect
    final: dict  # {"rms", "params", "residual_white", detectors' p}
    unexplained: bool
    confounded: list  # [[name, name], ...]
    unexplained_where: list  # [{"channel", "time": [t0, t1], "pressure": [lo, hi], "mean_residual", "unit"}]
    verdict: str
    log: tuple  # log.Note records
    detectors: dict
    ranking: list  # the last screen: [{"effect", "score", "score_p_value", "one_step", "significant"}]
    method: str
    wall_time: float
    measured: dict = field(default_factory=dict)  # channel -> compared values (Pa, A, rad/s)
    times: dict = field(default_factory=dict)  # channel -> their times [s]
    noise: dict = field(default_factory=dict)  # channel -> its noise sigma (Pa, A, rad/s): the RMS unit
    history: tuple = ()  # BenchModelFit: the baseline, then after each named effect
    budget: dict = field(default_factory=dict)
    runs: int = 0  # model runs the diagnosis made
    withdrawn: tuple = ()  # BenchStep the search named before the guard found the model inadequate (pump_guard)
    consistency: dict = field(default_factory=dict)  # the guard's test of the final model (pump_guard.consistency)

    JSON = ("baseline", "steps", "effects", "final", "unexplained", "confounded", "unexplained_where",
            "verdict", "notes", "detectors", "ranking", "method", "wall_time", "budget", "runs", "consistency")

    def to_json(self) -> dict:
        out = {k: getattr(self, k) for k in self.JSON}
        out["steps"] = [s.to_json() for s in self.steps]
        out["withdrawn"] = [s.to_json() for s in self.withdrawn]
        return out

    def __str__(self):
        return self.summary()

    def summary(self) -> str:
        """The step table: baseline, each named effect, the final model, the verdict and the notes."""
        lines = [f"{'step':<22}{'RMS before':>12}{'RMS after':>12}{'p-value':>10}  parameters (RMS in {NOISE_UNIT})"]
        lines.append(f"{'baseline':<22}{'':>12}{self.baseline['rms']:>12.4g}{'':>10}  " + ", ".join(
            parameter_text(k, v["value"], v["stderr"]) for k, v in self.baseline["params"].items()))
        for s in self.steps:
            lines.append(f"{s.effect.name:<22}{s.rms_before:>12.4g}{s.rms_after:>12.4g}{s.p_value:>10.2g}  "
                         + ", ".join(s.parameter_texts()))
        f = self.final
        lines.append(f"final: RMS {f['rms']:.4g} {NOISE_UNIT}; detectors p: runs {f['runs_p_value']:.2g}, "
                     f"Ljung-Box {f['ljung_box_p_value']:.2g}, noise level {f['noise_level_p_value']:.2g}"
                     + (f", mean level {f['mean_level_p_value']:.2g}" if "mean_level_p_value" in f else ""))
        lines.append(f"verdict: {self.verdict}")
        for w in self.unexplained_where:
            lines.append(f"  unexplained in {w['channel']}: t {w['time'][0]:.3g}-{w['time'][1]:.3g} s, booster "
                         f"pressure {w['pressure'][0] / 1e3:.4g}-{w['pressure'][1] / 1e3:.4g} kPa, mean residual "
                         f"{w['mean_residual']:+.3g} {w['unit']}")
        lines += [f"confounded: {a} ~ {b}" for a, b in self.confounded]
        lines += [f"note: {n}" for n in self.notes]
        lines.append(PLUS_MINUS)
        return "\n".join(lines)

