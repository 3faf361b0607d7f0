"""Selection: accept a contender, detect a rival within the decisive BIC margin, drop an effect a
later one made unnecessary."""
from __future__ import annotations

import dataclasses
import math

from dataclasses import dataclass

import numpy as np

from ..distributions import chi2_sf
from ..signals import speed_column_disagreement

from .detectors import Detection, noise_scatter
from .effects import absent_values
from .log import Dropped, NotStationary, Rejected, TooSmall
from .refit import Contender, completed_contenders, full_fit
from .state import State, ar1, common_keep, identify, lr_bic, make_problem, on_kept, state_from, sum_squares
from .stationarity import stationary_at_its_speed


@dataclass(frozen=True, eq=False)
class Judged:
    """A contender refitted on the whole record and compared with the current model on their
    common samples: its state and fit, the BIC of both (prewhitened) and its LR test's p."""

    contender: Contender
    state: State
    res: object
    bic0: float
    bic1: float
    lr_p: float


@dataclass(frozen=True)
class Acceptance:
    """What the acceptance test made of one step's contenders."""

    accepted: Judged | None
    judged: tuple  # the contenders compared on the whole record (a rival is none of them)
    refuted: frozenset  # the labels a measured speed column refuted


def _judge(run, f: Contender, state, current, rho) -> Judged | Rejected:
    """The contender on the whole record against the current model, or (logged) why a range or a
    measured speed column refuses it."""
    reasons = run.implausible(f.screen_state)
    if reasons:
        run.log.append(Rejected(f.cand.label, tuple(reasons)))
        return run.log[-1]
    st, res = full_fit(run, f)
    disagreement = _speed_column_disagrees(run, st, res)
    if disagreement:
        run.log.append(Rejected(f.cand.label, (disagreement,), by_speed_column=True))
        return run.log[-1]
    q = len(st.names) - len(state.names)
    # the plain LR too: an AR(1) filter fitted to a large unmodelled line amplifies high
    # frequencies, where moved friction reversals can buy a spurious whitened gain
    lr, lr_plain, bic0, bic1 = lr_bic(current, len(state.names), res, len(st.names), rho, common_keep(current, res))
    return Judged(f, st, res, bic0, bic1,
                  max(float(chi2_sf(lr, max(q, 1))), float(chi2_sf(lr_plain, max(q, 1)))))


def _size(current, res) -> float:
    """The torque change a fit makes: the smaller of that change's RMS and the RMS it explains (the
    drop of the residual's mean square), on the samples both keep. A change that moves friction
    reversals across samples is a step's height there but explains little."""
    keep = common_keep(current, res)
    (rss0, n), (rss1, _) = sum_squares(current.residual, keep), sum_squares(res.residual, keep)
    return min(float(np.sqrt(np.mean(on_kept(res.fitted - current.fitted, keep) ** 2))),
               math.sqrt(max(rss0 - rss1, 0.0) / max(n, 1)))


def accept(run, fits, state, current, verdict, rho, score_level) -> Acceptance:
    """The first fit (by screening BIC) that is plausible, refitted on the whole record, changes
    the torque by at least `named_size` x the noise's scatter, passes the LR test (prewhitened and
    plain), lowers BIC and is stationary, each fit compared with the current one on their common
    samples. Implausible fits are logged as rejected with their reasons. The contenders after the
    first are completed (refit.completed_contenders) before any of them is judged."""
    opts, judged, refuted = run.opts, [], set()
    for i in range(len(fits)):
        if i:  # past the first: the rest as the full refits would have ordered them
            completed_contenders(fits, i)
        f = fits[i]
        j = _judge(run, f, state, current, rho)
        if isinstance(j, Rejected):
            if j.by_speed_column:
                refuted.add(f.cand.label)
            continue
        judged.append(f)
        level = opts.lr_alpha if f.score.p_value < score_level else opts.lr_alpha / opts.searched
        # named only if it changes the model torque by more than a quarter of the noise's whole
        # standard deviation (noise_scatter: coloured noise's high-frequency level is well below
        # it), estimated on the candidate's residual -- the noise under the hypothesis tested, as
        # an F-test takes its variance from the larger model
        size, scatter = _size(current, j.res), noise_scatter(run, j.res, verdict)
        if size < opts.named_size * scatter:
            run.log.append(TooSmall(f.cand.label, size, opts.named_size, scatter))
            continue
        if j.lr_p < level and j.bic1 < j.bic0 and not run.implausible(j.state):
            h, st, res = stationary_at_its_speed(run, j.state, j.res,
                                                 [n for n in j.state.names if n not in state.names], verdict.sigma)
            if h is not None and h.p_value < opts.stationary_alpha:
                run.log.append(NotStationary(f.cand.label, h.statistic, h.dof, h.p_value, opts.stationary_alpha))
                continue
            return Acceptance(dataclasses.replace(j, state=st, res=res), tuple(judged), frozenset(refuted))
    return Acceptance(None, tuple(judged), frozenset(refuted))


def _speed_column_disagrees(run, st, res) -> str | None:
    """Why a fit that moves the shaft speed (a speed ripple) cannot be this measurement's, when a
    measured speed column shows a different ripple (None when they agree, or nothing to compare:
    no column, a column the model follows, several measurements). The speed is evidence, not
    only a mean (signals.speed_column_disagreement)."""
    d = run.datasets[0]
    if len(run.datasets) > 1 or d.speed is None or d.speed_trend() is not None or "ripple_cos" not in st.names:
        return None
    v = {**{"theta0": st.cfg.angle, "speed": d.mean_speed(), "delay": 0.0}, **st.values}
    e = [res.estimates[n] for n in ("ripple_cos", "ripple_sin")]
    if any(x.value is None for x in e):
        return None
    theta = v["theta0"] + v["speed"] * (d.time - d.time[0] - v["delay"])
    test = speed_column_disagreement(d.speed, d.time, theta, v["speed"], st.ripple_order, [x.value for x in e],
                                     np.diag([(x.stderr or 0.0) ** 2 for x in e]))
    if test is None or test["p_value"] >= run.opts.speed_column_alpha:
        return None
    need, seen = (100 * math.hypot(*test["hypothesis"]), 100 * math.hypot(*test["column"]))
    return (f"the measured speed column disagrees: the fit needs an order-{st.ripple_order} speed ripple of "
            f"{need:.3g} %, the column shows {seen:.3g} % (chi2 {test['statistic']:.3g} on 2 dof, p "
            f"{test['p_value']:.2g} < {run.opts.speed_column_alpha:g}; column noise {test['column_sigma']:.3g} rad/s)")


def find_rival(run, fits, acceptance: Acceptance, state, current, rho):
    """Another effect (not another order of the same) within `bic_decisive` of the accepted one,
    significant and plausible, among the contenders the acceptance test did not judge? Then the
    pair (returned, else None) goes to `confounded` and neither is named. The three fits
    (current, accepted, rival) are compared on their common samples."""
    accepted, opts = acceptance.accepted, run.opts
    mine = accepted.contender
    rival = next((f for f in fits if f.cand.label not in acceptance.refuted and f is not mine
                  and not any(f is g for g in acceptance.judged)
                  and f.cand.effect != mine.cand.effect  # another order: BIC chose
                  and f.bic_screen - mine.bic_screen < opts.bic_decisive
                  and not run.implausible(f.screen_state)), None)
    if rival is None:
        return None
    st, res = full_fit(run, rival)
    keep = common_keep(current, accepted.res, res)
    k0 = len(state.names)
    lr, _, bic0, bic_r = lr_bic(current, k0, res, len(st.names), rho, keep)
    bic_a = lr_bic(current, k0, accepted.res, len(accepted.state.names), rho, keep).bic1
    lr_p = float(chi2_sf(lr, max(len(st.names) - k0, 1)))
    if lr_p < opts.lr_alpha and bic_r < bic0 and bic_r - bic_a < opts.bic_decisive:
        pair = [mine.cand.effect, rival.cand.effect]
        if pair not in run.confounded:
            run.confounded.append(pair)
        return pair
    return None


def drop_superseded(run, state, current, steps, history):
    """Backward check after a new effect (forward selection is greedy: an effect named first can
    be one that a later, right effect makes unnecessary -- a speed ripple of order 1 standing in
    for a 1-vane eccentricity). Each earlier-named effect is judged by the acceptance test's own
    criteria given the others: its part of the final model torque (its parameters set absent, the
    rest unchanged) must be at least `named_size` x the noise sigma, and removing it (the others
    refitted) must fail the prewhitened LR test (p < `lr_alpha`) with a higher BIC. The least
    needed failing one is dropped, with a note, and the check repeats. Assumes, like the
    acceptance test, that the residual's AR(1) coefficient stands for the noise."""
    while len(steps) >= 2:
        sigma = Detection(current, run.datasets, len(state.names), run.opts).sigma
        rho = ar1(on_kept(current.residual, current.keep))
        worst = None
        for j in range(len(steps) - 1):
            names_j = [n for n in run.added[j] if n in state.names]
            why = _superseded(run, state, current, names_j, sigma, rho) if names_j else None
            if why is not None and (worst is None or why[0] > worst[0]):
                worst = (*why, j)
        if worst is None:
            break
        _, reason, state, current, j = worst
        gone = steps.pop(j).effect.name
        run.added.pop(j)
        history.pop(j + 1)
        history[-1] = dataclasses.replace(history[-1], result=current)
        run.log.append(Dropped(gone, steps[-1].effect.name, reason))
    return state, current


def _superseded(run, state, current, names, sigma, rho):
    """(rank, reason, reduced state, its fit) if the effect with fitted `names` is no longer
    needed (see drop_superseded), else None."""
    absent = absent_values(run, names)
    prob = make_problem(state.cfg, run.full_data, state.names, initial=state.values,
                        extra={k: v for k, v in state.values.items() if k not in state.names},
                        ripple_order=state.ripple_order)
    x = prob.x0.copy()
    for n in names:
        x[state.names.index(n)] = absent[n]
    size = float(np.sqrt(np.mean(on_kept(prob.model(prob.x0) - prob.model(x), current.keep) ** 2)))
    st, res = _without(run, state, names, absent)
    if size < run.opts.named_size * sigma:
        return (2.0, f"its part of the torque is {size:.3g} N m RMS, below {run.opts.named_size:g} x the noise sigma",
                st, res)
    lr, _, bic0, bic1 = lr_bic(res, len(st.names), current, len(state.names), rho, common_keep(current, res))
    p = float(chi2_sf(lr, len(names)))
    if p >= run.opts.lr_alpha or bic0 <= bic1:
        return p, f"without it the likelihood ratio p is {p:.2g} (or BIC no higher)", st, res
    return None


def _without(run, state, names, absent):
    """The state refitted on the whole record with `names` at their `absent` values."""
    cfg = dataclasses.replace(state.cfg, values={**state.cfg.values,
                                                 **{k: v for k, v in absent.items() if k in state.cfg.values}})
    keep = [n for n in state.names if n not in names]
    values = {**state.values, **absent}
    held = {k: v for k, v in values.items() if k not in keep}
    res = identify(cfg, run.full_data, keep, initial={n: values[n] for n in keep}, multistart=False,
                   ripple_order=state.ripple_order, extra=held)
    return state_from(cfg, run.full_data, keep, values, res, state.ripple_order), res
