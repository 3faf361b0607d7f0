"""The discrepancy workflow on a bench log (spec §10): fit the baseline (the vane COF), test the
residual against noise, screen the pump-level library (pump_effects) by score tests, refit the
best few, name one only by the torque workflow's rules (likelihood ratio, BIC, a naming size, a
decisive BIC lead over any rival), repeat; else say `unexplained`, and where.

Cost is counted in model runs of the whole log (a run is ~1-10 CPU s): the screen needs one run
per candidate (its secant column at the current fit, over a clear fault's size: a loose
integrator's error stays far below it), a refit ~(1 + parameters) runs per Gauss-Newton step. The
statistics are the torque workflow's (state: AR(1) prewhitening, BIC, the likelihood-ratio
comparison; options: the levels; verdict: the wording); the residual is each channel over its
noise sigma (pumpdown_fit), stacked."""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field

import numpy as np

from ..blas import small_solves
from ..benchlog import start_above_atmosphere
from ..distributions import chi2_sf, norm_sf
from ..identification.bench_model import START_NAME
from ..identification.optimiser import NO_STEP_FROM_START, START_TEST_LEVEL, scaled_svd, start_test
from ..identification.pumpdown_fit import UNITS
from ..identification.result import fit_estimates
from ..signals import high_frequency_noise, ljung_box, quantization_step, runs_test
from ..tolerances import BENCH_FIT_ATOL, BENCH_FIT_RTOL
from .log import Budgeted, BudgetReached, DataNote, Note, NotConverged, Rejected, TooSmall, unconverged_fits
from .options import OPTIONS, DiagnosisOptions
from .pump_guard import Inconsistent, consistency
from .pump_effects import OF_PARAM, Drives, EffectProblem, PumpEffect, library, unweighted
from .pump_result import (
    NOISE_UNIT,
    BenchDiagnosis,
    BenchModelFit,
    BenchStep,
    estimates_json,
)
from .state import ar1, bic, lr_bic
from .verdict import verdict_notes, verdict_of

# fitted in every model: the vane COF is what a bench log is read for, and the booster's pressure at
# the first sample (a nuisance): the log's quadratic start estimate is tens of Pa off at 0.5 % noise,
# and on a clean 0.5 s twin that start biased the fitted vane COF by 0.8 % and left each channel's
# residual mean 0.4-0.7 noise sigmas off (the mean-level detector's false alarm); fitted, mu is
# within 0.03 % and the means within 0.12 sigma
BASELINE = ("mu", START_NAME)
CONTENDERS = 2  # refitted per step (a refit is ~10 runs of the log; the score ranks well)
FIT_ITERATIONS = 8
STOP_RSS = 0.1  # a fit stops when a step gains less (noise sigmas squared): no likelihood ratio moves
SAME_MODEL = 1 - 1e-6  # |cos| of two candidates' columns above which they are one model (identical runs)
DETECTORS = ("runs_test", "ljung_box", "noise_level", "mean_level")
WHERE_WINDOWS = 25  # the unexplained residual's moving mean spans 1/25 of a channel
WHERE_Z = 4.0  # a window mean this many standard errors from 0 is systematic


@dataclass(frozen=True)
class Absorbed(Note):
    """A candidate whose signature on this log lies inside the fitted parameters' (|cos| above the
    collinearity bar): its change would be read as theirs."""

    effect: str
    partner: str
    cos: float

    def text(self) -> str:
        return (f"{self.effect}'s signature on this log lies within {self.partner}'s (|cos| {self.cos:.4f}): such a "
                f"change would read as {self.partner}")


@dataclass(frozen=True)
class Confounded(Note):
    """Two effects the log cannot tell apart, and what would."""

    first: str
    second: str
    how: str
    cos: float  # |cos| of their columns projected off the fitted ones
    decisive: float | None = None  # None: collinear; else rivals without a BIC lead this large

    def text(self) -> str:
        if self.decisive is not None:
            why = f"explain this log equally well (within {self.decisive:g} BIC)"
        else:
            why = ("act identically on this log" if self.cos > SAME_MODEL else
                   f"have collinear signatures on this log (|cos| {self.cos:.4f})")
        return f"{self.first} and {self.second} {why}: neither is named; to separate them: {self.how}"


@dataclass(frozen=True)
class Alias(Note):
    """A named effect that a change outside the library reads the same as on a pump-down log."""

    effect: str
    alias: str
    how: str

    def text(self) -> str:
        return (f"{self.effect} is named assuming calibrated sensors: {self.alias} reads the same on a pump-down "
                f"log; to rule it out: {self.how}")


@dataclass
class Fit:
    """One model's fit: its fitted names, every value it holds, the residual (noise sigmas) and
    Jacobian at the fit."""

    names: list
    values: dict
    residual: np.ndarray
    jacobian: np.ndarray
    converged: bool
    prob: EffectProblem
    why: str = ""  # how the fit stopped when it did not converge (gauss_newton)

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.residual ** 2)))

    def estimates(self) -> dict:
        x = np.array([self.values[n] for n in self.names])
        return fit_estimates(self.names, x, list(self.prob.x0), self.residual, self.jacobian)[0]


def mean_level(r, sigma, relevant) -> dict:
    """Two-sided z-test of a channel's residual mean against 0, `sigma` the channel's white-noise
    level: the runs test (about the median), Ljung-Box and the noise level all remove the mean, so a
    channel read a few per cent off everywhere (a sensor's gain, the fitted vane COF absorbing it
    elsewhere) would pass them. A mean below `relevant` noise sigmas counts as none (p 1): the
    model's block-mean current is not the log's trapezoidal one (the ripple aliases at a bench's
    sample rate), and on a clean 0.5 s twin at 0.5 % noise the fitted vane COF leaves each channel's
    mean ~0.4 sigma off -- significant on 250 samples, and no effect's worth naming."""
    r = np.asarray(r, float)
    mean = float(np.mean(r)) / max(sigma, 1e-300)
    z = mean * math.sqrt(r.size)
    p = float(min(1.0, 2.0 * norm_sf(abs(z)))) if abs(mean) >= relevant else 1.0
    return {"z": z, "mean": mean, "p_value": p}


class BenchDetection:
    """Is a residual noise? Per channel the runs test, Ljung-Box, the noise level (variance
    against the high-frequency estimate) and the mean level; the family p is Bonferroni over
    detectors and channels.
    Reads as the torque Detection for the verdict (p["family"], systematic, sigma, consistent)."""

    def __init__(self, residual, sizes, names, fitted, opts: DiagnosisOptions = OPTIONS, floors=None):
        self.opts = opts
        self.pieces = dict(zip(names, np.split(residual, np.cumsum(sizes)[:-1])))
        self.per = {c: {"runs_test": runs_test(r), "ljung_box": ljung_box(r, fitted=fitted),
                        "noise_level": high_frequency_noise(r)} for c, r in self.pieces.items()}
        # a channel rounded coarser than its noise (floors: its rounding's sigma, in noise sigmas): its
        # residual is the rounding's staircase, neither white nor a model error -- not tested
        self.rounded = [c for c in names if (floors or {}).get(c, 0.0) > self.per[c]["noise_level"]["sigma"]]
        for c in self.rounded:
            self.per[c] = {d: {"p_value": 1.0} for d in ("runs_test", "ljung_box")}
            self.per[c]["noise_level"] = {"p_value": 1.0, "sigma": floors[c]}
        for c, r in self.pieces.items():
            self.per[c]["mean_level"] = mean_level(r, self.per[c]["noise_level"]["sigma"], opts.relevant)
        k = len(DETECTORS) * len(self.per)
        self.p = {d: min(1.0, len(self.per) * min(m[d]["p_value"] for m in self.per.values())) for d in DETECTORS}
        self.p["family"] = min(1.0, k * min(m[d]["p_value"] for m in self.per.values() for d in DETECTORS))
        self.channel_p = {c: min(1.0, k * min(m[d]["p_value"] for d in DETECTORS)) for c, m in self.per.items()}
        # in noise sigmas (each channel is scaled by its own): the systematic part of each channel
        # (its mean included) over that channel's high-frequency noise level, the largest
        self.sigma = 1.0
        self.floor_sigma = self.sigma  # the relevance bar's noise (detectors.Detection's may be lower)
        self.systematic = max(math.sqrt(max(float(np.mean(r * r)) / self.per[c]["noise_level"]["sigma"] ** 2 - 1.0,
                                            0.0))
                              for c, r in self.pieces.items())

    def searching(self) -> bool:
        return self.p["family"] < self.opts.search_alpha

    def consistent(self) -> bool:
        return self.p["family"] >= self.opts.unexplained_alpha or self.systematic < self.opts.relevant * self.sigma

    def to_json(self) -> dict:
        return {"combined_p": self.p, "per_channel": {c: {d: m[d]["p_value"] for d in DETECTORS}
                                                       for c, m in self.per.items()},
                "systematic_rms": self.systematic, "noise_sigma": self.sigma,
                "relevance_floor": self.opts.relevant * self.sigma, "unit": NOISE_UNIT,
                "rounded_channels": list(self.rounded)}


@dataclass(frozen=True)
class Screened:
    """A candidate's score test at the current fit and its one-step estimate."""

    effect: PumpEffect
    score: float
    p_value: float
    one_step: dict  # the values of the fitted names and the effect's parameter after one step
    direction: np.ndarray  # its column projected off the fitted ones
    inside: float  # |cos| of its column with the fitted span

    def to_json(self, level) -> dict:
        return {"effect": self.effect.name, "score": self.score, "score_p_value": self.p_value,
                "one_step": self.one_step[self.effect.param], "significant": self.p_value < level}


@dataclass
class Run(Budgeted):
    """What every step of one bench-log diagnosis shares."""

    drives: Drives
    opts: DiagnosisOptions
    say: object
    deadline: float | None
    log: list = field(default_factory=list)
    confounded: list = field(default_factory=list)
    budget: dict = field(default_factory=dict)


@small_solves
def diagnose_bench(cfg, log, resistance_known: bool = False, max_effects: int | None = None, progress=None,
                   budget: float | None = None, rtol: float = BENCH_FIT_RTOL, atol: float = BENCH_FIT_ATOL,
                   options: DiagnosisOptions = OPTIONS, atmosphere_known: bool = False) -> BenchDiagnosis:
    """Find, name and add the pump-level effects (pump_effects.PUMP_EFFECTS) that the bench log
    `log` shows against the model of `cfg` (spec §10). resistance_known: the config's
    motor.resistance is measured (a stalled-rotor test), so a series supply resistance can be told
    from a winding-resistance error. atmosphere_known: the log starts with the booster vented and
    the config's booster start (gas.atmosphere) is that day's barometer reading, so the booster
    starts there, not at the log's fitted start reading: a pressure sensor's offset and span then
    show at the start and are told from the pump's effects. budget: wall seconds after which no new
    step or refit starts. rtol, atol: the model integrator's."""
    wall0 = _time.perf_counter()
    effects = library(resistance_known)
    # motor.resistance always: a supply resistance acts through it; the start pressure: the
    # booster starts from the start reading mapped back through the pressure sensor (pump_effects)
    values = {"mu": float(cfg.values["friction.housing.dynamic"]),
              "motor.resistance": float(cfg.pneumatic.values["motor.resistance"]),
              START_NAME: float(cfg.pneumatic.booster_start) if atmosphere_known else log.start_pressure(),
              **{e.param: e.absent_value(cfg) for e in effects}}
    run = Run(Drives(cfg, log, values, rtol, atol, start_known=atmosphere_known), options, progress or (lambda msg: None), None if budget is None else wall0 + budget,
              budget={"seconds": budget, "bound": False, "cut": []})
    run.log += [DataNote(f"the log: {n}") for n in log.notes]
    above = start_above_atmosphere(log, cfg)
    if above:
        run.log.append(DataNote(above))
    run.say("fitting the baseline")
    base = _weighted(run, _fit(run, [n for n in BASELINE if not (atmosphere_known and n == START_NAME)], values, None))
    if not base.converged:
        run.log.append(NotConverged("baseline", base.why))
    current, steps, history, ranking = base, [], [_model_fit("baseline", base)], []
    detection = _detect(current, options)
    limit = options.max_effects if max_effects is None else max_effects
    while len(steps) < limit and detection.searching() and not run.out_of_time("the search for a further effect"):
        named = {OF_PARAM[n].name for n in current.names if n in OF_PARAM}
        screened = _screen(run, current, library(resistance_known, exclude=named))
        ranking = screened
        step = _search_step(run, current, screened, detection)
        if step is None:
            break
        step_record, current = step
        steps.append(step_record)
        history.append(_model_fit(step_record.effect.name, current))
        detection = _detect(current, options)
    return _result(run, base, current, detection, steps, history, ranking, wall0, _guard(current, options, base))


def _fit(run, names, values, start) -> Fit:
    prob = EffectProblem(run.drives, names, values)
    x, r, J, converged, why = gauss_newton(prob, prob.x0 if start is None else np.clip(start, prob.lower, prob.upper))
    return Fit(list(names), {**values, **dict(zip(names, map(float, x)))}, r, J, converged, prob, why)


START_NOT_MINIMUM = (NO_STEP_FROM_START + ", yet the start is NOT a minimum: the model's slope there points {se} "
                     "standard errors away (to {to}; F test p = {p:.2g}); the start may sit on a step of the cost "
                     "(friction reversals make it a staircase)")


def gauss_newton(prob, x, max_iter=FIT_ITERATIONS, halvings=4) -> tuple:
    """Gauss-Newton (column-scaled, bounds by projection, halved steps) stopped once a step lowers
    the residual sum of squares by less than STOP_RSS: the residual is in noise sigmas, so such a
    change moves no test, and a loose integrator's error would make a tighter stop wander. The
    Jacobian of that last small step is the one before it (one run instead of 1 + parameters).
    A fit no step leaves from its start is converged only when the data cannot tell the start from
    a minimum (optimiser.start_test). Returns (x, residual, Jacobian, converged, why): why says
    how a fit that did not converge stopped ("" when it converged)."""
    m, J = prob.model_and_jacobian(x)
    r = prob.y - m
    for it in range(max_iter):
        scale, U, s, Vt = scaled_svd(J)
        keep = s > s[0] * 1e-10
        step = full = (Vt[keep].T @ ((U[:, keep].T @ r) / s[keep])) / scale
        for k in range(halvings):
            xn = np.clip(x + step, prob.lower, prob.upper)
            rn = prob.y - prob.model(xn)
            if rn @ rn < r @ r:
                break
            step = 0.5 * step
        else:  # no step lowers the residual: a minimum, unless the fit never left its start
            return (x, r, J, True, "") if it else (x, r, J, *_stalled_start(prob, x, full, r, J))
        # a halved step's small gain says the model is nonlinear there, not that the fit is done
        gain = float(r @ r - rn @ rn)
        small = k == 0 and gain < STOP_RSS
        x, r = xn, rn
        if small:
            return x, r, J, True, ""
        J = prob.model_and_jacobian(x)[1]
    return x, r, J, False, (f"{max_iter} Gauss-Newton step{'s' if max_iter != 1 else ''} did not settle: the last "
                            f"lowered the residual sum of "
                            f"squares by {gain:.3g} ({NOISE_UNIT} squared; a fit stops below {STOP_RSS:g})")


def _stalled_start(prob, x, full, r, J) -> tuple:
    """(converged, why) of a fit no step leaves from its start x (full: the Gauss-Newton step
    there): start_test on the residual in noise sigmas, over the values weighed (a value of
    infinite weight, the current's switch-on block, counts for nothing)."""
    n = int(np.count_nonzero(np.isfinite(np.broadcast_to(getattr(prob, "w", 1.0), r.shape))))
    se, p = start_test(x, full, r, J, prob.lower, prob.upper, n)
    if p >= START_TEST_LEVEL:
        return True, ""
    to = ", ".join(f"{nm} = {v:.6g}" for nm, v in zip(prob.names, np.clip(x + full, prob.lower, prob.upper)))
    length = f"{se:.3g}" if np.isfinite(se) else "infinitely many (noise-free data)"
    return False, START_NOT_MINIMUM.format(se=length, p=p, to=to)


def _weighted(run, fit: Fit) -> Fit:
    """The baseline fit with each channel weighted by its residual's own noise level
    (Drives.set_weights): its residual and Jacobian rescaled, no run."""
    run.drives.set_weights(fit.residual)
    prob = EffectProblem(run.drives, fit.names, fit.values)
    w = prob.w / fit.prob.w
    return Fit(fit.names, fit.values, fit.residual / w, fit.jacobian / w[:, None], fit.converged, prob, fit.why)


def _detect(fit: Fit, opts) -> BenchDetection:
    p = fit.prob
    base = p.drives.get(0.0)
    return BenchDetection(fit.residual, [base.measured[c].size for c in p.channel_names],
                          p.channel_names, len(fit.names), opts, p.drives.rounding_floors())


def _guard(fit: Fit, opts, base: Fit) -> dict:
    """The final model's consistency over the log's time parts (pump_guard), its relevance measured
    also against what the named effects explain (the baseline `base`'s residual less the fit's): no run."""
    p = fit.prob
    inner = p.drives.get(0.0)
    # the start pressure is a nuisance of the first samples alone: the parts are compared in the rest
    keep = [j for j, n in enumerate(fit.names) if n != START_NAME]
    return consistency([fit.names[j] for j in keep], fit.values, fit.residual, fit.jacobian[:, keep],
                       [inner.bench.times(c) for c in p.channel_names],
                       (inner.bench.times("booster_pressure"), inner.measured["booster_pressure"]), opts,
                       explained=max(float(base.residual @ base.residual - fit.residual @ fit.residual), 0.0))


def _screen(run, current: Fit, effects) -> list:
    """Each candidate's score test at the current fit from its secant column over a clear fault's
    size (one run each), ranked by the statistic. Not prewhitened: the channels are scaled by their
    white-noise sigmas, and the current residual's autocorrelation is the misfit's (a smooth
    pressure gap), not the noise's -- a filter fitted to it would leave only the misfit's slope.
    Coloured noise is guarded against where an effect is accepted (_judge)."""
    r, Jb = current.residual, current.jacobian
    Q = np.linalg.qr(Jb)[0]
    Mr = r - Q @ (Q.T @ r)
    sigma2 = float(Mr @ Mr) / max(r.size - Jb.shape[1], 1)
    m0 = current.prob.model(np.array([current.values[n] for n in current.names]))
    out = []
    for e in effects:
        run.say(f"screening {e.name}")
        prob = EffectProblem(run.drives, current.names + [e.param], current.values)
        c = prob.column(prob.x0, len(current.names), e.probe, m0)
        Mc = c - Q @ (Q.T @ c)
        inside = float(np.linalg.norm(Q.T @ c) / max(np.linalg.norm(c), 1e-300))
        mc2 = float(Mc @ Mc)
        lm = float(Mr @ Mc) ** 2 / max(mc2, 1e-300) / max(sigma2, 1e-300) if mc2 > 0 else 0.0
        coef = float(Mr @ Mc) / mc2 if mc2 > 0 else 0.0
        base = np.linalg.lstsq(Jb, r - c * coef, rcond=None)[0]
        one = {n: current.values[n] + d for n, d in zip(current.names, base)}
        one[e.param] = float(np.clip(current.values[e.param] + coef, prob.lower[-1], prob.upper[-1]))
        out.append(Screened(e, lm, float(chi2_sf(lm, 1)), one, Mc, inside))
    return sorted(out, key=lambda s: -s.score)


def cosine(a, b) -> float:
    return abs(float(a @ b)) / max(float(np.linalg.norm(a) * np.linalg.norm(b)), 1e-300)


def _groups(significant: list, collinear: float) -> list:
    """The significant candidates in groups whose projected directions are collinear beyond
    `collinear`, in rank order: the log cannot tell them apart. Their nonlinear refits cannot
    either -- on a 0.5 s twin of a grown tip clearance (|cos| > 0.995 with a booster leak) the
    leak's refit led the truth's by 15 in BIC, the loose integrator's error and the noise deciding --
    so a group is refitted once and, if it explains the log, reported `confounded`."""
    groups = []
    for s in significant:
        g = next((g for g in groups if cosine(g[0].direction, s.direction) > collinear), None)
        if g is None:
            groups.append([s])
        else:
            g.append(s)
    return groups


def _search_step(run, current: Fit, screened: list, detection):
    """One step: the CONTENDERS best significant groups refitted (a group of candidates the log
    cannot tell apart once); the best by BIC that passes the acceptance rules is named, unless it
    is a group of several or a rival within the decisive BIC margin: then `confounded`. Returns
    (BenchStep, the new fit) or None."""
    opts = run.opts
    level = opts.score_alpha / max(len(screened), 1)
    for s in screened:
        if s.inside > opts.collinear:
            run.log.append(Absorbed(s.effect.name, ", ".join(current.names), s.inside))
    significant = [s for s in screened if s.p_value < level and s.inside <= opts.collinear]
    groups = sorted(_groups(significant, opts.collinear), key=lambda g: _one_step_rss(run, current, g[0]))
    judged = []
    for g in groups[:CONTENDERS]:
        if run.out_of_time(f"the refit of {g[0].effect.name}"):
            break
        run.say(f"refitting {g[0].effect.name}")
        judged.append(_judge(run, current, g, detection))
    fitting = sorted((j for j in judged if j["passes"]), key=lambda j: j["bic1"])
    passing = [j for j in fitting if not j["wrong_way"]]
    if not passing:
        return None
    best = passing[0]
    # a one-way effect that fits as well only when moved the impossible way says the log holds
    # something the library does not describe: nothing is named at this step
    blocker = next((j for j in fitting if j["wrong_way"] and j["bic1"] - best["bic1"] < opts.bic_decisive), None)
    if blocker is not None:
        run.log.append(Rejected(best["group"][0].effect.name, (
            f"{blocker['group'][0].effect.name} fits the log as well (BIC {blocker['bic1']:.1f} against "
            f"{best['bic1']:.1f}) only the impossible way: the log holds a change the library does not describe",)))
        return None
    rival = next((j for j in passing[1:] if j["bic1"] - best["bic1"] < opts.bic_decisive), None)
    if len(best["group"]) > 1 or rival is not None:
        first = best["group"][0].effect
        for other in [g.effect for g in best["group"][1:]] + ([rival["group"][0].effect] if rival else []):
            pair = [first.name, other.name]
            if pair not in run.confounded:
                run.confounded.append(pair)
                how = "; or ".join(e.separate for e in (first, other) if e.separate) or "a second experiment"
                grouped = rival is None or other is not rival["group"][0].effect
                cos = cosine(best["group"][0].direction, (rival["group"][0] if not grouped else
                                                          next(g for g in best["group"] if g.effect is other)).direction)
                run.log.append(Confounded(*pair, how, cos, None if grouped else opts.bic_decisive))
        return None
    e = best["group"][0].effect
    if e.alias and not run.drives.start_known:  # a known start tells the span from the pump (pump_effects)
        run.log.append(Alias(e.name, e.alias, e.separate))
    return _step(best, current), best["fit"]


def _one_step_rss(run, current: Fit, s: Screened) -> float:
    """The residual sum of squares of the model at the candidate's one-step values (one run): a
    look past the linearisation that ranks the contenders (the score test alone ranks a nonlinear
    effect's linear shadow)."""
    names = current.names + [s.effect.param]
    prob = EffectProblem(run.drives, names, {**current.values, **s.one_step})
    r = prob.y - prob.model(prob.x0)
    return float(r @ r)


def _judge(run, current: Fit, group: list, detection) -> dict:
    """The group's first candidate refitted from its one-step values and compared with the current
    model: prewhitened and plain likelihood ratios, BIC, and the size of the change it makes."""
    s = group[0]
    names = current.names + [s.effect.param]
    fit = _fit(run, names, {**current.values, **s.one_step}, np.array([s.one_step[n] for n in names]))
    if not fit.converged:
        run.log.append(NotConverged(s.effect.name, fit.why))
    # the noise's AR(1) under the hypothesis tested, as an F-test's variance is the larger model's:
    # the current residual's would be the misfit's
    rho = ar1(fit.residual)
    comp = lr_bic(current, len(current.names), fit, len(names), rho, None)
    lr_p = max(float(chi2_sf(comp.lr, 1)), float(chi2_sf(comp.lr_plain, 1)))
    n = current.residual.size
    # contenders are compared by the plain BIC (each one's prewhitening filter is its own)
    bic0, bic1 = bic(float(current.residual @ current.residual), n, len(current.names)), \
        bic(float(fit.residual @ fit.residual), n, len(names))
    size = min(float(np.sqrt(np.mean((fit.residual - current.residual) ** 2))),
               math.sqrt(max(float(current.residual @ current.residual - fit.residual @ fit.residual), 0.0) / n))
    passes = lr_p < run.opts.lr_alpha and comp.bic1 < comp.bic0 and bic1 < bic0
    wrong_way = s.effect.wrong_way(fit.values[s.effect.param] - s.effect.absent_value(current.prob.drives.cfg))
    if passes and wrong_way:
        run.log.append(Rejected(s.effect.name, (wrong_way,)))
    if passes and size < run.opts.named_size * detection.sigma:
        run.log.append(TooSmall(s.effect.name, size, run.opts.named_size, detection.sigma, NOISE_UNIT,
                                "the logged channels"))
        passes = False
    run.say(f"{s.effect.name}: RMS {current.rms:.4g} -> {fit.rms:.4g}, BIC {comp.bic0:.1f} -> {comp.bic1:.1f}, "
            f"LR p {lr_p:.2g}, size {size:.3g}, {s.effect.param} = {fit.values[s.effect.param]:.4g}")
    return {"group": group, "fit": fit, "lr_p": lr_p, "bic0": bic0, "bic1": bic1, "size": size,
            "passes": passes, "wrong_way": wrong_way}


def _step(j: dict, current: Fit) -> BenchStep:
    s, fit = j["group"][0], j["fit"]
    e = s.effect
    est = estimates_json({e.param: fit.estimates()[e.param]})
    est["change"] = fit.values[e.param] - e.absent_value(current.prob.drives.cfg)
    return BenchStep(e, est, current.rms, fit.rms, s.p_value, s.score, j["lr_p"], j["bic0"], j["bic1"], j["size"])


def _model_fit(label, fit: Fit) -> BenchModelFit:
    x = np.array([fit.values[n] for n in fit.names])
    return BenchModelFit(label, fit.rms, estimates_json(fit.estimates()), dict(fit.prob.channels(x)))


def where_unexplained(fit: Fit, detection: BenchDetection, opts: DiagnosisOptions = OPTIONS) -> list:
    """Where a channel's residual departs from noise: the spans (time, and the booster pressure
    there) whose moving mean over 1/WHERE_WINDOWS of the channel lies WHERE_Z standard errors from
    0, the largest two per rejecting channel, with the mean residual in the channel's unit."""
    inner = fit.prob.drives.get(0.0)
    tp, pb = inner.bench.times("booster_pressure"), inner.measured["booster_pressure"]
    out = []
    w = np.broadcast_to(fit.prob.w, fit.residual.shape)
    weights = dict(zip(detection.pieces, np.split(w, np.cumsum([r.size for r in detection.pieces.values()])[:-1])))
    for c, r in detection.pieces.items():
        if detection.channel_p[c] >= opts.unexplained_alpha or r.size < 2 * WHERE_WINDOWS:
            continue
        w = max(r.size // WHERE_WINDOWS, 3)
        mm = np.convolve(r, np.ones(w) / w, mode="same")
        flagged = np.abs(mm) > WHERE_Z * detection.per[c]["noise_level"]["sigma"] / math.sqrt(w)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], flagged.astype(int), [0]])))
        spans = sorted(zip(edges[::2], edges[1::2]), key=lambda ab: -abs(float(np.sum(r[ab[0]:ab[1]]))))[:2]
        t = inner.bench.times(c)
        for a, b in spans:
            p = np.interp(t[a:b], tp, pb)
            out.append({"channel": c, "time": [float(t[a]), float(t[b - 1])], "pressure": [float(p.min()), float(p.max())],
                        "mean_residual": float(np.mean(unweighted(r[a:b], weights[c][a:b])) * inner.sigma[c]),
                        "unit": UNITS[c]})
    return out


def method_text(opts: DiagnosisOptions = OPTIONS) -> str:
    return ("detectors per channel (noise-scaled): runs, Ljung-Box, noise level (family "
            f"{opts.unexplained_alpha:g}, Bonferroni over detectors and channels); candidates: score "
            f"tests from secant columns at the current fit; the {CONTENDERS} best refitted (Gauss-Newton); "
            f"acceptance by prewhitened and plain likelihood ratio (p < {opts.lr_alpha:g}), BIC, a model change of "
            f"at least {opts.named_size:g} noise sigmas and a BIC lead of {opts.bic_decisive:g} over any rival")


def _result(run, base: Fit, current: Fit, detection, steps, history, ranking, wall0, guard) -> BenchDiagnosis:
    opts = run.opts
    named = [s.effect.name for s in steps]
    verdict = verdict_of(detection, named, [], opts, NOISE_UNIT,
                         unconverged=unconverged_fits(run.log, ["baseline", *named]))
    text, withdrawn = verdict.text, ()
    # the names of a model that does not describe the log are no answer, nor is "consistent with
    # noise" (where the detectors already say unexplained and nothing is named, that verdict stands)
    inadequate = guard["fires"] and (bool(steps) or verdict.consistent)
    if inadequate:
        withdrawn, steps = tuple(steps), []
        run.log = [n for n in run.log if not isinstance(n, Alias)]  # said of names no longer given
        text = "model inadequate: nothing named; unexplained"
        run.log.append(Inconsistent(tuple(current.names), tuple(s.effect.name for s in withdrawn), guard["statistic"],
                                    guard["dof"], guard["p_value"], guard["alpha"], guard["worst"]))
    if run.confounded:
        text += "; confounded: " + ", ".join(" ~ ".join(p) for p in run.confounded)
    inner = current.prob.drives.get(0.0)
    for c in detection.rounded:
        step = quantization_step(inner.measured[c])
        run.log.append(DataNote(f"{c} is rounded to steps of {step:.4g} {UNITS[c]}, coarser than its noise: "
                                "its residual (the rounding's staircase) counts as noise of step/sqrt(12) and is not "
                                "tested for whiteness"))
    run.log += [n for n in verdict_notes(detection, {"p_value": 1.0, "excess_rms": 0.0, "mad_sigma": 1.0},
                                         verdict.consistent, opts, NOISE_UNIT)]
    if run.budget.get("bound"):
        run.log.append(BudgetReached(run.budget["seconds"], tuple(run.budget["cut"])))
    p = detection.p
    level = opts.score_alpha / max(len(ranking), 1)
    return BenchDiagnosis(
        baseline={"rms": base.rms, "params": history[0].params, "converged": base.converged}, steps=tuple(steps),
        final={"rms": current.rms, "params": history[-1].params, "converged": current.converged,
               "residual_white": verdict.consistent,
               "runs_p_value": p["runs_test"], "ljung_box_p_value": p["ljung_box"],
               "noise_level_p_value": p["noise_level"], "mean_level_p_value": p["mean_level"]},
        unexplained=not verdict.consistent or inadequate, confounded=run.confounded,
        unexplained_where=[] if verdict.consistent else where_unexplained(current, detection, opts),
        verdict=text, log=tuple(run.log), detectors=detection.to_json(),
        ranking=[s.to_json(level) for s in ranking], method=method_text(opts),
        wall_time=_time.perf_counter() - wall0, measured=dict(inner.measured),
        times={c: inner.bench.times(c) for c in inner.channel_names}, noise=dict(inner.sigma),
        history=tuple(history), budget=run.budget, runs=run.drives.runs, withdrawn=withdrawn, consistency=guard)
