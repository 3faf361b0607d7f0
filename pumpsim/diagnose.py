"""Discrepancy workflow: find where model and measurement disagree, name the missing physical
effect, add it, refit, show the gap shrink -- and say "unexplained" rather than guess.

1. Baseline fit (identification: mu, theta0, and speed when the data has no speed column).
2. Residual tests (runs, Ljung-Box, order spectrum, angle-domain average).
3. Every candidate effect of the library is ranked by a score (Lagrange-multiplier) test computed
   from the model's sensitivities at the current fit -- no refit needed to rank. Serially
   correlated residuals make nominal p-values too small, so the test is done on prewhitened
   quantities: an AR(1) filter estimated on the current residual is applied to the residual and to
   every Jacobian column (a GLS score test). Where the pump's symmetry cancels a defect's
   first-order effect (an eccentric housing, odd out-of-round orders with an even vane count), the
   test uses the second-order terms (exact Jacobians at +-probe points).
4. Candidates whose score p-value beats 0.01 / (number tested) (Bonferroni) are significant; the
   two best by p-value and the two whose joint one-step estimate gives the lowest nonlinear
   residual are refitted, and the lowest BIC wins. It is
   kept when its likelihood-ratio test (prewhitened, p < 0.01) passes and BIC falls. When a second
   effect comes within 10 BIC units of it, the two are reported `confounded` and neither is picked.
   Repeat until the residual is white or nothing significant is left.
5. Candidates nearly collinear with a fitted parameter (cosine > 0.995) whose projected score is
   not significant could hide inside that parameter: reported in `confounded`. A residual that
   stays non-white (runs or Ljung-Box p < 0.005 each, 1 % family-wise) with no significant
   candidate is `unexplained`, with its spectral peaks.

Physics worth knowing: with N identical, equally spaced vanes, housing-fixed defects only appear at
multiples of N shaft orders; other orders point to vane-to-vane differences or drive/sensor effects.
"""
from __future__ import annotations

import dataclasses
import math
import sys
import time as _time
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy import stats

from .config import PumpConfig
from .data import Dataset
from .diagnostics import order_spectrum, residual_report
from .identify import identify, make_problem
from .presentation import OPTIMISTIC, PLUS_MINUS, parameter_text, step_parameters

SCORE_ALPHA = 0.01
LR_ALPHA = 0.01
COLLINEAR = 0.995
MAX_EFFECTS = 4
UNEXPLAINED_ALPHA = 0.01  # family-wise level of the two whiteness tests behind `unexplained`
CONTENDERS = 2  # refitted per step: the best by score p-value and the best by one-step residual
BIC_DECISIVE = 10.0  # a BIC lead below this does not decide between two effects (Kass & Raftery)


@dataclass
class Candidate:
    effect: str
    params: list  # parameter names for Problem
    order: int | None = None  # shaft order (out-of-round, speed ripple)
    # geometric defects of a pump with identical, equally spaced vanes can leave the torque
    # unchanged to first order (an eccentric housing with N >= 2: the per-vane changes at odd orders
    # cancel in the sum); their score test then uses the second-order terms
    symmetric: bool = False

    @property
    def label(self):
        return f"{self.effect}(k={self.order})" if self.order else self.effect

    def config(self, cfg: PumpConfig) -> PumpConfig:
        return _with_harmonic_pair(cfg, self.order) if self.effect == "housing_out_of_round" else cfg


def candidates(cfg: PumpConfig, added: set) -> list:
    N = cfg.vanes
    out = []
    if "rotor_eccentricity" not in added:
        out.append(Candidate("rotor_eccentricity", ["housing.center.0", "housing.center.1"], symmetric=True))
    if "housing_out_of_round" not in added:
        j = len(cfg.harmonics)
        out += [Candidate("housing_out_of_round", [f"housing.harmonics.{j}.amplitude",
                                                   f"housing.harmonics.{j + 1}.amplitude"], k, symmetric=True)
                for k in range(2, 9)]
    if "speed_ripple" not in added:
        out += [Candidate("speed_ripple", ["ripple_cos", "ripple_sin"], k) for k in range(1, 2 * N + 1)]
    for name, params in (("torque_offset", ["torque_offset"]), ("sensor_lag", ["lag"]),
                         ("viscous_tip_friction", ["effects.viscous_tip_friction"])):
        if name not in added:
            out.append(Candidate(name, params))
    if N >= 2 and "vane_friction_spread" not in added:
        out.append(Candidate("vane_friction_spread", [f"effects.vane_friction_factor.{i}" for i in range(1, N)]))
    return out


def _with_harmonic_pair(cfg: PumpConfig, k: int) -> PumpConfig:
    """The config with two more housing-harmonic slots of order k, phases 0 and pi/(2k), zero
    amplitudes a and b: a cos(k phi) + b sin(k phi) = A cos(k (phi - gamma)) is linear in (a, b),
    so the fit needs no phase wrapping and the absent defect (a = b = 0) is a regular point."""
    return cfg.with_harmonics(cfg.harmonics + [[k, 0.0, 0.0], [k, 0.0, math.pi / (2 * k)]])


def _ar1(r):
    """Lag-1 autocorrelation of r, the AR(1) coefficient of the prewhitening filter."""
    rc = r - r.mean()
    rho = float(np.dot(rc[1:], rc[:-1]) / max(np.dot(rc, rc), 1e-300))
    return min(max(rho, -0.99), 0.99)


def _prewhiten(v, rho):
    """z_k = v_k - rho v_(k-1) (rows of a matrix, or a vector)."""
    return v[1:] - rho * v[:-1]


class State:
    """The current model: config (with added effects' values), fitted names and values."""

    def __init__(self, cfg, data, names, values, ripple_order=1):
        self.cfg, self.data = cfg, data
        self.names, self.values = list(names), dict(values)
        self.ripple_order = ripple_order
        self._jacobian = None

    def jacobian(self):
        """The fitted parameters' Jacobian at the current fit, shared by every candidate's score
        test (a candidate at its absent value leaves the model and these columns unchanged)."""
        if self._jacobian is None:
            prob = self.problem()
            self._jacobian = prob.model_and_jacobian(prob.x0)[1]
        return self._jacobian

    def problem(self, extra_names=(), cfg=None, ripple_order=None):
        names = self.names + [n for n in extra_names if n not in self.names]
        return make_problem(cfg or self.cfg, self.data, names, initial=self.values,
                       extra={k: v for k, v in self.values.items() if k not in names},
                       ripple_order=ripple_order or self.ripple_order)


def _probe_scale(state: State) -> float:
    """Probe step for geometric defects: 1e-3 of the housing size (tens of micrometres)."""
    v = state.cfg.values
    return 1e-3 * max(v.get("housing.a", 0.0), v.get("housing.b", 0.0), 1e-3)


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


def _probe_grid(prob, nb, Jb, h, directions=8, radii=(0.5, 1, 2, 4, 8, 16)):
    """The model at finite defect sizes r (cos b, sin b), b in [0, pi) (the mirror defect gives the
    same torque), with the fitted parameters' linear correction: the best point and its residual.
    Where the torque reacts to a defect only through the instants of friction reversals (a
    non-analytic, sampling-dependent change), this finds what no Taylor term can."""
    best = (None, None, np.inf)
    for rr in radii:
        for b in np.arange(directions) * math.pi / directions:
            x = prob.x0.copy()
            x[nb:nb + 2] = rr * h * math.cos(b), rr * h * math.sin(b)
            r = prob.y - prob.model(x)
            if nb:
                d = np.linalg.lstsq(Jb, r, rcond=None)[0]
                x[:nb] += d
                r = r - Jb @ d
            if r @ r < best[2]:
                best = (x, r, float(r @ r))
    x = np.clip(best[0], prob.lower, prob.upper)
    return x, prob.y - prob.model(x)


def _rank_one_start(coef, pairs, q):
    """e with e e' closest to the fitted quadratic coefficients (c_ii = e_i^2, c_ij = e_i e_j);
    the overall sign stays open (the defect and its mirror give the same torque)."""
    P = np.zeros((q, q))
    for c, (i, j) in zip(coef, pairs):
        P[i, j] = P[j, i] = c if i == j else 0.5 * c
    w, V = np.linalg.eigh(P)
    e = math.sqrt(abs(w[-1])) * V[:, -1]
    return e if e[int(np.argmax(np.abs(e)))] >= 0 else -e


def score_test(state: State, cand: Candidate, start=True):
    """LM statistic for adding `cand` at the current fit (prewhitened GLS score test). Returns the
    statistic, p-value, the collinearity with the fitted parameters and (start=True) a start for
    the refit with the nonlinear residual there."""
    prob = state.problem(cand.params, cfg=cand.config(state.cfg),
                         ripple_order=cand.order if cand.effect == "speed_ripple" else None)
    nb = len(state.names)
    m, Je = prob.model_and_jacobian(prob.x0, range(nb, len(prob.names)))  # the candidate's columns
    rs = prob.y - m
    Jb = state.jacobian()
    if cand.effect == "sensor_lag":  # one-sided (T >= 0), probe a twentieth of a radian of lag
        quad = _second_order_columns(prob, prob.x0, nb, Je, 0.05 / prob.speed_of(prob.x0), Jb, one_sided=True)
    elif cand.symmetric:
        quad = _second_order_columns(prob, prob.x0, nb, Je, _probe_scale(state), Jb)
    else:
        quad = None
    if quad is not None:
        Je, pairs = quad
    rho = _ar1(rs)
    r_w, Jb_w, Je_w = _prewhiten(rs, rho), _prewhiten(Jb, rho), _prewhiten(Je, rho)
    # project out the fitted directions
    Q, _ = np.linalg.qr(Jb_w) if Jb_w.shape[1] else (np.zeros((r_w.size, 0)), None)
    proj = lambda A: A - Q @ (Q.T @ A)  # noqa: E731
    Me, Mr = proj(Je_w), proj(r_w)
    params = list(cand.params)
    if quad is None and Me.shape[1] > 1:
        # parameters the data cannot tell apart (with an ellipse, vanes i and i + N/2 see the same
        # housing): keep an independent subset, the others stay at their configured values
        norms = np.linalg.norm(Me, axis=0)
        _, R, piv = scipy.linalg.qr(Me / np.where(norms > 0, norms, 1.0), mode="economic", pivoting=True)
        keep = sorted(piv[:int(np.sum(np.abs(np.diag(R)) > 1e-8))])
        if len(keep) < Me.shape[1]:
            params = [params[i] for i in keep]
            Je, Je_w, Me = Je[:, keep], Je_w[:, keep], Me[:, keep]
    # collinearity of each candidate direction with the fitted ones
    cos = [float(np.linalg.norm(Q.T @ Je_w[:, j]) / max(np.linalg.norm(Je_w[:, j]), 1e-300))
           for j in range(Je_w.shape[1])]
    partner = None
    if Jb_w.shape[1] and max(cos) > COLLINEAR:
        j = int(np.argmax(cos))
        c = [abs(np.dot(Jb_w[:, i], Je_w[:, j])) / (np.linalg.norm(Jb_w[:, i]) * np.linalg.norm(Je_w[:, j]) + 1e-300)
             for i in range(Jb_w.shape[1])]
        partner = state.names[int(np.argmax(c))]
    dof = max(r_w.size - Jb_w.shape[1], 1)
    sigma2 = float(Mr @ Mr) / dof
    scale = np.linalg.norm(Me, axis=0)
    scale[scale == 0] = 1.0
    coef, _, rank, _ = np.linalg.lstsq(Me / scale, Mr, rcond=1e-10)
    lm = float((Mr @ (Me / scale)) @ coef) / max(sigma2, 1e-300)
    coef = coef / scale
    q = max(int(rank), 1)
    out = {"lm": lm, "dof": q, "p_value": float(stats.chi2.sf(lm, q)), "params": params,
           "second_order": quad is not None, "partner": partner}
    if not start:
        return out
    # the joint one-step estimate (fitted parameters move too) and the nonlinear model there: a
    # cheap look past the linearisation, used to choose which candidates to refit
    step = _rank_one_start(coef, pairs, len(cand.params)) if quad is not None else coef
    x1 = prob.x0.copy()
    x1[[nb + cand.params.index(n) for n in params]] += step
    if nb:
        x1[:nb] += np.linalg.lstsq(Jb_w, r_w - Je_w @ coef, rcond=None)[0]
    x1 = np.clip(x1, prob.lower, prob.upper)
    r1 = prob.y - prob.model(x1)
    if quad is not None and len(cand.params) == 2:  # seen only beyond first order: try finite probes
        xp, rp = _probe_grid(prob, nb, Jb, _probe_scale(state))
        if rp @ rp < r1 @ r1:
            x1, r1 = xp, rp
    out.update(start={n: v for n, v in zip(prob.names, x1) if n in state.names + params},
               one_step_rss=float(r1 @ r1))
    return out


def _bic(rss, n, k):
    return n * math.log(max(rss, 1e-300) / n) + k * math.log(n)


def _whitened_rss(r, rho):
    rw = _prewhiten(r, rho)
    return float(rw @ rw), rw.size


def _params_json(res, names):
    out = {}
    for n in names:
        e = res.estimates.get(n)
        if e is not None:
            out[n] = {"value": e.value, "stderr": e.stderr}
    return out


def _polar(res, names, k):
    """(a, b) -> amplitude and phase of a cos(k x) + b sin(k x) = A cos(k x - k gamma) with
    standard errors by the delta method: the physical description of an out-of-round or ripple."""
    ea, eb = res.estimates[names[0]], res.estimates[names[1]]
    a, b = ea.value, eb.value
    A = math.hypot(a, b)
    ids = [n for n in res.estimates if res.estimates[n].identifiable]
    C = np.eye(2)
    if res.correlation is not None and all(n in ids for n in names):
        i, j = ids.index(names[0]), ids.index(names[1])
        C = res.correlation[np.ix_([i, j], [i, j])]
    S = np.outer([ea.stderr, eb.stderr], [ea.stderr, eb.stderr]) * C
    gA = np.array([a, b]) / max(A, 1e-300)
    gP = np.array([-b, a]) / max(A * A, 1e-300)
    return ({"value": A, "stderr": float(math.sqrt(max(gA @ S @ gA, 0.0)))},
            {"value": math.atan2(b, a), "stderr": float(math.sqrt(max(gP @ S @ gP, 0.0)))})


def _effect_params(cand, res, new_names):
    """The step's parameters as an engineer reads them."""
    out = _params_json(res, new_names)
    if cand.order:
        out["order"] = cand.order
    if cand.effect == "housing_out_of_round":  # A cos(k (phi - gamma))
        A, ph = _polar(res, new_names, cand.order)
        out["amplitude"], out["phase"] = A, {"value": ph["value"] / cand.order, "stderr": ph["stderr"] / cand.order}
    if cand.effect == "speed_ripple":  # omega = omega0 (1 + A cos(k theta + phase))
        out["amplitude"], out["phase"] = _polar(res, new_names, cand.order)
    return out


def diagnose(cfg: PumpConfig, data: Dataset, max_effects: int = MAX_EFFECTS, progress=None,
             baseline_params=None) -> dict:
    wall0 = _time.perf_counter()
    say = progress or (lambda msg: None)
    datasets = list(data) if isinstance(data, (list, tuple)) else [data]
    speeds_known = all(d.speed is not None for d in datasets)
    base_names = baseline_params or (["mu", "theta0"] + ([] if speeds_known else ["speed"]))
    say("fitting the baseline")
    base = identify(cfg, datasets, base_names)
    base_names = list(base.estimates)  # per-measurement names (theta0@i) when several are fitted
    names = [n for n in base_names if base.estimates[n].identifiable]
    values = {n: base.estimates[n].value for n in names}
    state = State(cfg, datasets, names, values)
    current = base
    history = [{"label": "baseline", "result": base}]
    steps, effects, confounded = [], [], []
    screens = []  # every candidate's score test at each step, for the report's ranking table
    screened_for = None  # the state whose candidates were last screened (their collinearity is known)
    explained_by_confounded = False
    for _ in range(max_effects):
        if current.diagnostics["white_at_5pct"]:
            break
        cands = candidates(state.cfg, set(effects))
        screened_for = state
        scored = []
        for c in cands:
            say(f"screening {c.label}")
            scored.append((c, score_test(state, c)))
        alpha = SCORE_ALPHA / len(scored)
        _note_confounded(scored, alpha, confounded)
        screens.append(_ranking(scored, alpha, effects, current.residual.size))
        by_p = sorted([cs for cs in scored if cs[1]["p_value"] < alpha],
                      key=lambda cs: (cs[1]["p_value"], -cs[1]["lm"]))
        if not by_p:
            break
        # ranking needs no refit; choosing among the best few does: the best by p-value and the
        # best by the nonlinear residual at their one-step estimates are refitted, BIC decides
        by_rss = sorted(by_p, key=lambda cs: cs[1]["one_step_rss"])
        contenders = []
        for c, s in by_p[:CONTENDERS] + by_rss[:CONTENDERS]:
            if all(c is not c2 for c2, _ in contenders):
                contenders.append((c, s))
        rho = _ar1(current.residual)
        rss0, nw = _whitened_rss(current.residual, rho)
        bic0 = _bic(rss0, nw, len(state.names))
        fits = []
        for c, s in contenders:
            say(f"refitting with {c.label}")
            new_state, res = _refit(state, c, s)
            rss1, _ = _whitened_rss(res.residual, rho)
            q = len(new_state.names) - len(state.names)
            lr = nw * math.log(max(rss0, 1e-300) / max(rss1, 1e-300))
            fits.append({"cand": c, "score": s, "state": new_state, "res": res, "rss": rss1,
                         "lr_p": float(stats.chi2.sf(lr, max(q, 1))), "bic": _bic(rss1, nw, len(new_state.names))})
        fits.sort(key=lambda f: f["bic"])
        best = fits[0]
        _note_refits(screens[-1], fits, bic0)
        if best["lr_p"] >= LR_ALPHA or best["bic"] >= bic0:
            break
        rival = next((f for f in fits[1:] if f["lr_p"] < LR_ALPHA and f["bic"] < bic0
                      and f["bic"] - best["bic"] < BIC_DECISIVE), None)
        if rival is not None:  # two effects explain the residual equally well: do not pick one
            pair = [best["cand"].effect, rival["cand"].effect]
            if pair not in confounded:
                confounded.append(pair)
            explained_by_confounded = True
            break
        c, s, res, new_state = best["cand"], best["score"], best["res"], best["state"]
        new_names = [n for n in new_state.names if n not in state.names]
        steps.append({"effect": c.effect, "params": _effect_params(c, res, new_names),
                      "rms_before": current.rms, "rms_after": res.rms, "p_value": s["p_value"],
                      "score": s["lm"], "score_dof": s["dof"], "second_order_score": s["second_order"],
                      "lr_p_value": best["lr_p"], "bic_before": bic0, "bic_after": best["bic"],
                      "all_params": _params_json(res, new_state.names)})
        effects.append(c.effect)
        screens[-1]["chosen"] = c.label
        state, current = new_state, res
        history.append({"label": c.label, "result": res})
    # a last screen for collinearity, whatever the residual: a white residual can hide an effect that
    # a fitted parameter absorbed (an offset inside mu at one speed). Skipped when the loop already
    # screened the final state.
    if screened_for is not state:
        scored = [(c, score_test(state, c, start=False)) for c in candidates(state.cfg, set(effects))]
        _note_confounded(scored, SCORE_ALPHA / max(len(scored), 1), confounded)
    white = bool(current.diagnostics["white_at_5pct"])
    first = datasets[0].time.size  # the spectrum of the first measurement (one speed)
    spec = order_spectrum(current.residual[:first], datasets[0].time[1] - datasets[0].time[0], current.speed)
    where = [{"order": round(p["order"], 3), "frequency": round(p["frequency"], 3), "amplitude": p["amplitude"]}
             for p in spec["peaks"][:5]]
    # "unexplained" is a claim about the data, so it needs stronger evidence than the 5 % whiteness
    # check that stops the search: runs or Ljung-Box below UNEXPLAINED_ALPHA / 2 (Bonferroni)
    d = current.diagnostics
    departs = min(d["runs_test"]["p_value"], d["ljung_box"]["p_value"]) < UNEXPLAINED_ALPHA / 2
    unexplained = departs and not explained_by_confounded
    out = {
        "baseline": {"rms": base.rms, "params": _params_json(base, base_names)},
        "steps": steps,
        "effects": effects,
        "final": {"rms": current.rms, "params": _params_json(current, state.names), "residual_white": white,
                  "runs_p_value": current.diagnostics["runs_test"]["p_value"],
                  "ljung_box_p_value": current.diagnostics["ljung_box"]["p_value"]},
        "unexplained": unexplained,
        "confounded": confounded,
        "unexplained_where": where if unexplained else [],
        "notes": _notes(confounded, cfg.vanes, len(datasets)),
        "method": ("score (Lagrange-multiplier) tests on AR(1)-prewhitened residual and sensitivities "
                   "(second-order terms where symmetry cancels the first-order ones), Bonferroni alpha "
                   f"{SCORE_ALPHA}; the {CONTENDERS} best by p-value and by one-step residual refitted and compared by BIC; acceptance by "
                   f"prewhitened likelihood ratio (p < {LR_ALPHA}) and BIC"),
        "wall_time": _time.perf_counter() - wall0,
        "screens": screens,
    }
    out["_history"] = history
    return out


def _ranking(scored, alpha, effects, n) -> dict:
    """One screen's candidates, best first: what was tested, how strongly, what was refitted."""
    rows = [{"candidate": c.label, "effect": c.effect, "order": c.order, "p_value": s["p_value"],
             "score": s["lm"], "dof": s["dof"], "significant": bool(s["p_value"] < alpha),
             "one_step_rms": math.sqrt(s["one_step_rss"] / n) if "one_step_rss" in s else None,
             "collinear_with": s["partner"]} for c, s in scored]
    rows.sort(key=lambda r: (r["p_value"], -r["score"]))
    return {"after": effects[-1] if effects else "baseline", "alpha": alpha, "candidates": rows,
            "chosen": None}


def _note_refits(screen, fits, bic0):
    """Mark the refitted contenders of a screen with their BIC change and likelihood-ratio p."""
    by_label = {r["candidate"]: r for r in screen["candidates"]}
    for f in fits:
        row = by_label[f["cand"].label]
        row["refit_delta_bic"], row["refit_lr_p_value"] = f["bic"] - bic0, f["lr_p"]


def _note_confounded(scored, alpha, confounded):
    """A candidate nearly collinear with a fitted parameter whose own (projected) score is not
    significant could hide inside that parameter: report the pair."""
    for c, s in scored:
        if s["partner"] is not None and s["p_value"] >= alpha:
            pair = [c.effect, s["partner"]]
            if pair not in confounded:
                confounded.append(pair)


def _notes(confounded, vanes, measurements=1):
    notes = []
    more = "a second speed" if measurements == 1 else "a measurement at a further speed"
    for a, b in confounded:
        notes.append(f"{a} and {b} have nearly collinear effects on this data: {more} would separate them")
    notes.append(f"with {vanes} identical, equally spaced vanes, housing-fixed defects appear only at "
                 f"multiples of {vanes} shaft orders")
    return notes


def _refit(state: State, cand: Candidate, score):
    """Fit the current names plus the candidate's parameters, starting from the score step."""
    cfg = cand.config(state.cfg)
    values = dict(state.values)
    values.update(score["start"])  # the joint one-step estimate
    if cand.effect == "sensor_lag":
        values["lag"] = max(values["lag"], 1e-6)
    ripple = cand.order if cand.effect == "speed_ripple" else state.ripple_order
    names = state.names + list(score["params"])
    res = identify(cfg, state.data, names, initial={n: values[n] for n in names}, multistart=False,
                   ripple_order=ripple)
    fitted = {n: (res.estimates[n].value if res.estimates[n].value is not None else values[n]) for n in names}
    vals = dict(cfg.values)
    for n_, v in fitted.items():
        if n_ in vals:
            vals[n_] = v
    return State(dataclasses.replace(cfg, values=vals), state.data, names, fitted, ripple), res


def step_table(result) -> str:
    lines = [f"{'step':<28}{'RMS before':>13}{'RMS after':>13}{'p-value':>11}  parameters"]
    lines.append(f"{'baseline':<28}{'':>13}{result['baseline']['rms']:>13.5g}{'':>11}  " + ", ".join(
        parameter_text(k, v["value"], v["stderr"]) for k, v in result["baseline"]["params"].items()))
    for s in result["steps"]:
        ps = ", ".join(step_parameters(s))  # amplitude/phase with units; (a, b) in the JSON only
        lines.append(f"{s['effect']:<28}{s['rms_before']:>13.5g}{s['rms_after']:>13.5g}{s['p_value']:>11.2g}  {ps}")
    f = result["final"]
    where = ", ".join(str(w["order"]) for w in result["unexplained_where"]) or "none distinct (broadband)"
    lines.append(f"final: RMS {f['rms']:.5g}, residual {'white' if f['residual_white'] else 'NOT white'} at 5 % "
                 f"(runs p {f['runs_p_value']:.2g}, Ljung-Box p {f['ljung_box_p_value']:.2g})"
                 + (f"; UNEXPLAINED residual, spectral peaks at shaft orders: {where}" if result["unexplained"] else ""))
    for a, b in result["confounded"]:
        lines.append(f"confounded: {a} ~ {b} (data at another speed would separate them)")
    lines.append(PLUS_MINUS)
    if not f["residual_white"]:
        lines.append(OPTIMISTIC)
    return "\n".join(lines)


def tty_progress():
    if not sys.stderr.isatty():
        return None
    return lambda msg: print(f"\r\033[Kpumpsim: {msg}", end="", file=sys.stderr, flush=True)
