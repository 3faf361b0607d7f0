"""The `diagnose` driver: speed, baseline, search steps, verdict."""
from __future__ import annotations

import dataclasses
import sys
import time as _time
from dataclasses import dataclass, field

import numpy as np

from ..config import PumpConfig
from ..data import Dataset
from ..diagnostics import synchronous_speed_scan
from ..errors import ConfigError
from ..identification import base_name, half_band, speed_band

from .detectors import Detection, kurtosis_off_reversals, where_unexplained
from .effects import candidates, plausible
from .options import BIC_DECISIVE, MAX_EFFECTS, RELEVANT, SCORE_ALPHA, SCREEN_SAMPLES, SPEED_DETERMINED, UNEXPLAINED_ALPHA
from .refit import contender_fits, try_speed
from .result import DiagnosisResult, MU_DEFINITION, effect_params, params_json, vane_cofs
from .screen import detected_ripple_orders, note_confounded, rank_candidates, score_test, screen_table
from .selection import accept, drop_superseded, find_rival
from .state import State, ar1, identify, measurement_of, on_kept
from .verdict import METHOD, confounded_notes, drift_findings


def _screen(datasets):
    """The search's window: the first samples of each measurement, SCREEN_SAMPLES in all."""
    each = max(SCREEN_SAMPLES // len(datasets), 64)
    if all(d.n <= each for d in datasets):
        return datasets
    return [d.window(0, min(d.n, each)) for d in datasets]


def _fit(cfg, data, names, values, ripple, screen, multistart=True, screen_hold=()):
    """identify on the screening window first (cheap), then polished on the whole record.
    `screen_hold`: names the window fit keeps at their values because the whole record already
    determines them better (a speed from the synchronous scan of the whole record: a window of a
    tenth of the record would estimate it ten times less precisely, and the whole-record polish
    would spend its costly iterations undoing the phase drift that error makes)."""
    held = {k: v for k, v in values.items() if k not in names}
    init = {n: values[n] for n in names if n in values}
    if screen is not data:
        sn = [n for n in names if n not in screen_hold or n not in init]
        sheld = {**held, **{n: init[n] for n in names if n not in sn}}
        r0 = identify(cfg, screen, sn, initial={n: init[n] for n in sn if n in init}, multistart=multistart,
                      ripple_order=ripple, extra=sheld)
        init.update({n: e.value for n, e in r0.estimates.items() if e.value is not None})
        multistart = False
    return identify(cfg, data, names, initial=init, multistart=multistart, ripple_order=ripple, extra=held)


@dataclass
class _Run:
    """What every step of one diagnosis shares: the data (whole record and screening window),
    the torque scale the plausibility ranges need, and the notes and lists the steps add to."""

    cfg: PumpConfig
    datasets: list
    full_data: object
    screen_data: object
    free: list
    say: object
    speed_info: dict
    notes: list = field(default_factory=list)
    rejected: list = field(default_factory=list)
    confounded: list = field(default_factory=list)
    torque_rms: float = 0.0
    mean_torque: float = 0.0
    added: list = field(default_factory=list)  # per named effect: the fitted names it added
    deadline: float | None = None  # perf_counter() after which no new step or refit starts
    budget: dict = field(default_factory=dict)

    def implausible(self, st) -> list:
        return plausible(st.cfg, st.values, self.torque_rms, self.mean_torque)

    def out_of_time(self, what: str) -> bool:
        """True (and `what` listed as cut) once the time budget is spent."""
        if self.deadline is None or _time.perf_counter() < self.deadline:
            return False
        self.budget["bound"] = True
        self.budget["cut"].append(what)
        return True


def diagnose(cfg: PumpConfig, data: Dataset, max_effects: int = MAX_EFFECTS, progress=None,
             baseline_params=None, speed_tolerance: float | None = None,
             budget: float | None = None) -> DiagnosisResult:
    """Find, name and add the effects missing from the model of `cfg` that the measurement(s)
    `data` (a Dataset or a list: several speeds fitted together) show.

    speed_tolerance: relative band about the configured speed for measurements without a speed
    column (default: the config's operation.speed_tolerance, 0.02).
    budget: wall seconds after which no further search step or contender refit starts (None: no
    limit); what it cut is in the result's `budget` and notes. Returns a DiagnosisResult."""
    wall0 = _time.perf_counter()
    datasets = list(data) if isinstance(data, (list, tuple)) else [data]
    if speed_tolerance is not None:
        if not 0 <= speed_tolerance <= 0.5:
            raise ConfigError(f"--speed-tolerance must be in [0, 0.5], got {speed_tolerance:g}")
        cfg = dataclasses.replace(cfg, speed_tolerance=float(speed_tolerance))
    run, held = _start(cfg, datasets, progress)
    run.deadline = None if budget is None else wall0 + budget
    run.budget = {"seconds": budget, "bound": False, "cut": []}
    base, state = _baseline(run, baseline_params, held)
    current = base
    history = [{"label": "baseline", "result": base}]
    steps, effects, ranking, screens = [], [], [], []
    verdict = Detection(current, datasets, len(state.names))
    rival_pair = None
    for _ in range(max_effects):
        if not verdict.searching():
            break
        if run.out_of_time("the search for a further effect"):
            break
        found = _search_step(run, state, current, verdict, effects, screens)
        ranking = found["ranking"]
        rival_pair = found.get("rival_pair", rival_pair)
        if "accepted" not in found:
            break
        state, current = _add_effect(run, found, state, current, steps, effects, screens)
        history.append({"label": found["accepted"]["cand"].label, "result": current})
        state, current = drop_superseded(run, state, current, steps, effects, history)
        verdict = Detection(current, datasets, len(state.names))
    return _result(run, base, state, current, verdict, steps, effects, ranking, screens, rival_pair,
                   history, wall0)


def _start(cfg, datasets, progress):
    """Step 1, the speed: nominal, refined in its band from shaft-synchronous evidence only; and
    the screening window. Returns the run's context and the held speeds by fit name."""
    K = len(datasets)
    free = [i for i, d in enumerate(datasets) if d.speed is None] if cfg.mode == "speed" else []
    held, speed_info = {}, {"nominal": cfg.speed, "tolerance": cfg.speed_tolerance, "measurements": []}
    for i, d in enumerate(datasets):
        if i not in free:
            speed_info["measurements"].append({"source": "speed column", "value": d.mean_speed(),
                                               **_speed_trend_info(d)})
            continue
        lo, hi = cfg.speed * (1 - cfg.speed_tolerance), cfg.speed * (1 + cfg.speed_tolerance)
        # evidence of the speed only at the orders the pump's own torque has: multiples of the vane
        # count (identical, equally spaced vanes in a housing-fixed geometry repeat every vane
        # passage); a disturbance that happens to repeat at another order at a speed in the band is
        # no evidence (F16: a pulse train at 1.27 x the shaft frequency looked like order 5 at +1.6 %
        # on the concentric 4-vane rig, whose torque has no angle dependence at all)
        scan = synchronous_speed_scan(d.time, d.torque, lo, hi, cfg.speed, order=cfg.vanes)
        held[f"speed@{i}" if K > 1 else "speed"] = scan["speed"]
        speed_info["measurements"].append({"source": "synchronous scan" if scan["refined"] else "nominal",
                                           "value": scan["speed"], "scan_p_value": scan["p_value"]})
    # one measurement with a noisy speed column: its mean is known to a few standard errors (a band
    # of ~1e-4 of the speed, too narrow for a disturbance to pull it onto its own frequency), and the
    # speed is refined inside it as a nominal speed is inside its tolerance (baseline, and after an
    # effect makes the torque depend on the angle), and where the held mean turns a named effect's
    # phase over the record (stationary_at_its_speed)
    if K == 1 and cfg.mode == "speed" and datasets[0].speed is not None and speed_band(cfg, datasets[0]):
        free = [0]
    screen = _screen(datasets)
    full_data = datasets if K > 1 else datasets[0]
    screen_data = full_data if screen is datasets else (screen if K > 1 else screen[0])
    y_all = np.concatenate([d.torque for d in datasets])
    run = _Run(cfg, datasets, full_data, screen_data, free, progress or (lambda msg: None), speed_info,
               torque_rms=float(np.sqrt(np.mean(y_all ** 2))), mean_torque=float(np.mean(y_all)))
    for i, m in enumerate(speed_info["measurements"]):
        if "trend" in m:
            run.notes.append(f"speed column of measurement {i} drifts ({100 * m['trend']['relative_change']:.2g} % "
                             "over the record): the model's angle and speed follow its smoothed trend")
    return run, held


def _speed_trend_info(d) -> dict:
    """A speed column's significant slow trend (pumpsim.data.speed_trend), which the fits follow."""
    tr = d.speed_trend()
    return {} if tr is None else {"trend": {"degree": tr.degree, "relative_change": tr.change(),
                                            "p_value": tr.p_value}}


def _baseline(run, baseline_params, held):
    """Step 2: mu, theta0 (and a free speed, dropped again where the fit does not determine it)."""
    cfg, K = run.cfg, len(run.datasets)
    base_names = list(baseline_params or (["mu", "theta0"] + (["speed"] if run.free else [])))
    run.say("fitting the baseline")
    values = dict(held)
    scanned = [f"speed@{i}" if K > 1 else "speed" for i in run.free
               if run.speed_info["measurements"][i]["source"] == "synchronous scan"]
    base = _fit(cfg, run.full_data, base_names, values, 1, run.screen_data, screen_hold=scanned)
    # a speed the data does not determine stays where the synchronous evidence put it (or nominal)
    loose = [n for n, e in base.estimates.items() if base_name(n) == "speed" and
             (e.value is None or e.stderr is None or
              e.stderr > SPEED_DETERMINED * half_band(cfg, run.datasets[measurement_of(n)]))]
    for n in loose:
        m = run.speed_info["measurements"][measurement_of(n)]
        why = ("torque depends on mu omega^2 only" if base.estimates[n].value is None
               else "standard error above a third of the band")
        held_at = {"nominal": "nominal", "speed column": "speed column's mean"}.get(m["source"], "synchronous-scan")
        run.notes.append(f"speed of measurement {measurement_of(n)} not determined by the fit ({why}): held at the "
                         f"{held_at} value {m['value']:.6g} rad/s")
    if loose:
        keep = [b for b in base_names if b != "speed"] if K == 1 or len(loose) == len(run.free) else base_names
        if keep != base_names:
            base = _fit(cfg, run.full_data, keep, values, 1, run.screen_data, screen_hold=scanned)
    names = [n for n in base.estimates if base.estimates[n].identifiable and base.estimates[n].value is not None]
    for n in base.estimates:
        if base_name(n) == "speed" and n in names:
            e = base.estimates[n]
            run.speed_info["measurements"][measurement_of(n)].update(source="fitted in band", value=e.value,
                                                                   stderr=e.stderr)
    values.update({n: base.estimates[n].value for n in names})
    for reason in plausible(cfg, values, run.torque_rms, run.mean_torque):
        run.notes.append(f"baseline: {reason} -- check the config and the data's units")
    return base, State(cfg, run.full_data, names, values)


def _search_step(run, state, current, verdict, effects, screens) -> dict:
    """Step 3-4 once: score and rank every candidate on the screening window, refit the best,
    accept the lowest-BIC plausible one whose LR test passes. Returns ranking and, when one is
    accepted, `accepted` and the whitened baseline `bic0`; a decisive-less rival: `rival_pair`."""
    scr = state.on(run.screen_data)
    detected, examined = detected_ripple_orders(run, current, set(effects), len(candidates(state.cfg, set(effects))))
    scored = []
    for c in candidates(state.cfg, set(effects), detected):
        run.say(f"screening {c.label}")
        scored.append((c, score_test(scr, c)))
    tests = len(scored) + (examined and not detected)  # the detector counts as one candidate
    ranking = rank_candidates(scr, scored, tests)
    screens.append(screen_table(ranking, SCORE_ALPHA / tests, effects, scr))
    note_confounded(scored, SCORE_ALPHA / tests, run.confounded, state.cfg)
    sig = [r for r in ranking if r["significant"]]
    rho = ar1(on_kept(current.residual, current.keep))
    refuted = set()
    while True:  # a contender a measured speed column refutes gives the next ones their chance
        fits = contender_fits(run, scr, state, [r for r in sig if r["cand"].label not in refuted], rho)
        if not fits:
            return {"ranking": ranking}
        accepted = accept(run, fits, state, current, verdict, rho, SCORE_ALPHA / tests)
        now = {f["cand"].label for f in fits if f.get("column_refuted")} - refuted
        if accepted is not None or not now:
            break
        refuted |= now
    if accepted is None:
        return {"ranking": ranking}
    pair = find_rival(run, [f for f in fits if not f.get("column_refuted")], accepted, state, current, rho)
    if pair is not None:
        return {"ranking": ranking, "rival_pair": pair}
    return {"ranking": ranking, "accepted": accepted, "bic0": accepted["bic0"]}


def _add_effect(run, found, state, current, steps, effects, screens):
    """Record the accepted effect as a step; the new state (with a held speed tried again)."""
    accepted = found["accepted"]
    c, s, res, new_state = accepted["cand"], accepted["score"], accepted["res"], accepted["state"]
    # a speed refined with it (stationary_at_its_speed) is the measurement's, not the effect's
    new_names = [n for n in new_state.names if n not in state.names and base_name(n) != "speed"]
    steps.append({"effect": c.effect, "params": effect_params(c, res, new_names, new_state.cfg),
                  "rms_before": current.rms, "rms_after": res.rms, "p_value": s["p_value"],
                  "score": s["lm"], "score_dof": s["dof"], "second_order_score": s["second_order"],
                  "lr_p_value": accepted["lr_p"], "bic_before": found["bic0"], "bic_after": accepted["bic"],
                  "all_params": params_json(res, new_state.names, new_state.cfg)})
    effects.append(c.effect)
    run.added.append(new_names)
    screens[-1]["chosen"] = c.label
    if run.free and not any(base_name(n) == "speed" for n in new_state.names):
        return try_speed(new_state, res, run.full_data, run.screen_data, run.speed_info, run.notes)
    return new_state, res


def _result(run, base, state, current, verdict, steps, effects, ranking, screens, rival_pair, history, wall0):
    """Step 5: the verdict (exactly one of three), notes, the reported mu, the DiagnosisResult."""
    # a last screen for collinearity, whatever the residual: a white residual can hide an effect
    # that a fitted parameter absorbed (an offset inside mu at one speed)
    scr = state.on(run.screen_data)
    scored = [(c, score_test(scr, c, start=False)) for c in candidates(state.cfg, set(effects)) if not c.symmetric]
    note_confounded(scored, SCORE_ALPHA / max(len(scored), 1), run.confounded, state.cfg)
    consistent = verdict.consistent()
    notes = run.notes
    if rival_pair is not None:
        notes.append(f"{rival_pair[0]} and {rival_pair[1]} explain the remaining residual equally well "
                     f"(within {BIC_DECISIVE:g} BIC): neither is named")
    if consistent and verdict.p["family"] < UNEXPLAINED_ALPHA:
        notes.append(f"a systematic residual of {verdict.systematic:.3g} N m remains, below "
                     f"{RELEVANT:g} x the noise sigma ({verdict.sigma:.3g} N m): not claimed as a discrepancy")
    for m, k in zip(verdict.per, kurtosis_off_reversals(run, state, current)):
        m["kurtosis"] = k  # reported as tested: on the samples off the model's reversals
    kurt = verdict.per[0]["kurtosis"]
    # claimed like a systematic residual: significant AND relevant (the tails add at least
    # RELEVANT x the noise sigma in RMS; a lone sample a fit's moved reversal leaves is not)
    if kurt["p_value"] < UNEXPLAINED_ALPHA and kurt["excess_rms"] >= RELEVANT * kurt["mad_sigma"]:
        notes.append(f"heavy-tailed residual (kurtosis test): spikes or non-Gaussian noise add "
                     f"{kurt['excess_rms']:.3g} N m RMS above the noise sigma {kurt['mad_sigma']:.3g} N m")
    notes += confounded_notes(run.confounded, state, run.screen_data, len(run.datasets))
    drifts = drift_findings(run, state)
    notes += [f"{d.text()} (a straight line through {len(d.segments)} segment fits, p {d.p_value:.2g}): the "
              "model's constant value is its mean over the record" for d in drifts]
    if run.budget.get("bound"):
        notes.append(f"time budget of {run.budget['seconds']:g} s reached: not done -- "
                     + "; ".join(run.budget["cut"]) + " (a larger --budget does them)")
    per_vane, mu_mean = vane_cofs(current, state.cfg)
    final_params = params_json(current, state.names, state.cfg)
    if "mu" in final_params and final_params["mu"]["value"] is not None:
        final_params["mu"] = mu_mean
    # never "consistent with noise" while a detector rejects: a remainder below the relevance bar is
    # still said, with its size
    quiet = ("consistent with noise" if verdict.p["family"] >= UNEXPLAINED_ALPHA else
             f"a systematic remainder of {verdict.systematic:.3g} N m below the relevance bar")
    label = (quiet + (" after the named effects" if effects else "")) if consistent else \
        ("named effects and an unexplained remainder" if effects else "nothing named; unexplained")
    if drifts:
        label += "; " + ", ".join(d.text() for d in drifts)
    return DiagnosisResult(
        baseline={"rms": base.rms, "params": params_json(base, list(base.estimates), run.cfg)},
        steps=steps, effects=effects,
        final={"rms": current.rms, "params": final_params, "residual_white": consistent,
               "runs_p_value": verdict.p["runs_test"], "ljung_box_p_value": verdict.p["ljung_box"],
               "synchronous_f_p_value": verdict.p["synchronous_f"],
               "noise_level_p_value": verdict.p["noise_level"], "vane_mu": per_vane,
               "mu_definition": MU_DEFINITION},
        unexplained=not consistent, confounded=run.confounded,
        unexplained_where=[] if consistent else where_unexplained(current, run.datasets, verdict), verdict=label,
        notes=notes, detectors=verdict.to_json(), speed=run.speed_info,
        ranking=[{"effect": r["cand"].label, "score_p_value": r["score"]["p_value"],
                  "one_step_bic": r["bic"], "significant": r["significant"]} for r in ranking],
        screens=screens, rejected=run.rejected, method=METHOD,
        wall_time=_time.perf_counter() - wall0, history=history, drift=[d.to_json() for d in drifts],
        budget=run.budget)


def tty_progress():
    if not sys.stderr.isatty():
        return None
    return lambda msg: print(f"\r\033[Kpumpsim: {msg}", end="", file=sys.stderr, flush=True)
