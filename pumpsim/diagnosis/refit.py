"""Refits of the screen's contenders: from the score step, tied subsets and polar starts."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..identification import SMOOTH_COLUMNS, base_name, half_band
from ..identification.optimiser import MAX_ITER

from .effects import Candidate
from .log import SpeedRefined
from .options import OPTIONS, DiagnosisOptions
from .screen import Score
from .state import (Fitted, State, bic, common_keep, identify, lr_bic, measurement_of, past_stall, refit_on,
                    state_from, sum_squares, whitened_rss)


@dataclass(frozen=True, eq=False)
class Contender:
    """A significant candidate refitted on the screening window, with the BIC of that fit on the
    window (against the current model on their common samples, on the current model's scale).
    `complete`: for a fit cut short because it trailed the contenders before it by more than
    completing it could gain (a polar search left at its best scout), what returns the contender as
    the full refit would have made it; None when it is complete."""

    cand: Candidate
    score: Score
    screen_state: State
    screen_res: object
    bic_screen: float = math.nan
    complete: Callable[[], "Contender"] | None = None


def contender_fits(run, scr, state, sig, rho) -> list[Contender]:
    """The contenders among the significant candidates `sig` -- the best by the one-step BIC,
    the best by score p-value (a smooth effect whose one-step fit a probe grid happened to beat),
    the lowest significant orders and every other significant out-of-round order -- refitted on
    the screen, sorted by their BIC there. A contender that trails those before it beyond what
    completing its fit can gain is left incomplete (Contender.complete; completed_contenders).
    The other orders are refitted because a lobing's one-step fit ranks it poorly (an order-6
    lobing on the eccentric 5-vane rig: 15.3 sigma left by its one-step fit, 13.9 by order 4's,
    which was named with a speed ripple for the rest); on a record longer than the probe window
    each is first scouted there and left incomplete if that trails."""
    best = sig[:run.opts.contenders]
    contenders = best + [r for r in sorted(sig, key=lambda r_: r_.score.p_value)[:2]
                         if not any(r is b_ for b_ in best)]
    lowest = lowest_orders(sig)
    contenders += [r for r in lowest if not any(r is c_ for c_ in contenders)]
    orders = [r for r in sig if r.cand.kind.harmonic_pair and not any(r is c_ for c_ in contenders)]
    contenders += orders

    def polar(r):  # the lowest order of an out-of-round, an eccentricity
        return any(r is r_ for r_ in lowest) or (r.cand.symmetric and not r.cand.kind.harmonic_pair)
    screen_bic = _screen_bic(scr, state, rho)

    def contender(c, s, is_polar, needed, behind=None, scout_first=False):
        st, res, settled = refit(scr, c, s, polar=is_polar, opts=run.opts, needed=needed, behind=behind,
                                 scout_first=scout_first)
        full = lambda: contender(c, s, is_polar, needed)  # noqa: E731  (every start, to the bit)
        if not settled:
            return Contender(c, s, st, res, screen_bic(st, res), full)
        if not c.symmetric:  # (whether or not it trails: rephasing can gain a quarter of the RMS)
            st, res = rephased(st, res)
        return Contender(c, s, st, res, screen_bic(st, res))

    out = []
    # the polar searches last: their starts are all scouted only where the fit could still matter
    for r in sorted(contenders, key=polar):
        c, s = r.cand, r.score
        if out and run.out_of_time(f"the refit of {c.label}"):
            continue
        run.say(f"refitting with {c.label}")
        bar = min((f.bic_screen for f in out), default=math.inf) + _search_margin(scr, run.opts)
        lead = min(out, key=lambda f: f.bic_screen, default=None)
        out.append(contender(  # nothing to trail yet: every start, rephased
            c, s, polar(r), None if math.isinf(bar) else lambda st_, res_, bar=bar: screen_bic(st_, res_) < bar,
            None if lead is None else lambda r_, allow=1.0, lead=lead: _trails(r_, lead.screen_res, run.opts, allow),
            any(r is o for o in orders)))
    out.sort(key=lambda f: f.bic_screen)
    return out


def completed_contenders(fits: list, done: int) -> None:
    """Complete, in place, the contenders after the first `done` (already judged) that were left
    incomplete, and sort those again by their BIC on the screen: the order the full refits would
    have given them. An incomplete one trails the first by more than completing it can gain, so
    while the first stands nothing needs completing."""
    if any(f.complete is not None for f in fits[done:]):
        rest = [f.complete() if f.complete is not None else f for f in fits[done:]]
        fits[done:] = sorted(rest, key=lambda f: f.bic_screen)


def _trails(scout, lead, opts: DiagnosisOptions = OPTIONS, allowance: float = 1.0) -> bool:
    """Whether a polar search's best scout (a few steps on the probe window, the screen's first
    samples) trails the best contender so far, on the samples both keep there, by more than
    finishing it and completing its search could gain (opts.refit_gain in RMS each) -- and
    `allowance` in RMS on top: it is then left unfinished, as a search whose finalists' fit trails
    is not completed."""
    n = scout.residual.size
    if lead.residual.size < n:
        return False
    lead_keep = None if lead.keep is None else lead.keep[:n]
    keep = common_keep(scout.keep, lead_keep)
    (rss, m), (rss_lead, _) = sum_squares(scout.residual, keep), sum_squares(lead.residual[:n], keep)
    return m > 0 and rss > allowance ** 2 * (1 + opts.refit_gain) ** 4 * rss_lead


def _screen_bic(scr, state, rho):
    """(state, fit) -> the fit's BIC on the screen against the current model, on their common
    samples, on the current model's scale (Contender.bic_screen)."""
    base = screen_base(scr)
    base_bic = bic(*whitened_rss(base.residual, rho, base.keep), len(state.names))

    def screen_bic(st, res):
        _, _, bic0, bic1 = lr_bic(base, len(state.names), res, len(st.names), rho, common_keep(base, res))
        return base_bic + bic1 - bic0
    return screen_bic


def _search_margin(scr, opts: DiagnosisOptions = OPTIONS) -> float:
    """How far behind the best contender so far a polar search's finalists-only fit may be and
    still be completed: the decisive margin (a rival) plus what completing the search can gain,
    opts.refit_gain in RMS (n ln(1 + g)^2 in BIC on the screen's n samples)."""
    n = sum(d.n for d in scr.data) if isinstance(scr.data, (list, tuple)) else scr.data.n
    return opts.bic_decisive + 2 * n * math.log1p(opts.refit_gain)


def rephased(st: State, res):
    """A smooth contender's fit (no polar starts: its one-step start is good in its own parameters)
    also fitted from the phase-and-speed scan start (identification/start.py) at its values, the
    better kept. Its cost is a staircase in theta0 and speed (each friction reversal falls on one
    side of a sample or the other), and a Gauss-Newton fit from the one-step start stays on the
    step it starts on: the grid's tilted3 torque offset at SNR 10 was refitted to 1.028 sigma, its
    own optimum is 1.020, and the viscous rival, at 1.023, was named instead. Two non-nested
    contenders are compared only at their optima."""
    if not any(base_name(n) in ("theta0", "speed") for n in st.names):
        return st, res
    again = refit_on(st, st.data, multistart=True)
    return again if again[1].rms < res.rms else (st, res)


def lowest_orders(sig) -> list:
    """Per housing-shape effect (a harmonic pair per order), its lowest significant order: a
    machined or clamped housing's out-of-round is dominated by its lowest orders (ovality k = 2,
    then trilobing), while the one-step fits that rank the orders cannot be trusted for a defect
    that acts through the friction reversals (a 15 um oval's one-step fit left 5.4 sigma,
    its refit 1.0) -- so it is refitted whatever its one-step rank."""
    out = {}
    for r in sig:
        c = r.cand
        if c.kind.harmonic_pair and (c.effect not in out or c.order < out[c.effect].cand.order):
            out[c.effect] = r
    return list(out.values())


def screen_base(scr) -> Fitted:
    """The current model on the screening window (no refit)."""
    prob = scr.problem()
    m = prob.model(prob.x0)
    return Fitted(prob.y - m, m, prob.keep_at(prob.x0))


def full_fit(run, f):
    """A contender's state and fit on the whole record (refitted from its screening fit)."""
    if run.screen_data is run.full_data:
        return f.screen_state, f.screen_res
    return refit_on(f.screen_state, run.full_data)


def refit(state: State, cand: Candidate, score: Score, polar=False, opts: DiagnosisOptions = OPTIONS, needed=None,
          behind=None, scout_first=False):
    """_refit_from the score step and from each tied subset's (score_test), the lowest RMS kept:
    the subsets' one-step fits rank them only to first order (independent 4-vane ellipse, one vane
    25 % smoother with the baseline's phase a vane pitch off, so that vane is not vane 3 but vane 2:
    the best one-step subset, vane 3's factor, refitted to 1.266 at 1.05 sigma -- vane 2's to 0.749
    at the noise -- and a 0.0045 % speed ripple was named for the difference). `needed`: see
    _refit_from."""
    fits = [_refit_from(state, cand, s, polar, opts, needed, behind, scout_first) for s in (score, *score.tied)]
    return min(fits, key=lambda f: f[1].rms)  # (state, fit, settled)


def _refit_from(state: State, cand: Candidate, score, polar=False, opts: DiagnosisOptions = OPTIONS, needed=None,
                behind=None, scout_first=False):
    """Fit the current names plus the candidate's parameters, starting from the score step (on the
    state's data). A geometric defect (eccentricity, out-of-round) is fitted with the interval
    Jacobian columns (identification/problem.py: they carry the friction reversals' motion), and
    with `polar` also from opts.refit_starts directions about its absent value at the one-step
    estimate's radius (at least opts.refit_radius) and at half of it, a few steps each, the lowest cost fitted to
    convergence: the cost is a staircase in its parameters whose valley a fit from the
    one-step start often misses (the grid's 15 um oval on the 4-vane ellipse: 1.61 sigma from the
    one-step start, 1.02 from a polar start, the truth's valley 1.017; an eccentricity's one-step
    estimate can be the mirror image of the truth). `needed(state, res)`: whether a fit could still
    matter to the selection (_scouted); without it every start is scouted in full. `behind(scout)`:
    whether the best scout on the probe window trails so far that it is not fitted to convergence
    (its result then takes one step on the state's data); with `scout_first` a one-start refit is
    scouted so too before its fit: (state, fit, whether fitted to convergence)."""
    cfg = cand.config(state.cfg)
    values = dict(state.values)
    values.update(score.start or {})  # the joint one-step estimate
    for name, least in cand.kind.start_floor:
        values[name] = max(values.get(name, 0.0), least)
    ripple = cand.ripple_order if cand.ripple_order is not None else state.ripple_order
    names = state.names + list(score.params)
    held = {k: v for k, v in values.items() if k not in names}
    starts = [{n: values[n] for n in names if n in values}]
    if polar and len(score.params) == 2:
        starts += _polar_starts(state, cand, score.params, values, opts)
    fit = lambda init, data=state.data, interval=True, **kw: identify(  # noqa: E731
        cfg, data, names, initial=init, multistart=False, ripple_order=ripple, extra=held,
        interval=interval if cand.symmetric else False, **kw)
    settled = True
    scout = _scout_window(state.data, opts)

    def finish(r, settle=True):
        if scout is not state.data or not _stopped_at_minimum(r):
            at = {n: r.estimates[n].value for n in names if r.estimates[n].value is not None}
            return _past_stall(fit, at, fit(at)) if settle else fit(at, max_iter=1, polish=False, final_jacobian=False)
        return r
    if len(starts) == 1:
        first = (_scout_unless_far_behind(lambda **kw: fit(starts[0], scout, **kw), behind, opts)
                 if scout_first and behind is not None and scout is not state.data else None)
        if first is not None and behind(first):
            res, settled = finish(first, settle=False), False
        else:
            res = _past_stall(fit, starts[0], fit(starts[0]))
    else:  # a few steps from the starts (on the probe window), then the best one to convergence
        res, settled = _scouted(starts, lambda init, **kw: fit(init, scout, **kw), finish, opts,
                       None if needed is None else lambda r: needed(state_from(cfg, state.data, names, values, r,
                                                                               ripple), r),
                       None if behind is None or scout is state.data else behind)
    return state_from(cfg, state.data, names, values, res, ripple), res, settled


def _scout_unless_far_behind(scout_fit, behind, opts: DiagnosisOptions = OPTIONS):
    """A one-start contender's scout on the probe window -- or, where its quick look (one step on
    the smooth interval columns, ~0.2x a scout's cost) trails the best contender so far by more
    than the scout could gain over it (opts.quick_look_gain in RMS) on top of behind's margin, that
    quick look: it is left incomplete either way (Contender.complete), and where the selection
    reaches it, completed as before (docs/explanation/discrepancy-workflow.md, Cost)."""
    quick = scout_fit(max_iter=opts.refit_quick_steps, polish=False, final_jacobian=False, interval=SMOOTH_COLUMNS)
    if behind(quick, opts.quick_look_gain):
        return quick
    return scout_fit(max_iter=opts.refit_scout_steps)


def _stopped_at_minimum(res) -> bool:
    """A scout a stop rule ended at its minimum -- not its iteration limit, even where the step
    left is below the optimiser's standard-error bar (converged for a fit's flag): a scout's few
    steps often end there, and finishing it can still reach another step of the staircase (on
    the reduced grid, keeping such a scout named a concentric4 oval an eccentricity)."""
    return res.converged and not res.message.startswith(MAX_ITER)


def _past_stall(fit, init, res):
    """A refit stalled on a step fitted again from where its slope points (state.past_stall): a
    contender stuck on a step would understate what its effect explains."""
    return past_stall(fit, init, res)[0]


def _scouted(starts, scout_fit, finish, opts: DiagnosisOptions = OPTIONS, needed=None, behind=None):
    """The best of opts.refit_scout_steps Gauss-Newton steps (and a polish) from each start, fitted
    to convergence by `finish`. With `needed`, first only from the finalists (_finalists); the
    other starts are scouted too when `needed` says that fit could still win or tie the selection,
    and the result is then the one all starts give, to the bit (the first best start by cost).
    With `behind`, finalists whose best scout trails (behind(scout) true) are not finished:
    finish(scout, settle=False). Returns (fit, whether it was finished)."""
    chosen = range(len(starts)) if needed is None else _finalists(starts, scout_fit, opts)
    scouts = {i: scout_fit(starts[i], max_iter=opts.refit_scout_steps) for i in chosen}
    win = min(sorted(scouts), key=lambda i: scouts[i].rms)
    if needed is not None and behind is not None and behind(scouts[win]):
        return finish(scouts[win], settle=False), False
    res = _with_one_step_start(finish(scouts[win]), win, scouts, starts, scout_fit, finish, opts)
    if len(scouts) < len(starts) and needed(res):
        scouts.update({i: scout_fit(starts[i], max_iter=opts.refit_scout_steps)
                       for i in range(len(starts)) if i not in scouts})
        best = min(sorted(scouts), key=lambda i: scouts[i].rms)
        res = res if best == win else _with_one_step_start(finish(scouts[best]), best, scouts, starts, scout_fit,
                                                           finish, opts)
    return res, True


def _with_one_step_start(res, win, scouts, starts, scout_fit, finish, opts: DiagnosisOptions = OPTIONS):
    """The best scout's fit, or the one-step start's (starts[0], the score test's joint estimate)
    fitted to convergence where its scout was still descending at its iteration limit and that
    fit is lower. Ranking scouts by a few steps favours starts already in a shallow valley: on an
    eccentric 5-vane circle with a 10 um oval, the best scouts sat converged at 1.45e-4 N m, the
    one-step start's scout at 2.95e-4 went on to 1.17e-4 (the truth's valley 1.14e-4), and an
    order-4 lobing was named instead."""
    if win == 0:
        return res
    if 0 not in scouts:  # (scouted once: the search's later scouting of every start takes it as it is)
        scouts[0] = scout_fit(starts[0], max_iter=opts.refit_scout_steps)
    first = scouts[0]
    if _stopped_at_minimum(first):
        return res
    alt = finish(first)
    return alt if alt.rms < res.rms else res


def _finalists(starts, scout_fit, opts: DiagnosisOptions = OPTIONS) -> list:
    """The opts.refit_finalists starts (in their order) whose opts.refit_quick_steps steps on the
    scout window reach the lowest cost: only they are scouted in full (opts.refit_scout_steps steps
    and a polish each). A quick look steps on the interval columns' smooth formula on every sample
    (SMOOTH_COLUMNS: no sub-sample runs, ~0.2x the cost). Scouting all 17 starts in full was half
    of a 5,000-sample diagnosis; on 11 geometric refits of the reduced grid the winner of all 17 was
    among the three best quick looks in 8, the three reached a cost 1e-6 lower in one, and 2.0 and
    4.5 % higher RMS in two, both named effects: hence `needed`
    (docs/explanation/discrepancy-workflow.md, which also has what the smooth quick looks changed)."""
    if len(starts) <= opts.refit_finalists:
        return list(range(len(starts)))
    quick = [scout_fit(init, max_iter=opts.refit_quick_steps, polish=False, final_jacobian=False,
                       interval=SMOOTH_COLUMNS).rms for init in starts]
    return sorted(int(i) for i in np.argsort(quick, kind="stable")[:opts.refit_finalists])


def _scout_window(data, opts: DiagnosisOptions = OPTIONS):
    """The first opts.probe_samples samples of one measurement (the polar starts only choose a start; the
    probe search's window, long enough to place the reversals), else the data itself. A shorter
    window (1000 samples, of the reduced grid's 1001) chose starts that lost 2 of its 87 named
    cases (concentric4 oval SNR 5, ellipse4 eccentricity SNR 5)."""
    if isinstance(data, (list, tuple)) or data.n <= opts.probe_samples:
        return data
    return data.window(0, opts.probe_samples)


def _polar_starts(state, cand, params, values, opts: DiagnosisOptions = OPTIONS) -> list:
    """opts.refit_starts directions x opts.refit_radii starts of a two-parameter geometric defect about its
    absent value (a harmonic pair's zero, the configured centre), the fitted names at the current fit."""
    v = state.cfg.values
    centre = np.array([0.0 if cand.kind.harmonic_pair else v[n] for n in params])
    radius = max(opts.refit_radius * max(v["housing.a"], v["housing.b"]),
                 float(np.hypot(*(np.array([values.get(n, 0.0) for n in params]) - centre))))
    return [{**{n: state.values[n] for n in state.names},
             **dict(zip(params, centre + f * radius * np.array([math.cos(b), math.sin(b)])))}
            for b in np.arange(opts.refit_starts) * 2 * math.pi / opts.refit_starts for f in opts.refit_radii]


def try_speed(state, current, full_data, screen_data, speed_info, notes, opts: DiagnosisOptions = OPTIONS):
    """After an effect has made the torque depend on the angle, refine a held speed in its band if
    the data now determines it (and BIC agrees)."""
    names = state.names + ["speed"]
    held = {k: v for k, v in state.values.items() if k not in names}
    init = {n: state.values[n] for n in state.names}
    init["speed"] = state.values.get("speed", state.cfg.speed)
    res = identify(state.cfg, full_data, names, initial=init, multistart=False,
                   ripple_order=state.ripple_order, extra=held)
    datasets = full_data if isinstance(full_data, (list, tuple)) else [full_data]
    sp = [(e, half_band(state.cfg, datasets[measurement_of(n)])) for n, e in res.estimates.items()
          if base_name(n) == "speed"]
    keep = common_keep(current, res)
    (rss1, n), (rss0, _) = sum_squares(res.residual, keep), sum_squares(current.residual, keep)
    if (all(e.value is not None and e.stderr is not None and e.stderr <= opts.speed_determined * half for e, half in sp)
            and bic(rss1, n, len(res.estimates)) < bic(rss0, n, len(state.names))):
        for nm, e in res.estimates.items():
            if base_name(nm) == "speed":
                speed_info["measurements"][measurement_of(nm)].update(source="fitted in band", value=e.value,
                                                                    stderr=e.stderr)
        notes.append(SpeedRefined())
        return state_from(state.cfg, full_data, list(res.estimates), state.values, res, state.ripple_order), res
    return state, current
