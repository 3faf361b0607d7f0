"""The candidate screen: every candidate of the library scored at the current fit (prewhitened
score test, second-order terms and finite probes where the first order is blind) and ranked by
the BIC of its one-step nonlinear fit."""
from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..distributions import chi2_sf
from ..signals import order_lines

from .effects import EFFECTS, Candidate, Effect, clearance, effect_of, owner_of
from .options import OPTIONS, DiagnosisOptions
from .state import State, ar1, bic, common_keep, on_kept, prewhiten, split_rows, sum_squares


def detected_ripple_orders(run, current, added: set, fixed: int) -> tuple:
    """The speed-ripple orders above the library's that the current residual singles out (per
    measurement, Bonferroni over them) and whether any order was examined. The detector's family
    level is one candidate's share of the screen's, run.opts.score_alpha / (fixed + 1), and the screen counts
    it as one more candidate: a false opening and the fixed candidates' false alarms together stay
    within run.opts.score_alpha (union bound)."""
    ripple = next(e for e in EFFECTS if e.ripple)
    if ripple.name in added or current.angle is None:
        return [], False
    library = set(ripple.orders(run.cfg))
    orders = [k for k in range(1, run.opts.ripple_order_max + 1) if k not in library]
    rows = np.cumsum([0] + [d.n for d in run.datasets])
    alpha = run.opts.score_alpha / (fixed + 1) / len(run.datasets)
    found, examined = set(), False
    for r, a in zip(split_rows(current.residual, rows), split_rows(current.angle, rows)):
        lines = order_lines(r, a, orders, alpha)
        examined |= bool(lines["examined"])
        found.update(lines["orders"])
    return sorted(found), examined


def _second_order_columns(prob, x0, nb, J0e, h, Jb, one_sided=False):
    """If the candidate's first-order sensitivities vanish, or lie entirely inside the span of the
    fitted parameters' (a short sensor lag is, to first order, a pure delay: theta0 absorbs it),
    the columns of the quadratic model d tau = 1/2 sum_ij H_ij e_i e_j in the unknowns
    (e_i e_j, i <= j), H from exact Jacobians at probe points; else None."""
    q = J0e.shape[1]
    cols = range(nb, nb + q)
    Q = np.linalg.qr(Jb)[0] if nb else np.zeros((J0e.shape[0], 0))
    proj = lambda A: A - Q @ (Q.T @ A)  # noqa: E731
    H = []
    for i in range(q):
        step = np.zeros_like(x0)
        step[nb + i] = h
        Jp = prob.model_and_jacobian(x0 + step, cols)[1]
        if i == 0 and np.linalg.norm(proj(J0e)) > 1e-6 * np.linalg.norm(proj(Jp - J0e)):
            return None  # a genuine first-order effect
        Jm = J0e if one_sided else prob.model_and_jacobian(x0 - step, cols)[1]
        H.append((Jp - Jm) / (h if one_sided else 2 * h))  # column j: d2 tau / de_i de_j
    cols, pairs = [], []
    for i in range(q):
        for j in range(i, q):
            cols.append(0.5 * H[i][:, i] if i == j else 0.5 * (H[i][:, j] + H[j][:, i]))
            pairs.append((i, j))
    return np.column_stack(cols), pairs


def _probe_window(state, cand, prob, Jb, opts: DiagnosisOptions = OPTIONS):
    """The candidate's problem and the fitted parameters' Jacobian on the first opts.probe_samples
    samples (one measurement): the probes only choose a start, which is then judged on the whole
    screening window; ~120 model runs per candidate would otherwise cost ~120 x the window."""
    d = state.data
    if isinstance(d, (list, tuple)) or d.n <= opts.probe_samples:
        return prob, Jb
    pw = cand.problem(state.on(d.window(0, opts.probe_samples)))
    return pw, Jb[:opts.probe_samples]


def _probe_grid(prob, Jb, nb, h, directions=16, radii=(0.5, 1, 2, 4, 8, 16), one_sided=False):
    """The model at finite defect sizes r (cos b, sin b), b in [0, 2 pi), with the fitted
    parameters' linear correction: the best point, refined by a pattern search in (ln r, b) with
    halving steps. Where the torque reacts to a defect through the instants of
    friction reversals (a non-analytic, sampling-dependent change), this finds what no Taylor term
    and no Gauss-Newton step can. The cost: the mean square over the samples that neither the
    current model's nor the probe's reversal-aware mask drops. A one-parameter effect is probed
    along its line (r, or +-r unless one-sided) and searched in ln r only."""
    keep0 = prob.keep_at(prob.x0)
    line = prob.x0.size - nb == 1
    if line:
        directions = 1 if one_sided else 2

    def at(rr, b):
        x = prob.x0.copy()
        x[nb:] = (rr * math.cos(b),) if line else (rr * math.cos(b), rr * math.sin(b))
        r, cost, keep = _cost(prob, x, keep0)
        if not np.isfinite(cost):
            return x, r, np.inf
        if line:  # the fitted parameters profiled on the model: a lag of a sample or more moves theta0
            x, (r, cost, _) = _profiled(prob, Jb, nb, x, (r, cost, keep), keep0)  # by more than one linear step
            return x, r, cost
        if nb:
            d = np.linalg.lstsq(on_kept(Jb, keep), on_kept(r, keep), rcond=None)[0]
            x[:nb] += d
            r = r - Jb @ d
        return x, r, float(np.mean(on_kept(r, keep) ** 2))

    best, where = (None, None, np.inf), None
    for rr in radii:
        for b in np.arange(directions) * 2 * math.pi / directions:
            trial = at(rr * h, b)
            if trial[2] < best[2]:
                best, where = trial, (rr * h, b)
    if where is None:
        return prob.x0.copy()
    f, db = math.sqrt(2), math.pi / directions
    for _ in range(12):  # pattern search: move to a better neighbour, else halve the steps
        moved = False
        turns = () if line else ((where[0], where[1] + db), (where[0], where[1] - db))
        for rr, b in ((where[0] * f, where[1]), (where[0] / f, where[1])) + turns:
            trial = at(rr, b)
            if trial[2] < best[2]:
                best, where, moved = trial, (rr, b), True
                break
        if not moved:
            f, db = math.sqrt(f), db / 2
    return np.clip(best[0], prob.lower, prob.upper)


def _rank_one_start(coef, pairs, q):
    """e with e e' closest to the fitted quadratic coefficients (c_ii = e_i^2, c_ij = e_i e_j);
    the overall sign stays open (the defect and its mirror give the same torque)."""
    P = np.zeros((q, q))
    for c, (i, j) in zip(coef, pairs):
        P[i, j] = P[j, i] = c if i == j else 0.5 * c
    w, V = np.linalg.eigh(P)
    e = math.sqrt(abs(w[-1])) * V[:, -1]
    return e if e[int(np.argmax(np.abs(e)))] >= 0 else -e


def _independent_subsets(Me, opts: DiagnosisOptions = OPTIONS) -> list:
    """Column subsets of the projected candidate columns Me that span what they all span, the
    pivoted QR's choice first. Parameters the data cannot tell apart to first order (on an ellipse,
    vanes i and i + N/2 see the same housing; after mu is projected out, every vane of a 4-vane
    ellipse has one direction) leave several such subsets: which one the pivot keeps is decided by
    rounding, and the subsets are not equivalent fits once the model is nonlinear (a vane 30 %
    rougher is not its opposite vane 35 % smoother with mu raised)."""
    q = Me.shape[1]
    if q < 2:
        return [list(range(q))]
    norms = np.linalg.norm(Me, axis=0)
    A = Me / np.where(norms > 0, norms, 1.0)
    _, R, piv = scipy.linalg.qr(A, mode="economic", pivoting=True)
    rank = int(np.sum(np.abs(np.diag(R)) > 1e-8))
    first = sorted(piv[:rank])
    if rank == q:
        return [first]
    full = np.linalg.svd(A[:, first], compute_uv=False)[-1]
    out = [first]
    for subset in itertools.combinations(range(q), rank):
        if list(subset) != first and len(out) < opts.tied_subsets and \
                np.linalg.svd(A[:, subset], compute_uv=False)[-1] > 0.5 * full:
            out.append(list(subset))
    return out


@dataclass(frozen=True)
class Score:
    """A candidate's score test at the current fit and, when asked for, its one-step fit."""

    lm: float  # Lagrange-multiplier statistic (prewhitened, projected off the fitted directions)
    dof: int
    p_value: float
    params: tuple  # the candidate's parameters the test moved (a tied subset, or all)
    second_order: bool  # by the second-order terms (the first order vanishes by symmetry)
    partner: str | None  # the fitted parameter a nearly collinear candidate could hide in
    searched: bool = False  # its one-step fit is the best of a probe search
    start: dict | None = None  # the one-step fit's values: the refit's start
    one_step_rss: float | None = None  # RSS of the one-step fit on the samples both keep
    base_rss: float | None = None  # RSS of the current model on the same samples
    n: int = 0  # their number
    base: tuple | None = None  # (RSS, n) of the current model on its own samples
    tied: tuple = ()  # the Scores of the other subsets the data cannot tell apart (refitted too)


@dataclass(frozen=True)
class _Linear:
    """The candidate's problem linearised at the current fit, prewhitened and projected."""

    prob: object
    keep0: object  # the current model's samples (the candidate at its absent values)
    rows: object
    J1: np.ndarray  # the candidate's first-order columns on those samples
    rs: np.ndarray  # the current residual
    Je: np.ndarray  # the candidate's columns (second-order ones where the first order is blind)
    pairs: list | None  # (i, j) of each second-order column
    r_w: np.ndarray
    Jb_w: np.ndarray
    Je_w: np.ndarray
    Q: np.ndarray  # orthonormal basis of the fitted directions
    Me: np.ndarray  # the candidate's columns projected off them
    Mr: np.ndarray  # the residual projected off them


def _linearised(state: State, cand: Candidate) -> _Linear:
    prob = cand.problem(state)
    nb = len(state.names)
    m, Je = prob.model_and_jacobian(prob.x0, range(nb, len(prob.names)))  # the candidate's columns
    keep0 = prob.keep_at(prob.x0)
    rows = slice(None) if keep0 is None else keep0
    J1, rs, Jb, eff = Je[rows], prob.y - m, state.jacobian(), cand.kind
    quad = (_second_order_columns(prob, prob.x0, nb, Je, eff.probe_step(state, prob), Jb, one_sided=eff.one_sided)
            if eff.probe_step is not None else None)
    pairs = None
    if quad is not None:
        Je, pairs = quad
    rho = ar1(rs[rows])
    r_w, Jb_w, Je_w = prewhiten(rs[rows], rho), prewhiten(Jb[rows], rho), prewhiten(Je[rows], rho)
    # project out the fitted directions
    Q, _ = np.linalg.qr(Jb_w) if Jb_w.shape[1] else (np.zeros((r_w.size, 0)), None)
    return _Linear(prob, keep0, rows, J1, rs, Je, pairs, r_w, Jb_w, Je_w, Q,
                   Je_w - Q @ (Q.T @ Je_w), r_w - Q @ (Q.T @ r_w))


def _partner(state: State, lin: _Linear, Je_w, opts: DiagnosisOptions) -> str | None:
    """The fitted parameter most collinear with a candidate direction nearly inside the fitted span."""
    cos = [float(np.linalg.norm(lin.Q.T @ Je_w[:, j]) / max(np.linalg.norm(Je_w[:, j]), 1e-300))
           for j in range(Je_w.shape[1])]
    Jb_w = lin.Jb_w
    if not (Jb_w.shape[1] and max(cos) > opts.collinear):
        return None
    j = int(np.argmax(cos))
    c = [abs(np.dot(Jb_w[:, i], Je_w[:, j])) / (np.linalg.norm(Jb_w[:, i]) * np.linalg.norm(Je_w[:, j]) + 1e-300)
         for i in range(Jb_w.shape[1])]
    return state.names[int(np.argmax(c))]


def score_test(state: State, cand: Candidate, start=True, opts: DiagnosisOptions = OPTIONS, lin=None) -> Score:
    """LM statistic for adding `cand` at the current fit (prewhitened GLS score test): the
    statistic, p-value, the collinearity with the fitted parameters and (start=True) a start for
    the refit with the nonlinear residual there. `start` may be a column subset of the
    candidate's parameters (one of several the data cannot tell apart): the start is then made
    with only those moved. `lin`: the candidate's linearisation at this state when the caller has
    it (the tied subsets share one)."""
    lin = _linearised(state, cand) if lin is None else lin
    quad = lin.pairs is not None
    subsets = _independent_subsets(lin.Me, opts) if not quad else [list(range(lin.Me.shape[1]))]
    if len(subsets) > 1 and start is True:  # tied: the subset whose one-step fit is best, not the pivot's
        tried = [score_test(state, cand, start=subset, opts=opts, lin=lin) for subset in subsets]
        best = min(tried, key=lambda o: o.one_step_rss / max(o.n, 1))
        return dataclasses.replace(best, tied=tuple(o for o in tried if o is not best))  # refitted too
    keep = list(start) if isinstance(start, list) else subsets[0]
    params = tuple(cand.params) if quad else tuple(cand.params[i] for i in keep)
    Je_w, Me = lin.Je_w, lin.Me
    if len(keep) < Me.shape[1]:
        Je_w, Me = Je_w[:, keep], Me[:, keep]
    partner = _partner(state, lin, Je_w, opts)
    Mr = lin.Mr
    sigma2 = float(Mr @ Mr) / max(lin.r_w.size - lin.Jb_w.shape[1], 1)
    scale = np.linalg.norm(Me, axis=0)
    scale[scale == 0] = 1.0
    coef, _, rank, _ = np.linalg.lstsq(Me / scale, Mr, rcond=1e-10)
    lm = float((Mr @ (Me / scale)) @ coef) / max(sigma2, 1e-300)
    q = max(int(rank), 1)
    score = Score(lm, q, float(chi2_sf(lm, q)), params, quad, partner)
    if start is False:
        return score
    return _with_one_step(state, cand, lin, score, coef / scale, Je_w, opts)


def _with_one_step(state, cand, lin: _Linear, score: Score, coef, Je_w, opts) -> Score:
    """The joint one-step estimate (fitted parameters move too) and the nonlinear model there: a
    cheap look past the linearisation, used to choose which candidates to refit."""
    prob, nb, rs, keep0 = lin.prob, len(state.names), lin.rs, lin.keep0
    step = _rank_one_start(coef, lin.pairs, len(cand.params)) if score.second_order else coef
    x1 = prob.x0.copy()
    x1[[nb + cand.params.index(n) for n in score.params]] += step
    if nb:
        x1[:nb] += np.linalg.lstsq(lin.Jb_w, lin.r_w - Je_w @ coef, rcond=None)[0]
    x1 = np.clip(x1, prob.lower, prob.upper)
    if cand.symmetric:  # a step beyond the quadratic model's reach: back inside a tenth of the clearance
        x1[nb:] = _capped(x1[nb:], 0.5 * clearance(state.cfg))
    c1 = _cost(prob, x1, keep0)
    if not np.isfinite(c1[1]):
        c1 = (rs, float(np.mean(rs[lin.rows] ** 2)), keep0)
        x1 = prob.x0.copy()
    Jb = state.jacobian()
    x1, c1 = _profiled(prob, Jb, nb, x1, c1, keep0, opts)
    # its one-step fit is then the best of many: judged at the searched level
    searched = bool(cand.kind.finite_probes and (score.second_order or len(cand.params) == 1
                                                 or _direction_blind(lin.J1, opts)))
    if searched:
        x1, c1 = _probed(state, cand, prob, Jb, nb, x1, c1, keep0, opts)
    common = common_keep(keep0, c1[2])  # the one-step and the current model on one sample set
    (rss1, n1), (rss0, _) = sum_squares(c1[0], common), sum_squares(rs, common)
    return dataclasses.replace(score, searched=searched, one_step_rss=rss1, base_rss=rss0, n=n1,
                               start={n: v for n, v in zip(prob.names, x1) if n in state.names + list(score.params)},
                               base=sum_squares(rs, keep0))


def _capped(e, cap):
    norm = np.linalg.norm(e)
    return e * cap / norm if norm > cap else e


def _cost(prob, x, keep0):
    """(residual, mean square over the samples kept both by keep0 and by the model at x, that
    common mask) -- the mean, not the sum: points of a search differ in their masks by a few
    samples."""
    r = prob.y - prob.model(x)
    if not np.all(np.isfinite(r)):
        return r, np.inf, keep0
    keep = common_keep(keep0, prob.keep_at(x))
    return r, float(np.mean(on_kept(r, keep) ** 2)), keep


def _profiled(prob, Jb, nb, x1, c1, keep0, opts: DiagnosisOptions = OPTIONS):
    """The one-step fit profiled over the fitted parameters: with the candidate's parameters at
    their one-step values, Gauss-Newton steps of the fitted ones on the NONLINEAR residual there
    (Jacobian Jb of the current fit). The joint linear step cannot see what the candidate does to
    first order inside the fitted span when its score used second-order columns: a low-pass's
    delay part is a theta0 shift the baseline already made, so the candidate at its size needs
    theta0 moved back; without this its one-step fit is worse than none and the candidate is
    never refitted. Keeps the better of before and after (the step is on the model). c1: the
    (residual, cost, mask) of _cost at x1; on the reversal-aware cost with the current model's
    mask keep0."""
    if not nb:
        return x1, c1
    best = (x1, c1)
    for _ in range(opts.profile_steps):
        x = best[0].copy()
        k = common_keep(keep0, best[1][2])
        x[:nb] += np.linalg.lstsq(on_kept(Jb, k), on_kept(best[1][0], k), rcond=None)[0]
        x = np.clip(x, prob.lower, prob.upper)
        c = _cost(prob, x, keep0)
        if not c[1] < best[1][1]:
            break
        best = (x, c)
    return best


def _probed(state, cand, prob, Jb, nb, x1, c1, keep0, opts: DiagnosisOptions = OPTIONS):
    """The better of the one-step fit (x1, r1) and the finite probes' best. For a non-smooth
    effect (the torque reacts through friction-reversal instants) where the first order is blind,
    in all directions (second-order score) or in one (a defect on a rig symmetric about an axis:
    the y shift of a centred 1-vane ellipse, where the linear step moves the other direction only)."""
    xp = _probe_grid(*_probe_window(state, cand, prob, Jb, opts), nb, cand.kind.probe_step(state, prob),
                     one_sided=cand.kind.one_sided)
    cp = _cost(prob, xp, keep0)
    return (xp, cp) if cp[1] < c1[1] else (x1, c1)


def _direction_blind(J, opts: DiagnosisOptions = OPTIONS) -> bool:
    """Whether the first-order sensitivity of a defect with several directions vanishes in one of
    them (a column's norm below opts.blind_direction of the largest, or all zero)."""
    norms = np.linalg.norm(J, axis=0)
    return J.shape[1] > 1 and float(norms.min()) <= opts.blind_direction * float(norms.max())


@dataclass(frozen=True, eq=False)
class Ranked:
    """A candidate of one screen with its score, the BIC of its one-step fit and whether it is
    significant (score p, or one-step likelihood ratio where it was searched, below the level)."""

    cand: Candidate
    score: Score
    bic: float
    significant: bool


def rank_candidates(state, scored, tests=None, opts: DiagnosisOptions = OPTIONS) -> list[Ranked]:
    """All candidates by one criterion: the BIC of their one-step nonlinear fit (score step, or
    second-order/probe start where the first order is blind). Significant: score p or one-step
    likelihood ratio below alpha / (number of tests: the candidates, by default)."""
    k0 = len(state.names)
    alpha = opts.score_alpha / max(tests or len(scored), 1)
    out = []
    for c, s in scored:
        q = len(s.params)
        # each one-step fit against the current model on the samples both keep (reversal-aware
        # cost); the candidates compared by that BIC difference, added to the current model's BIC
        # on its own samples (the intersection of ~30 candidates' masks would keep few samples)
        n, rss0 = s.n, s.base_rss
        rss1 = min(s.one_step_rss, rss0)
        lr = n * math.log(max(rss0, 1e-300) / max(rss1, 1e-300))
        lr_p = float(chi2_sf(lr, max(q, 1)))
        sig = s.p_value < alpha or ((s.second_order or s.searched) and lr_p < alpha / opts.searched)
        rss_b, n_b = s.base
        out.append(Ranked(c, s, bic(rss_b, n_b, k0) - lr + q * math.log(n), bool(sig)))
    out.sort(key=lambda r_: r_.bic)
    return out


@dataclass(frozen=True)
class ScreenRow:
    """One candidate of a screen as the report shows it."""

    candidate: str  # its label: effect(k=order)
    effect: Effect
    order: int | None
    p_value: float
    score: float
    dof: int
    significant: bool
    one_step_bic: float
    one_step_rms: float | None
    collinear_with: str | None

    def to_json(self) -> dict:
        return {"candidate": self.candidate, "effect": self.effect.name, "order": self.order,
                "p_value": self.p_value, "score": self.score, "dof": self.dof, "significant": self.significant,
                "one_step_bic": self.one_step_bic, "one_step_rms": self.one_step_rms,
                "collinear_with": self.collinear_with}


@dataclass(frozen=True)
class Screen:
    """One search step's screen: after which model, at which level, every candidate by score
    p-value, and the one chosen (None: nothing accepted)."""

    after: str
    alpha: float
    candidates: tuple
    chosen: str | None = None

    def to_json(self) -> dict:
        return {"after": self.after, "alpha": self.alpha, "candidates": [r.to_json() for r in self.candidates],
                "chosen": self.chosen}


def screen_table(ranking, alpha, effects) -> Screen:
    """One screen's candidates for the report, by score p-value: what was tested, how strongly."""
    rows = [ScreenRow(r.cand.label, r.cand.kind, r.cand.order, r.score.p_value, r.score.lm, r.score.dof,
                      r.significant, r.bic,
                      math.sqrt(r.score.one_step_rss / r.score.n) if r.score.one_step_rss is not None else None,
                      r.score.partner) for r in ranking]
    rows.sort(key=lambda r: (r.p_value, -r.score))
    return Screen(effects[-1] if effects else "baseline", alpha, tuple(rows))


def note_confounded(scored, alpha, confounded, cfg, hidden=None):
    """A candidate nearly collinear with a fitted parameter whose own (projected) score is not
    significant could hide inside that parameter: report the pair -- among the confounded when
    the parameter is a named effect's, in `hidden` (when given) when it is a baseline parameter
    (mu, theta0, ...): that is what one record cannot tell, not two effects it cannot tell apart."""
    for c, s in scored:
        if s.partner is not None and s.p_value >= alpha:
            owner = owner_of(s.partner, cfg)
            into = hidden if hidden is not None and effect_of(s.partner, cfg) is None else confounded
            pair = [c.effect, owner]
            if pair not in into:
                into.append(pair)
