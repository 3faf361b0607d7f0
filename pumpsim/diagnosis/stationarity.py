"""Stationarity of an accepted effect: its parameters fitted on segments of the record must agree."""
from __future__ import annotations

import math

from dataclasses import dataclass, field

import numpy as np

from ..distributions import chi2_sf
from ..identification import base_name
from ..signals import noise_sigma
from ..identification.problem import SPEED_COLUMN_Z

from .log import SpeedRefined
from .options import OPTIONS, DiagnosisOptions
from .refit import try_speed
from .state import full_mask, split_rows


@dataclass(frozen=True)
class Homogeneity:
    """Do per-segment estimates agree? A chi-square statistic on `dof` degrees of freedom."""

    statistic: float
    dof: int
    p_value: float
    estimates: list  # per usable segment, the estimates (in J's units)
    stderrs: list = field(default_factory=list)  # per usable segment, their standard errors (J's units)
    labels: list = field(default_factory=list)  # the usable segments' labels


def homogeneity(J, r, segments, sigma, nuisance=None) -> Homogeneity:
    """Chi-square test that the least-squares estimates of b in r ~ J b (+ N c, the nuisance
    columns N refitted in each segment and profiled out), one per segment label in `segments`,
    agree (white noise of standard deviation sigma). Segments whose columns are not of full rank
    are left out."""
    q = J.shape[1]
    A = J if nuisance is None else np.column_stack([J, nuisance])
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    A = A / scale
    est, info, used = [], [], []
    for s in np.unique(segments):
        m = segments == s
        F = A[m].T @ A[m]
        if np.linalg.matrix_rank(F, tol=1e-10 * max(np.trace(F), 1e-300)) < A.shape[1]:
            continue
        Finv = np.linalg.inv(F)
        est.append((Finv @ (A[m].T @ r[m]))[:q])
        info.append(np.linalg.inv(Finv[:q, :q]) / sigma ** 2)  # the profiled (Schur) information
        used.append(s)
    if len(est) < 2:
        return Homogeneity(0.0, 0, 1.0, [])
    W = sum(info)
    pooled = np.linalg.solve(W, sum(I @ b for I, b in zip(info, est)))
    stat = float(sum((b - pooled) @ I @ (b - pooled) for I, b in zip(info, est)))
    dof = (len(est) - 1) * q
    se = [np.sqrt(np.diag(np.linalg.inv(I))) / scale[:q] for I in info]
    return Homogeneity(stat, dof, float(chi2_sf(stat, dof)), [(b / scale[:q]).tolist() for b in est],
                       [e.tolist() for e in se], [s.item() for s in used])


def revolution_segments(angle, rows, opts: DiagnosisOptions = OPTIONS):
    """Per sample, its segment: each measurement cut into up to opts.stationary_segments runs of whole
    revolutions (None when no measurement has 2 x opts.stationary_min_revs revolutions)."""
    labels, usable = [], False
    for a in split_rows(angle, rows):
        rev = np.floor((a - a[0]) / (2 * math.pi)) if a.size else a
        revs = int(rev[-1]) + 1 if a.size else 0
        S = min(opts.stationary_segments, revs // opts.stationary_min_revs)
        usable |= S >= 2
        per = max(revs // max(S, 1), 1)
        labels.append(np.minimum(rev // per, max(S - 1, 0)))
    return np.concatenate(labels) if usable else None


def _stationary(run, st, res, new_names, sigma) -> Homogeneity | None:
    """The homogeneity test of the effect's parameters `new_names` over segments of the record;
    None when the record is too short to cut."""
    rows = np.cumsum([0] + [d.n for d in run.datasets])
    seg = None if res.angle is None else revolution_segments(np.asarray(res.angle, float), rows, run.opts)
    if seg is None or not new_names:
        return None
    # the base parameters and a held speed are refitted per segment: a speed error (held where the
    # record alone does not determine it) turns a stationary effect's phase over the record
    K = len(run.datasets)
    speeds = [f"speed@{i}" if K > 1 else "speed" for i in run.free]
    # the samples next to the model's reversals left out (keep_at with the noise sigma)
    prob = st.problem(extra_names=speeds, reversals=sigma)
    names = st.names + [n for n in speeds if n not in st.names]
    Jall = prob.model_and_jacobian(prob.x0)[1]
    cols = [names.index(n) for n in new_names if n in names]
    J, N = Jall[:, cols], Jall[:, [i for i in range(len(names)) if i not in cols]]
    keep = full_mask(prob.keep_at(prob.x0), res.residual.size)
    # the noise level from the median absolute first difference (robust to a pulse train, whose
    # few large samples inflate the detectors' high-frequency estimate), never above theirs
    robust = noise_sigma(res.residual[keep]) if keep.sum() > 1 else sigma
    args = (J[keep], res.residual[keep], seg[keep], min(sigma, robust) if robust > 0 else sigma)
    if np.sqrt(np.mean(args[1] ** 2)) < run.opts.stationary_gate * args[3]:
        return None  # no large remainder: the effect explains the record (see stationary_gate)
    h = homogeneity(*args, N[keep])
    # base columns collinear with the effect's within a segment: the base held at the record's fit
    return h if h.dof or not N.size else homogeneity(*args)


def stationary_at_its_speed(run, st, res, new_names, sigma):
    """(homogeneity test, state, fit) of an effect; if it fails while a speed column's mean is
    held, again with the speed refined in the column's band (try_speed): a held speed a little off
    turns a large effect's phase over the record, and its segments disagree although the effect is
    stationary (independent eccentric5 record, 0.3 % noisy speed column: its mean 1.6e-5 low left a
    true 0.57 % ripple at chi2 2580 on 6 dof; at the fitted speed the ripple leaves the noise). The
    refined speed is kept only if it makes the effect stationary."""
    h = _stationary(run, st, res, new_names, sigma)
    column = any(run.datasets[i].speed is not None for i in run.free)  # a column's speed in its band
    # a held speed (a column's mean, or the nominal where the baseline torque did not determine it:
    # a concentric rig's torque has no shaft orders until the effect gives it some) is refined
    if (h is None or h.p_value >= run.opts.stationary_alpha or not run.free
            or any(base_name(n) == "speed" for n in st.names)):
        return h, st, res
    info, notes = {"measurements": [dict(m) for m in run.speed_info["measurements"]]}, []
    st2, res2 = try_speed(st, res, run.full_data, run.screen_data, info, notes, run.opts)
    if st2 is st:
        return h, st, res
    h2 = _stationary(run, st2, res2, new_names, sigma)  # None: no remainder left to test
    if h2 is not None and h2.p_value < run.opts.stationary_alpha:
        return h, st, res
    run.speed_info["measurements"] = info["measurements"]
    band = (f"the speed column's band (its mean +- {SPEED_COLUMN_Z:g} standard errors)" if column else
            f"its tolerance band (+- {100 * run.cfg.speed_tolerance:g} %)")
    run.log.append(SpeedRefined(band))
    return h2, st2, res2
