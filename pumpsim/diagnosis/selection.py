"""Selection: accept a contender, detect a rival within the decisive BIC margin, drop an effect a
later one made unnecessary."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import stats

from ..diagnostics import speed_column_disagreement

from .detectors import Detection, noise_scatter
from .effects import absent_values
from .options import BIC_DECISIVE, LR_ALPHA, NAMED_SIZE, SEARCHED, SPEED_COLUMN_ALPHA, STATIONARY_ALPHA
from .refit import full_fit
from .state import ar1, common_keep, identify, lr_bic, make_problem, on_kept, state_from, sum_squares
from .stationarity import stationary_at_its_speed


def accept(run, fits, state, current, verdict, rho, score_level):
    """The first fit (by screening BIC) that is plausible, refitted on the whole record, changes
    the torque by at least NAMED_SIZE sigma, passes the LR test (prewhitened and plain) and lowers
    BIC, each fit compared with the current one on their common samples (reversal-aware cost);
    None if none does. Implausible fits go to `rejected` with their reasons."""
    for f in fits:
        reasons = run.implausible(f["screen_state"])
        if reasons:
            run.rejected.append({"effect": f["cand"].label, "reasons": reasons})
            run.notes.append(f"{f['cand'].label} rejected: " + "; ".join(reasons))
            continue
        st, res = full_fit(run, f)
        disagreement = _speed_column_disagrees(run, st, res)
        if disagreement:
            f["column_refuted"] = True
            run.rejected.append({"effect": f["cand"].label, "reasons": [disagreement]})
            run.notes.append(f"{f['cand'].label} rejected: {disagreement}")
            continue
        keep = common_keep(current, res)
        q = len(st.names) - len(state.names)
        # the plain LR too: an AR(1) filter fitted to a large unmodelled line amplifies high
        # frequencies, where moved friction reversals can buy a spurious whitened gain
        lr, lr_plain, bic0, bic1 = lr_bic(current, len(state.names), res, len(st.names), rho, keep)
        f.update(state=st, res=res, bic=bic1, bic0=bic0,
                 lr_p=max(float(stats.chi2.sf(lr, max(q, 1))), float(stats.chi2.sf(lr_plain, max(q, 1)))))
        level = LR_ALPHA if f["score"]["p_value"] < score_level else LR_ALPHA / SEARCHED
        # an effect is named only if it changes the model torque by more than a quarter of the
        # noise sigma: a statistically significant but smaller change is noise fitted through moved
        # friction reversals. Its size is the smaller of that change's RMS and the RMS it explains
        # (the drop of the residual's mean square): a change that moves friction reversals across
        # samples is a step's height there but explains little (a 3.9 us lag on an independent
        # no-effect record changed the torque by more than a quarter sigma, 9.6e-5 N m, and explained
        # 5.2e-5). The noise sigma is its whole standard deviation (noise_scatter): coloured noise
        # has a high-frequency level well below it, and a lobe fitted to its slow wander is not a
        # quarter of what the noise does to each sample (F17). It is estimated on the candidate's
        # residual, the noise under the hypothesis being tested (as an F-test takes its variance from
        # the larger model): the current residual still holds the candidate's effect, which inflated
        # the yardstick by the effect's own remainder (grid eccentric5 eccentricity SNR 10: 1.77e-4
        # against the noise's 1.71e-4, a true effect's 4.42e-5 refused); with no effect the two
        # differ by the q fitted parameters' share, O(q/n)
        (rss0, n), (rss1, _) = sum_squares(current.residual, keep), sum_squares(res.residual, keep)
        size = min(float(np.sqrt(np.mean(on_kept(res.fitted - current.fitted, keep) ** 2))),
                   math.sqrt(max(rss0 - rss1, 0.0) / max(n, 1)))
        scatter = noise_scatter(run, res, verdict)
        if size < NAMED_SIZE * scatter:
            run.notes.append(f"{f['cand'].label} not named: it changes (explains) the torque by {size:.3g} N m "
                             f"RMS, below {NAMED_SIZE:g} x the noise's scatter {scatter:.3g} N m")
            continue
        if f["lr_p"] < level and bic1 < bic0 and not run.implausible(st):
            h, st, res = stationary_at_its_speed(run, st, res, [n for n in st.names if n not in state.names],
                                                  verdict.sigma)
            f.update(state=st, res=res)
            if h is not None and h["p_value"] < STATIONARY_ALPHA:
                run.notes.append(f"{f['cand'].label} not named: not stationary -- its parameters fitted on "
                                 f"segments of the record disagree (chi2 {h['statistic']:.3g} on {h['dof']} dof, "
                                 f"p {h['p_value']:.2g} < {STATIONARY_ALPHA:g}): the synchronous shadow of a "
                                 "disturbance that is not shaft-fixed")
                continue
            return f
    return None


def _speed_column_disagrees(run, st, res) -> str | None:
    """Why a fit that moves the shaft speed (a speed ripple) cannot be this measurement's, when a
    measured speed column shows a different ripple (None when they agree, or nothing to compare:
    no column, a column the model follows, several measurements). The speed is evidence, not
    only a mean (diagnostics.speed_column_disagreement)."""
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
    if test is None or test["p_value"] >= SPEED_COLUMN_ALPHA:
        return None
    need, seen = (100 * math.hypot(*test["hypothesis"]), 100 * math.hypot(*test["column"]))
    return (f"the measured speed column disagrees: the fit needs an order-{st.ripple_order} speed ripple of "
            f"{need:.3g} %, the column shows {seen:.3g} % (chi2 {test['statistic']:.3g} on 2 dof, p "
            f"{test['p_value']:.2g} < {SPEED_COLUMN_ALPHA:g}; column noise {test['column_sigma']:.3g} rad/s)")


def find_rival(run, fits, accepted, state, current, rho):
    """Another effect (not another order of the same) within BIC_DECISIVE of the accepted one,
    significant and plausible? Then the pair (returned, else None) goes to `confounded` and
    neither is named. The three fits (current, accepted, rival) are compared on their common
    samples."""
    rival = next((f for f in fits if f is not accepted and "bic" not in f
                  and f["cand"].effect != accepted["cand"].effect  # another order: BIC chose
                  and f["bic_screen"] - accepted["bic_screen"] < BIC_DECISIVE
                  and not run.implausible(f["screen_state"])), None)
    if rival is None:
        return None
    st, res = full_fit(run, rival)
    keep = common_keep(current, accepted["res"], res)
    k0 = len(state.names)
    lr, _, bic0, bic_r = lr_bic(current, k0, res, len(st.names), rho, keep)
    bic_a = lr_bic(current, k0, accepted["res"], len(accepted["state"].names), rho, keep)[3]
    rival.update(bic=bic_r, lr_p=float(stats.chi2.sf(lr, max(len(st.names) - k0, 1))))
    if rival["lr_p"] < LR_ALPHA and bic_r < bic0 and bic_r - bic_a < BIC_DECISIVE:
        pair = [accepted["cand"].effect, rival["cand"].effect]
        if pair not in run.confounded:
            run.confounded.append(pair)
        return pair
    return None


def drop_superseded(run, state, current, steps, effects, history):
    """Backward check after a new effect (forward selection is greedy: an effect named first can
    be one that a later, right effect makes unnecessary -- a speed ripple of order 1 standing in
    for a 1-vane eccentricity). Each earlier-named effect is judged by the acceptance test's own
    criteria given the others: its part of the final model torque (its parameters set absent, the
    rest unchanged) must be at least NAMED_SIZE x the noise sigma, and removing it (the others
    refitted) must fail the prewhitened LR test (p < LR_ALPHA) with a higher BIC. The least
    needed failing one is dropped, with a note, and the check repeats. Assumes, like the
    acceptance test, that the residual's AR(1) coefficient stands for the noise."""
    while len(effects) >= 2:
        sigma = Detection(current, run.datasets, len(state.names)).sigma
        rho = ar1(on_kept(current.residual, current.keep))
        worst = None
        for j in range(len(effects) - 1):
            names_j = [n for n in run.added[j] if n in state.names]
            why = _superseded(run, state, current, names_j, sigma, rho) if names_j else None
            if why is not None and (worst is None or why[0] > worst[0]):
                worst = (*why, j)
        if worst is None:
            break
        _, reason, state, current, j = worst
        gone = effects.pop(j)
        steps.pop(j)
        run.added.pop(j)
        history.pop(j + 1)
        history[-1] = {"label": history[-1]["label"], "result": current}
        run.notes.append(f"{gone} dropped once {effects[-1]} was added: {reason}")
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
    if size < NAMED_SIZE * sigma:
        return 2.0, f"its part of the torque is {size:.3g} N m RMS, below {NAMED_SIZE:g} x the noise sigma", st, res
    lr, _, bic0, bic1 = lr_bic(res, len(st.names), current, len(state.names), rho, common_keep(current, res))
    p = float(stats.chi2.sf(lr, len(names)))
    if p >= LR_ALPHA or bic0 <= bic1:
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
