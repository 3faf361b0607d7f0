"""What a diagnosis found: `DiagnosisResult`, its JSON (spec section 7) and its step table."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..identification import base_name
from ..presentation import OPTIMISTIC, PLUS_MINUS, fmt_estimate, parameter_text

from .effects import Effect, clearance, effect_of
from .estimates import covariance
from .log import Rejected


def _baseline_resolution(b: str, value: float, cfg) -> float | None:
    """The standard error above which a baseline (non-effect) estimate is not a result."""
    if b == "theta0":
        return math.pi / max(cfg.vanes, 1)  # half the angular period
    if b in ("mu", "speed") or b.startswith("effects.vane"):
        return abs(value)
    if b.startswith("housing."):
        return clearance(cfg)
    return None


def undetermined(name, value, se, cfg) -> bool:
    """An estimate whose standard error exceeds what would make it a result: larger than itself
    for a positive quantity (COF, speed, lag), than half the angular period for theta0, than the
    clearance for geometry and than its plausible size for the other effect parameters (each
    effect declares its own: Effect.resolution)."""
    if value is None or se is None or not math.isfinite(se):
        return True
    effect = effect_of(name, cfg)
    if effect is None:
        bound = _baseline_resolution(base_name(name), value, cfg)
    else:
        bound = None if effect.resolution is None else effect.resolution(cfg, value)
    return bound is not None and se > bound


def params_json(res, names, cfg):
    out = {}
    for n in names:
        e = res.estimates.get(n)
        if e is None:
            continue
        if e.value is not None and not undetermined(n, e.value, e.stderr, cfg):
            out[n] = {"value": e.value, "stderr": e.stderr}
        else:  # never a number with a standard error larger than itself as a result
            out[n] = {"value": None, "stderr": None, "not_determined": {"estimate": e.value, "stderr": e.stderr}}
    return out


def effect_params(cand, res, new_names, cfg):
    """The step's parameters as an engineer reads them."""
    out = params_json(res, new_names, cfg)
    if cand.order:
        out["order"] = cand.order
    if cand.kind.polar is not None:  # amplitude and phase of a harmonic pair
        out.update(cand.kind.polar.describe(res, new_names, cand.order))
    return out


def vane_cofs(res, cfg) -> tuple:
    """Each vane's effective dynamic COF (tip and slot: mu x its factor, vane 0 the reference) and
    the reported mu, their mean over the vanes, with standard errors by the delta method."""
    N = cfg.vanes
    names = ["mu"] + [f"effects.vane_friction_factor.{i}" for i in range(1, N)]
    fitted = [n for n in names if n in res.estimates and res.estimates[n].value is not None]
    val = {n: (res.estimates[n].value if n in fitted else
               (cfg.values["friction.housing.dynamic"] if n == "mu" else cfg.values[n])) for n in names}
    S = covariance(res, fitted)
    mu = val["mu"]
    facs = [1.0] + [val[n] for n in names[1:]]
    per = []
    for i in range(N):
        g = np.array([facs[i] if n == "mu" else (mu if n == names[i] and i > 0 else 0.0) for n in fitted])
        per.append({"value": mu * facs[i], "stderr": float(math.sqrt(max(g @ S @ g, 0.0)))})
    g = np.array([sum(facs) / N if n == "mu" else mu / N for n in fitted])
    mean = {"value": mu * sum(facs) / N, "stderr": float(math.sqrt(max(g @ S @ g, 0.0)))}
    return per, mean


MU_DEFINITION = ("mu: the mean over the vanes of each vane's dynamic COF (vane-housing tip, slot tied "
                 "unless mu_slot is fitted); vane_mu: each vane's COF = mu_vane0 x its factor")


WHITE_ALPHA = 0.05  # the runs and Ljung-Box tests' level behind "white"


@dataclass(frozen=True)
class ModelFit:
    """One model of the diagnosis's history (the baseline, then after each named effect) and its fit."""

    label: str
    result: object  # the IdentificationResult: residual, fitted, time, angle, estimates


# A baseline fit that stopped unconverged, its remaining Gauss-Newton step worth G noise variances
# (IdentificationResult.left_chi2), cannot have decided a named step whose BIC gain exceeds this many
# times G plus the decisive BIC margin: the verdict then does not rest on it (its figures are still
# not its minimum, and a note says so). The bench record's 20 um oval: G = 65, the oval's gain 7,055.
STALL_MARGIN = 10.0


def stall_outweighed(base, steps, opts) -> bool:
    """Whether the baseline `base` did not converge but every named step's BIC gain outweighs
    what its remaining step could still change (STALL_MARGIN)."""
    left = getattr(base, "left_chi2", None)
    return (not base.converged and bool(steps) and left is not None and math.isfinite(left)
            and all(-s.delta_bic > STALL_MARGIN * left + opts.bic_decisive for s in steps))


@dataclass(frozen=True)
class Step:
    """A named effect: its parameters as read (order, amplitude and phase), the RMS it left, its
    tests and the BIC of the models before and after it (one definition: `state.bic`, prewhitened
    with the AR(1) coefficient of the residual the step starts from, on the samples both keep)."""

    effect: Effect
    params: dict  # JSON: {name: {value, stderr}}, order, amplitude, phase
    rms_before: float
    rms_after: float
    p_value: float  # of its score test
    score: float
    score_dof: int
    second_order_score: bool
    lr_p_value: float
    bic_before: float
    bic_after: float
    all_params: dict  # JSON: every parameter of the model after the step

    def to_json(self) -> dict:
        return {"effect": self.effect.name, "params": self.params, "rms_before": self.rms_before,
                "rms_after": self.rms_after, "p_value": self.p_value, "score": self.score,
                "score_dof": self.score_dof, "second_order_score": self.second_order_score,
                "lr_p_value": self.lr_p_value, "bic_before": self.bic_before, "bic_after": self.bic_after,
                "all_params": self.all_params}

    @property
    def delta_bic(self) -> float:
        return self.bic_after - self.bic_before

    def parameter_texts(self) -> list[str]:
        """The parameters as an engineer reads them: order, amplitude and phase with units (as the
        effect declares them), other parameters with their units; the (a, b) components behind an
        amplitude stay in the JSON."""
        p, form = self.params, self.effect.polar
        items = [f"order k = {p['order']}"] if "order" in p else []
        if form is not None and "amplitude" in p:
            A, ph = p["amplitude"], p["phase"]
            phase = f"{fmt_estimate(ph['value'], ph['stderr'])} rad ({math.degrees(ph['value']):.3g}°)"
            return items + [f"{form.amplitude} {fmt_estimate(A['value'] * form.scale, A['stderr'] * form.scale)} "
                            f"{form.unit}", f"{form.phase} {phase}"]
        return items + [parameter_text(name, v["value"], v["stderr"]) for name, v in p.items() if isinstance(v, dict)]


@dataclass(frozen=True)
class PolarEstimate:
    """A named pair effect's amplitude and phase at the final fit (delta-method standard errors)."""

    effect: Effect
    order: int
    amplitude: dict  # {value, stderr}, SI
    phase: dict  # {value, stderr} [rad]


class NamedSteps:
    """What every diagnosis result reads off its `steps`, its step `log` and the convergence of
    its reported fits (`baseline`, `final`, `history`)."""

    @property
    def effects(self) -> list[str]:
        """The named effects, in the order added."""
        return [s.effect.name for s in self.steps]

    @property
    def notes(self) -> list[str]:
        return [n.text() for n in self.log]

    def unconverged(self) -> list[str]:
        """The models the diagnosis reports (the baseline, the final one) whose fit did not
        converge: the verdict rests on them (the command exits 1; the notes say how each stopped)."""
        stalled = not self.baseline.get("converged", True) and not self.baseline.get("stall_outweighed", False)
        out = ["the baseline fit is NOT converged"] if stalled else []
        if len(self.history) > 1 and not self.final.get("converged", True):  # the final model is not the baseline
            out.append("the final model's fit is NOT converged")
        return out


@dataclass(frozen=True)
class DiagnosisResult(NamedSteps):
    """What `diagnose` found. `to_json()` is the JSON output (spec section 7: its names are the
    keys), `result["key"]` reads it; the typed fields (`steps`, `screens`, `history`, `log`) carry
    what the report draws; `str()` (or `summary()`) is the step table."""

    baseline: dict
    steps: tuple  # Step per named effect
    final: dict
    unexplained: bool
    confounded: list
    unexplained_where: list
    verdict: str
    log: tuple  # the step log's records (log.Note); `notes` are their sentences
    detectors: dict
    speed: dict
    ranking: list
    screens: tuple  # screen.Screen per search step
    method: str
    wall_time: float
    history: tuple = ()  # ModelFit per model: the baseline, then after each named effect
    drift: list = field(default_factory=list)  # identification.drift.Drift.to_json() per drifting parameter
    budget: dict = field(default_factory=dict)  # {"seconds", "bound", "cut"}: what the time budget cut
    final_polar: tuple = ()  # PolarEstimate per named pair effect, at the final fit
    final_harmonics: list = field(default_factory=list)  # the final model's housing harmonics (labels)
    # [effect, baseline parameter]: an effect this record cannot tell from a fitted baseline
    # parameter (an offset inside mu at one speed); `confounded` holds pairs of effects only
    hidden_in_baseline: list = field(default_factory=list)

    JSON = ("baseline", "steps", "effects", "final", "unexplained", "confounded", "hidden_in_baseline",
            "unexplained_where", "verdict", "notes", "detectors", "speed", "ranking", "screens", "rejected",
            "method", "wall_time", "drift", "budget")


    white_alpha = WHITE_ALPHA

    @property
    def residual_tests_white(self) -> bool:
        """The final residual passes the runs and Ljung-Box tests at WHITE_ALPHA. The verdict may
        still call a non-white remainder below the relevance bar consistent (final.residual_white)."""
        return min(self.final["runs_p_value"], self.final["ljung_box_p_value"]) >= WHITE_ALPHA

    @property
    def rejected(self) -> list[dict]:
        return [n.to_json() for n in self.log if isinstance(n, Rejected)]

    def to_json(self) -> dict:
        out = {k: getattr(self, k) for k in self.JSON}
        # residual_white holds the verdict's view (a non-white remainder below the relevance bar is
        # consistent); the tests' own answer beside it, so the JSON says what the text says
        out["final"] = {**out["final"], "residual_tests_white": self.residual_tests_white}
        out["steps"] = [s.to_json() for s in self.steps]
        out["screens"] = [s.to_json() for s in self.screens]
        return out

    def __getitem__(self, key):  # read like the JSON
        if key not in self.JSON:
            raise KeyError(key)
        return self.to_json()[key] if key in ("steps", "screens") else getattr(self, key)

    def __contains__(self, key):
        return key in self.JSON

    def __str__(self):
        return self.summary()

    def __repr__(self):
        return (f"<DiagnosisResult: effects {', '.join(self.effects) or 'none'}; final RMS "
                f"{self.final['rms']:.4g} N m; unexplained {self.unexplained}; confounded {self.confounded}>")

    def summary(self) -> str:
        """The step table: baseline, each named effect, the final model, the verdict and the notes."""
        lines = [f"{'step':<28}{'RMS before':>13}{'RMS after':>13}{'p-value':>11}  parameters"]
        lines.append(f"{'baseline':<28}{'':>13}{self.baseline['rms']:>13.5g}{'':>11}  " + ", ".join(
            parameter_text(k, v["value"], v["stderr"]) for k, v in self.baseline["params"].items()))
        for s in self.steps:
            ps = ", ".join(s.parameter_texts())
            lines.append(f"{s.effect.name:<28}{s.rms_before:>13.5g}{s.rms_after:>13.5g}{s.p_value:>11.2g}  {ps}")
        f = self.final
        lines.append(f"final: RMS {f['rms']:.5g}, mu (mean over vanes) {_fmt_param(f['params'].get('mu'))}; "
                     f"detectors p: runs {f['runs_p_value']:.2g}, Ljung-Box {f['ljung_box_p_value']:.2g}, "
                     f"synchronous F {f['synchronous_f_p_value']:.2g}, noise level {f['noise_level_p_value']:.2g}")
        if "effects.vane_friction_factor.1" in f["params"]:
            lines.append("vane COFs: " + ", ".join(f"{i}: {v['value']:.4g}" for i, v in enumerate(f["vane_mu"])))
        where = ", ".join((f"order {w['order']}" if "order" in w else f"{w['angle_deg']} deg")
                          for w in self.unexplained_where) or "broadband"
        lines.append(f"verdict: {self.verdict}" + (f" (at {where})" if self.unexplained else ""))
        lines += [f"confounded: {a} ~ {b}" for a, b in self.confounded]
        lines += [f"cannot be told from the fitted {b} on this data: {a}" for a, b in self.hidden_in_baseline]
        lines += [f"note: {n}" for n in self.notes]
        lines.append(PLUS_MINUS)
        if not self.residual_tests_white:
            lines.append(OPTIMISTIC)
        return "\n".join(lines)


def _fmt_param(v) -> str:
    if v is None or v["value"] is None:
        return "not determined"
    return f"{v['value']:.4g} ± {v['stderr']:.2g}"
