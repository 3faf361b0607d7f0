"""Discrepancy workflow: find where model and measurement disagree, name the missing physical
effect, add it, refit, show the gap shrink -- and say "unexplained" rather than guess.

1. Speed: the configured speed is the operating point. A measurement without a speed column may
   refine it only inside a tolerance band (operation.speed_tolerance, default +-2 %) and only
   from shaft-synchronous evidence (an angle-domain average over revolutions, never a spectral
   peak); where the data cannot determine it (a concentric housing: torque ~ mu omega^2) it stays
   at the nominal, with a note.
2. Baseline fit (mu, theta0, and the speed as in 1.), then the residual detectors
   (diagnostics.detectors): runs test, Ljung-Box, the synchronous-average F-test (a shaft-locked
   residual, smooth or a train of one-sample spikes) and the high-frequency noise level;
   several measurements are tested one by one and combined (Bonferroni).
3. Every candidate effect of the library is scored on the (screening) record: a prewhitened
   score (Lagrange-multiplier) test from exact sensitivities, with second-order terms where the
   pump's symmetry cancels the first-order ones and finite probes where the torque reacts only
   through friction reversals that move. Every candidate also gets a one-step nonlinear fit, and
   all are compared by one criterion: the BIC of that fit.
4. The best few (significant by score or by their one-step likelihood ratio, Bonferroni) are
   refitted; the lowest BIC wins if its physical parameters are plausible (ranges below, declared
   once), its prewhitened likelihood-ratio test passes (p < 0.01) and BIC falls on the whole
   record. A rival within 10 BIC units -> both `confounded`, neither named. Repeat while the
   detectors reject at 5 %.
5. Verdict, exactly one of: consistent with noise (possibly after named effects); named effects
   and an unexplained remainder; nothing named and unexplained. `unexplained` needs the detector
   family at 1 % and a systematic residual above half the noise sigma (smaller remainders are
   what a fit's sample-level artefacts leave on exact data); an effect is named only if it changes
   the torque by more than that. `confounded` is reported in addition, never instead.

Long records: the search runs on a screening window of SCREEN_SAMPLES (the first samples of
each measurement); the baseline and every accepted effect are refitted on the whole record, and
the detectors and the acceptance test use the whole record: cost ~ linear in its length.

Physics worth knowing: with N identical, equally spaced vanes, housing-fixed defects only appear at
multiples of N shaft orders; other orders point to vane-to-vane differences or drive/sensor effects.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import sys
import time as _time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from scipy import stats

from .config import PumpConfig
from .data import Dataset
from .diagnostics import (VERDICT_DETECTORS, broadband_sigma, combined_p, detectors, kurtosis_test,
                          order_lines, order_spectrum, synchronous_speed_scan, systematic_rms)
from .errors import ConfigError
from .identification import base_name, half_band, speed_band
from .identification import identify as _identification_fit
from .identification import make_problem as _identification_problem
from .diagnostics import noise_sigma, speed_column_disagreement
from .identification.drift import parameter_drift
from .identification.problem import SPEED_COLUMN_Z, slot_ratio
from .model_spec.parameters import implausible
from .presentation import OPTIMISTIC, PLUS_MINUS, parameter_text, step_parameters

SCORE_ALPHA = 0.01
LR_ALPHA = 0.01
COLLINEAR = 0.995
MAX_EFFECTS = 4
SEARCH_ALPHA = 0.05  # detector family level that keeps the search going
UNEXPLAINED_ALPHA = 0.01  # detector family level behind `unexplained`
# systematic residual (or a named effect's torque change), RMS over the noise sigma, below which
# nothing is claimed: what a fit's sample-level artefacts (friction reversals moved by less than a
# sample) leave on exact data
RELEVANT = 0.5
NAMED_SIZE = 0.25  # a named effect's torque change, RMS over the noise sigma, at least
CONTENDERS = 3  # refitted per step: the best by the one-step BIC
BIC_DECISIVE = 10.0  # a BIC lead below this does not decide between two effects (Kass & Raftery)
SCREEN_SAMPLES = 5000  # the search's window of a long record (all measurements together)
# a fit found by searching ~150 probe configurations (the non-smooth eccentricity) is the best of
# many: its likelihood-ratio level is divided by this (Bonferroni over the probes)
SEARCHED = 150
SPEED_DETERMINED = 1 / 3  # a refined speed's stderr must be below this fraction of the band half-width
# the cost of the fits and comparisons: None = every sample; 0.0 = the reversal-aware cost
# (identification/reversals.py: samples within 1/8 sample interval of a model's Coulomb-reversal
# step weigh 0, the step threshold's noise sigma estimated from each residual). Every comparison
# below is made on the samples both models keep, so either choice is consistent. Measured on the
# reduced grid's geometric cases (notes of 2026-11-23, h11-diag): the reversal-aware cost turns
# most wrong names into misses -- on these rigs a 10 um oval or a 0.1 mm eccentricity moves the
# reversals by less than 1/8 of a sample and is seen ONLY through which side of a sample they
# fall -- so the fits stay on every sample; the kurtosis note uses the reversal-aware samples.
REVERSAL_SIGMA = None


def identify(*args, **kw):  # the workflow refines the operating point: its speed stays in the band;
    # its own detectors and verdict judge the fits (no per-fit adequacy)
    return _identification_fit(*args, reversals=REVERSAL_SIGMA, speed_in_band=True, adequacy=False, **kw)


def make_problem(*args, **kw):
    return _identification_problem(*args, reversals=REVERSAL_SIGMA, speed_in_band=True, **kw)


def _kept(*fits):
    """The samples every fit (an IdentificationResult, a bool array or None) kept: the common
    sample set on which two models are compared (the union of their masks dropped); None: all."""
    keep = None
    for f in fits:
        k = getattr(f, "keep", f)
        if k is not None:
            keep = np.array(k, dtype=bool) if keep is None else keep & k
    return keep


def _on(v, keep):
    return v if keep is None else v[keep]


def _every(keep, n):
    """The mask `keep` as a boolean array of n samples (None: all kept)."""
    return np.ones(n, bool) if keep is None else keep


def _rss(r, keep=None) -> tuple:
    rk = _on(r, keep)
    return float(rk @ rk), rk.size



# --- The effect library and its physical ranges (declared once, here) -------------------------

def clearance(cfg: PumpConfig) -> float:
    """Smallest radial gap between rotor and housing [m] (nominal housing, no defect)."""
    v = cfg.values
    return min(v["housing.a"], v["housing.b"]) - v["rotor.radius"]


def _with_harmonic_pair(cfg: PumpConfig, k: int) -> PumpConfig:
    """The config with two more housing-harmonic slots of order k, phases 0 and pi/(2k), zero
    amplitudes a and b: a cos(k phi) + b sin(k phi) = A cos(k (phi - gamma)) is linear in (a, b),
    so the fit needs no phase wrapping and the absent defect (a = b = 0) is a regular point."""
    return cfg.with_harmonics(cfg.harmonics + [[k, 0.0, 0.0], [k, 0.0, math.pi / (2 * k)]])


def _is_harmonic_amplitude(key: str) -> bool:
    return key.startswith("housing.harmonics.") and key.endswith(".amplitude")


def _out_of_round_implausible(cfg: PumpConfig, v: dict, context: dict) -> list:
    """An out-of-round of one order is a pair of harmonic slots: their hypot is the amplitude."""
    amps = {}
    for k_, x in v.items():
        if _is_harmonic_amplitude(k_):
            j = int(k_.split(".")[2])
            order = cfg.harmonics[j][0] if j < len(cfg.harmonics) else 0
            amps.setdefault(order, [k_, 0.0])[1] = math.hypot(amps.get(order, [k_, 0.0])[1], x)
    out = []
    for order, (k_, A) in amps.items():
        out += [m.replace(k_, f"out-of-round k={order:g} amplitude", 1) for m in implausible({k_: A}, context=context)]
    return out


def _vane_spread_implausible(cfg: PumpConfig, v: dict, context: dict) -> list:
    """A vane's COF is mu times its factor: checked against the COF's range."""
    mu = v.get("mu", cfg.values["friction.housing.dynamic"])
    out = []
    for i in range(cfg.vanes):
        f = v.get(f"effects.vane_friction_factor.{i}")
        if f is not None:
            out += [m.replace("friction.housing.dynamic", f"vane {i} COF (mu x factor)", 1)
                    for m in implausible({"friction.housing.dynamic": f * mu})]
    return out


def _out_of_round_polar(res, names, k) -> dict:
    """A cos(k (phi - gamma)): the housing's phase gamma is the harmonic pair's phase over k."""
    A, ph = _polar(res, names, k)
    return {"amplitude": A, "phase": {"value": ph["value"] / k, "stderr": ph["stderr"] / k}}


def _ripple_polar(res, names, k) -> dict:
    """omega = omega0 (1 + A cos(k theta + phase))."""
    A, ph = _polar(res, names, k)
    return {"amplitude": A, "phase": ph}


@dataclass(frozen=True)
class Effect:
    """One effect of the library, declared once: its fitted parameters (per shaft order), how it
    enters the model, how its score test probes it and how its parameters map onto the registry's
    plausibility ranges (model_spec.parameters). The workflow loops over these declarations."""
    name: str
    params: Callable[[PumpConfig, int | None], list]  # (config, order) -> fitted names for Problem
    orders: Callable[[PumpConfig], Iterable] = lambda cfg: (None,)  # shaft orders tried (None: no order)
    min_vanes: int = 1
    harmonic_pair: bool = False  # enters the config as a harmonic pair of its order
    ripple: bool = False  # its order is the drive's speed-ripple order
    # geometric defects of a pump with identical, equally spaced vanes can leave the torque
    # unchanged to first order (an eccentric housing with N >= 2: the per-vane changes at odd orders
    # cancel in the sum); their score test then uses the second-order terms, and the one-step
    # start is kept inside the clearance
    symmetric: bool = False
    # step of the second-order probes (state, problem) -> h; None: first-order score test only
    probe_step: Callable | None = None
    one_sided: bool = False  # a parameter >= 0 at its absent value 0: one-sided probes
    # non-smooth (friction reversals move): also a grid of finite sizes where the first order is
    # blind in some direction (score_test)
    finite_probes: bool = False
    start_floor: tuple = ()  # (name, least start value) pairs for the refit
    describe: Callable | None = None  # (result, names, order) -> extra JSON fields (amplitude, phase)
    claims: Callable[[str], bool] | None = None  # names whose range `implausible` checks instead of the registry
    implausible: Callable | None = None  # (config, values, context) -> reasons
    # (config, current values) -> its parameters' absent values where they are not the config's
    absent: Callable | None = None


def _slot_cof_tied(cfg: PumpConfig, values: dict) -> dict:
    """The slot COF while slot_friction is absent: mu's, in the configured slot/housing proportion
    (what every fit of mu alone does: identification/problem.py parameter_map)."""
    return {"mu_slot": values.get("mu", cfg.values["friction.housing.dynamic"]) * slot_ratio(cfg.values)}


EFFECTS = (
    Effect("rotor_eccentricity", lambda cfg, k: ["housing.center.0", "housing.center.1"], symmetric=True,
           probe_step=lambda state, prob: _probe_scale(state), finite_probes=True),
    Effect("housing_out_of_round",
           lambda cfg, k: [f"housing.harmonics.{j}.amplitude" for j in (len(cfg.harmonics), len(cfg.harmonics) + 1)],
           orders=lambda cfg: range(2, 9), harmonic_pair=True, symmetric=True,
           probe_step=lambda state, prob: _probe_scale(state), describe=_out_of_round_polar,
           claims=_is_harmonic_amplitude, implausible=_out_of_round_implausible),
    Effect("speed_ripple", lambda cfg, k: ["ripple_cos", "ripple_sin"], orders=lambda cfg: range(1, 2 * cfg.vanes + 1),
           ripple=True, describe=_ripple_polar),
    Effect("torque_offset", lambda cfg, k: ["torque_offset"]),
    # one-sided (T >= 0): probe a twentieth of a radian of lag; and a line of finite lags (a lag of
    # a sample or more, 0.3 ms at 5 kHz on an independent record, is far outside its quadratic model)
    Effect("sensor_lag", lambda cfg, k: ["lag"], probe_step=lambda state, prob: 0.05 / prob.speed_of(prob.x0),
           one_sided=True, start_floor=(("lag", 1e-6),), finite_probes=True),
    Effect("viscous_tip_friction", lambda cfg, k: ["effects.viscous_tip_friction"]),
    # a vane of another material or finish: its tip and slot COFs scaled together (vane 0 is the
    # reference; the reported mu is the mean over the vanes)
    Effect("vane_friction_spread", lambda cfg, k: [f"effects.vane_friction_factor.{i}" for i in range(1, cfg.vanes)],
           min_vanes=2, implausible=_vane_spread_implausible),
    # the configured slot/tip COF ratio is off (the slot COF is the one rigs rarely measure; a tip
    # COF rising with slip speed looks like this at one speed): mu_slot free, its range a COF's
    Effect("slot_friction", lambda cfg, k: ["mu_slot"], absent=_slot_cof_tied),
)
NOT_RANGED = ("theta0", "speed", "delay")  # measurement parameters without a plausibility range


def plausible(cfg: PumpConfig, values: dict, torque_rms: float, mean_torque: float) -> list:
    """Reasons why fitted values leave their physical range ([] = all plausible). `values` holds
    fitted names (joint suffixes allowed) -> value. The ranges and their physics are declared once,
    with each parameter, in the registry (model_spec.parameters: `plausible`); how this workflow's
    parametrisation maps onto them is declared with each effect (an out-of-round of one order is a
    pair of harmonic slots, a vane's COF is mu times its factor)."""
    v = {base_name(k): x for k, x in values.items() if x is not None}
    context = {"clearance": clearance(cfg), "speed": cfg.speed or 1.0, "vanes": cfg.vanes,
               "housing_a": cfg.values["housing.a"], "torque_rms": torque_rms, "mean_torque": mean_torque}
    plain = {k_: x for k_, x in v.items()
             if k_ not in NOT_RANGED and not any(e.claims is not None and e.claims(k_) for e in EFFECTS)}
    out = implausible(plain, context=context)
    for e in EFFECTS:
        if e.implausible is not None:
            out += e.implausible(cfg, v, context)
    return out


@dataclass
class Candidate:
    kind: Effect
    params: list  # parameter names for Problem
    order: int | None = None  # shaft order (out-of-round, speed ripple)

    @property
    def effect(self) -> str:
        return self.kind.name

    @property
    def symmetric(self) -> bool:
        return self.kind.symmetric

    @property
    def ripple_order(self) -> int | None:
        return self.order if self.kind.ripple else None

    @property
    def label(self):
        return f"{self.effect}(k={self.order})" if self.order else self.effect

    def config(self, cfg: PumpConfig) -> PumpConfig:
        return _with_harmonic_pair(cfg, self.order) if self.kind.harmonic_pair else cfg

    def problem(self, state: "State"):
        """The state's problem with this candidate's parameters added at their absent values."""
        if self.kind.absent is not None:
            state = State(state.cfg, state.data, state.names,
                          {**self.kind.absent(state.cfg, state.values), **state.values}, state.ripple_order)
        return state.problem(self.params, cfg=self.config(state.cfg), ripple_order=self.ripple_order)


def candidates(cfg: PumpConfig, added: set, detected: Iterable = ()) -> list:
    """The library's candidates, plus a speed ripple at each of the `detected` orders (above the
    library's: _detected_ripple_orders)."""
    return [Candidate(e, e.params(cfg, k), k) for e in EFFECTS if e.name not in added and cfg.vanes >= e.min_vanes
            for k in list(e.orders(cfg)) + (list(detected) if e.ripple else [])]


# A speed ripple above the library's orders 1..2N -- motor cogging or commutation ripple, seen by an
# in-line torque sensor only through the pump side's acceleration -- is tried at an order
# 2N < k <= RIPPLE_ORDER_MAX only where the current residual holds a line of its own AT that integer
# order (diagnostics.order_lines: significant against its non-integer neighbours, the largest within
# half an order, its frequency at k within its standard error, and the residual's lines mostly at
# integer orders -- a gear ripple, hum or a pulse train at 1.37 x shaft opens nothing). Trying every
# order up to 4N instead named a ripple on the reduced grid's concentric pulse train. The bound:
# the cogging order of a small PM motor is lcm(slots, poles) -- 12 (6 slots, 4 poles), 18 (9/6),
# 24 (12/8) -- and a brushed motor's commutator ripple is twice its 8-12 segments.
RIPPLE_ORDER_MAX = 24


def _detected_ripple_orders(run, current, added: set, fixed: int) -> tuple:
    """The speed-ripple orders above the library's that the current residual singles out (per
    measurement, Bonferroni over them) and whether any order was examined. The detector's family
    level is one candidate's share of the screen's, SCORE_ALPHA / (fixed + 1), and the screen counts
    it as one more candidate: a false opening and the fixed candidates' false alarms together stay
    within SCORE_ALPHA (union bound)."""
    ripple = next(e for e in EFFECTS if e.ripple)
    if ripple.name in added or current.angle is None:
        return [], False
    library = set(ripple.orders(run.cfg))
    orders = [k for k in range(1, RIPPLE_ORDER_MAX + 1) if k not in library]
    rows = np.cumsum([0] + [d.n for d in run.datasets])
    alpha = SCORE_ALPHA / (fixed + 1) / len(run.datasets)
    found, examined = set(), False
    for r, a in zip(_split(current.residual, rows), _split(current.angle, rows)):
        lines = order_lines(r, a, orders, alpha)
        examined |= bool(lines["examined"])
        found.update(lines["orders"])
    return sorted(found), examined


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

    def on(self, data):
        """The same model on other data (the screening record)."""
        return State(self.cfg, data, self.names, self.values, self.ripple_order)

    def jacobian(self):
        """The fitted parameters' Jacobian at the current fit, shared by every candidate's score
        test (a candidate at its absent value leaves the model and these columns unchanged)."""
        if self._jacobian is None:
            prob = self.problem()
            self._jacobian = prob.model_and_jacobian(prob.x0)[1]
        return self._jacobian

    def problem(self, extra_names=(), cfg=None, ripple_order=None, reversals=REVERSAL_SIGMA):
        names = self.names + [n for n in extra_names if n not in self.names]
        return _identification_problem(cfg or self.cfg, self.data, names, initial=self.values,
                                    extra={k: v for k, v in self.values.items() if k not in names},
                                    ripple_order=ripple_order or self.ripple_order, reversals=reversals,
                                    speed_in_band=True)


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


PROBE_SAMPLES = 2000  # the probe search's window: >= 10 revolutions at 10-20 kHz, enough to place the reversals


def _probe_window(state, cand, prob, Jb):
    """The candidate's problem and the fitted parameters' Jacobian on the first PROBE_SAMPLES
    samples (one measurement): the probes only choose a start, which is then judged on the whole
    screening window; ~120 model runs per candidate would otherwise cost ~120 x the window."""
    d = state.data
    if isinstance(d, (list, tuple)) or d.n <= PROBE_SAMPLES:
        return prob, Jb
    pw = cand.problem(state.on(d.window(0, PROBE_SAMPLES)))
    return pw, Jb[:PROBE_SAMPLES]


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
            d = np.linalg.lstsq(_on(Jb, keep), _on(r, keep), rcond=None)[0]
            x[:nb] += d
            r = r - Jb @ d
        return x, r, float(np.mean(_on(r, keep) ** 2))

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


TIED_SUBSETS = 12  # at most this many equivalent parameter subsets tried by their one-step fits


def _independent_subsets(Me) -> list:
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
        if list(subset) != first and len(out) < TIED_SUBSETS and \
                np.linalg.svd(A[:, subset], compute_uv=False)[-1] > 0.5 * full:
            out.append(list(subset))
    return out


def score_test(state: State, cand: Candidate, start=True):
    """LM statistic for adding `cand` at the current fit (prewhitened GLS score test). Returns the
    statistic, p-value, the collinearity with the fitted parameters and (start=True) a start for
    the refit with the nonlinear residual there. `start` may be a column subset of the
    candidate's parameters (one of several the data cannot tell apart): the start is then made
    with only those moved."""
    prob = cand.problem(state)
    nb = len(state.names)
    m, Je = prob.model_and_jacobian(prob.x0, range(nb, len(prob.names)))  # the candidate's columns
    keep0 = prob.keep_at(prob.x0)  # the current model's samples (the candidate at its absent values)
    rows = slice(None) if keep0 is None else keep0
    J1 = Je[rows]
    rs = prob.y - m
    Jb = state.jacobian()
    eff = cand.kind
    quad = (_second_order_columns(prob, prob.x0, nb, Je, eff.probe_step(state, prob), Jb, one_sided=eff.one_sided)
            if eff.probe_step is not None else None)
    if quad is not None:
        Je, pairs = quad
    rho = _ar1(rs[rows])
    r_w, Jb_w, Je_w = _prewhiten(rs[rows], rho), _prewhiten(Jb[rows], rho), _prewhiten(Je[rows], rho)
    # project out the fitted directions
    Q, _ = np.linalg.qr(Jb_w) if Jb_w.shape[1] else (np.zeros((r_w.size, 0)), None)
    proj = lambda A: A - Q @ (Q.T @ A)  # noqa: E731
    Me, Mr = proj(Je_w), proj(r_w)
    subsets = _independent_subsets(Me) if quad is None else [list(range(Me.shape[1]))]
    if len(subsets) > 1 and start is True:  # tied: the subset whose one-step fit is best, not the pivot's
        tried = [score_test(state, cand, start=subset) for subset in subsets]
        best = min(tried, key=lambda o: o["one_step_rss"] / max(o["n"], 1))
        best["tied"] = [o for o in tried if o is not best]  # refitted too (_refit)
        return best
    keep = list(start) if isinstance(start, list) else subsets[0]
    params = list(cand.params) if quad is not None else [cand.params[i] for i in keep]
    if len(keep) < Me.shape[1]:
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
           "second_order": quad is not None, "partner": partner, "searched": False}
    if start is False:
        return out
    # the joint one-step estimate (fitted parameters move too) and the nonlinear model there: a
    # cheap look past the linearisation, used to choose which candidates to refit
    step = _rank_one_start(coef, pairs, len(cand.params)) if quad is not None else coef
    x1 = prob.x0.copy()
    x1[[nb + cand.params.index(n) for n in params]] += step
    if nb:
        x1[:nb] += np.linalg.lstsq(Jb_w, r_w - Je_w @ coef, rcond=None)[0]
    x1 = np.clip(x1, prob.lower, prob.upper)
    if cand.symmetric:  # a step beyond the quadratic model's reach: back inside a tenth of the clearance
        x1[nb:] = _capped(x1[nb:], 0.5 * clearance(state.cfg))
    c1 = _cost(prob, x1, keep0)
    if not np.isfinite(c1[1]):
        c1 = (rs, float(np.mean(rs[rows] ** 2)), keep0)
        x1 = prob.x0.copy()
    x1, c1 = _profiled(prob, Jb, nb, x1, c1, keep0)
    # its one-step fit is then the best of many: judged at the searched level
    out["searched"] = bool(eff.finite_probes and (quad is not None or len(cand.params) == 1 or _direction_blind(J1)))
    if out["searched"]:
        x1, c1 = _probed(state, cand, prob, Jb, nb, x1, c1, keep0)
    common = _kept(keep0, c1[2])  # the one-step and the current model on one sample set
    (rss1, n1), (rss0, _) = _rss(c1[0], common), _rss(rs, common)
    out.update(start={n: v for n, v in zip(prob.names, x1) if n in state.names + params},
               one_step_rss=rss1, base_rss=rss0, n=n1, base=_rss(rs, keep0))
    return out


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
    keep = _kept(keep0, prob.keep_at(x))
    return r, float(np.mean(_on(r, keep) ** 2)), keep


PROFILE_STEPS = 2  # Gauss-Newton steps of the fitted parameters at the candidate's one-step value


def _profiled(prob, Jb, nb, x1, c1, keep0):
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
    for _ in range(PROFILE_STEPS):
        x = best[0].copy()
        k = _kept(keep0, best[1][2])
        x[:nb] += np.linalg.lstsq(_on(Jb, k), _on(best[1][0], k), rcond=None)[0]
        x = np.clip(x, prob.lower, prob.upper)
        c = _cost(prob, x, keep0)
        if not c[1] < best[1][1]:
            break
        best = (x, c)
    return best


def _probed(state, cand, prob, Jb, nb, x1, c1, keep0):
    """The better of the one-step fit (x1, r1) and the finite probes' best. For a non-smooth
    effect (the torque reacts through friction-reversal instants) where the first order is blind,
    in all directions (second-order score) or in one (a defect on a rig symmetric about an axis:
    the y shift of a centred 1-vane ellipse, where the linear step moves the other direction only)."""
    xp = _probe_grid(*_probe_window(state, cand, prob, Jb), nb, cand.kind.probe_step(state, prob),
                     one_sided=cand.kind.one_sided)
    cp = _cost(prob, xp, keep0)
    return (xp, cp) if cp[1] < c1[1] else (x1, c1)


BLIND_DIRECTION = 0.05  # a first-order column below this fraction of its pair's largest: blind


def _direction_blind(J) -> bool:
    """Whether the first-order sensitivity of a defect with several directions vanishes in one of
    them (a column's norm below BLIND_DIRECTION of the largest, or all zero)."""
    norms = np.linalg.norm(J, axis=0)
    return J.shape[1] > 1 and float(norms.min()) <= BLIND_DIRECTION * float(norms.max())


def _bic(rss, n, k):
    return n * math.log(max(rss, 1e-300) / n) + k * math.log(n)


def _whitened_rss(r, rho, keep=None):
    """The prewhitened RSS over the kept samples (dropped, the rest in order) and their number."""
    rw = _prewhiten(_on(r, keep), rho)
    return float(rw @ rw), rw.size


def _undetermined(name, value, se, cfg) -> bool:
    """An estimate whose standard error exceeds what would make it a result: larger than itself
    for a positive quantity (COF, speed, lag), than half the angular period for theta0, than the
    clearance for geometry and than its plausible size for the other effect parameters."""
    if value is None or se is None or not math.isfinite(se):
        return True
    b = base_name(name)
    if b == "theta0":
        return se > math.pi / max(cfg.vanes, 1)
    if b in ("mu", "mu_slot", "speed", "lag", "effects.viscous_tip_friction") or b.startswith("effects.vane"):
        return se > abs(value)
    if b.startswith("housing."):
        return se > clearance(cfg)
    if b in ("ripple_cos", "ripple_sin"):
        return se > 0.05
    return False


def _params_json(res, names, cfg):
    out = {}
    for n in names:
        e = res.estimates.get(n)
        if e is None:
            continue
        if e.value is not None and not _undetermined(n, e.value, e.stderr, cfg):
            out[n] = {"value": e.value, "stderr": e.stderr}
        else:  # never a number with a standard error larger than itself as a result
            out[n] = {"value": None, "stderr": None, "not_determined": {"estimate": e.value, "stderr": e.stderr}}
    return out


def _polar(res, names, k):
    """(a, b) -> amplitude and phase of a cos(k x) + b sin(k x) = A cos(k x - k gamma) with
    standard errors by the delta method: the physical description of an out-of-round or ripple."""
    ea, eb = res.estimates[names[0]], res.estimates[names[1]]
    a, b = ea.value, eb.value
    A = math.hypot(a, b)
    S = _covariance(res, names)
    gA = np.array([a, b]) / max(A, 1e-300)
    gP = np.array([-b, a]) / max(A * A, 1e-300)
    return ({"value": A, "stderr": float(math.sqrt(max(gA @ S @ gA, 0.0)))},
            {"value": math.atan2(b, a), "stderr": float(math.sqrt(max(gP @ S @ gP, 0.0)))})


def _covariance(res, names):
    """Covariance of the estimates `names` (stderr x correlation x stderr)."""
    ids = [n for n in res.estimates if res.estimates[n].identifiable]
    se = np.array([res.estimates[n].stderr or 0.0 for n in names])
    C = np.eye(len(names))
    if res.correlation is not None and all(n in ids for n in names):
        idx = [ids.index(n) for n in names]
        C = res.correlation[np.ix_(idx, idx)]
    return np.outer(se, se) * C


def _effect_params(cand, res, new_names, cfg):
    """The step's parameters as an engineer reads them."""
    out = _params_json(res, new_names, cfg)
    if cand.order:
        out["order"] = cand.order
    if cand.kind.describe is not None:  # amplitude and phase of a harmonic pair
        out.update(cand.kind.describe(res, new_names, cand.order))
    return out


def vane_cofs(res, cfg) -> tuple:
    """Each vane's effective dynamic COF (tip and slot: mu x its factor, vane 0 the reference) and
    the reported mu, their mean over the vanes, with standard errors by the delta method."""
    N = cfg.vanes
    names = ["mu"] + [f"effects.vane_friction_factor.{i}" for i in range(1, N)]
    fitted = [n for n in names if n in res.estimates and res.estimates[n].value is not None]
    val = {n: (res.estimates[n].value if n in fitted else
               (cfg.values["friction.housing.dynamic"] if n == "mu" else cfg.values[n])) for n in names}
    S = _covariance(res, fitted)
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


@dataclass
class DiagnosisResult:
    """What `diagnose` found. The JSON names (spec §7) are the fields; `str()` is the step table."""

    baseline: dict
    steps: list
    effects: list
    final: dict
    unexplained: bool
    confounded: list
    unexplained_where: list
    verdict: str
    notes: list
    detectors: dict
    speed: dict
    ranking: list
    screens: list  # per search step: after, alpha, candidates (by score p), chosen
    rejected: list
    method: str
    wall_time: float
    history: list = field(default_factory=list, repr=False)  # per step: label, IdentificationResult
    drift: list = field(default_factory=list)  # identification.drift.Drift.to_json() per drifting parameter
    budget: dict = field(default_factory=dict)  # {"seconds", "bound", "cut"}: what the time budget cut

    JSON = ("baseline", "steps", "effects", "final", "unexplained", "confounded", "unexplained_where",
            "verdict", "notes", "detectors", "speed", "ranking", "screens", "rejected", "method", "wall_time",
            "drift", "budget")

    def to_json(self) -> dict:
        return {k: getattr(self, k) for k in self.JSON}

    def __getitem__(self, key):  # read like the JSON
        if key not in self.JSON:
            raise KeyError(key)
        return getattr(self, key)

    def __contains__(self, key):
        return key in self.JSON

    def __str__(self):
        return step_table(self)


def _split(x, rows):
    return [x[a:b] for a, b in zip(rows[:-1], rows[1:])]


class _Verdict:
    """Detector results for one fit: per measurement, combined, and the systematic part."""

    def __init__(self, res, datasets, fitted):
        # on the samples the fit's reversal-aware cost kept (dropped, not zero-filled): the mask
        # follows the model, not the noise, so under the null the kept samples are still
        # independent with one variance and every detector's null distribution holds
        rows = np.cumsum([0] + [d.n for d in datasets])
        keep = _every(getattr(res, "keep", None), res.residual.size)
        pieces = [(r[k], a[k]) for r, a, k in zip(_split(res.residual, rows), _split(res.angle, rows),
                                                  _split(keep, rows))]
        self.per = [detectors(r, a, fitted) for r, a in pieces]
        self.p = combined_p(self.per)
        self.systematic = max(systematic_rms(r, d) for (r, _), d in zip(pieces, self.per))
        self.sigma = max(_noise_sigma(d) for d in self.per)

    def searching(self):
        """The residual departs from noise at the family level SEARCH_ALPHA (Bonferroni over the
        detectors and measurements): four detectors each at 5 % would search on ~19 % of pure-noise
        records (and pay for it in time and false-name chances); naming is guarded further by the
        score and LR tests."""
        return self.p["family"] < SEARCH_ALPHA

    def consistent(self):
        return self.p["family"] >= UNEXPLAINED_ALPHA or self.systematic < RELEVANT * self.sigma

    def to_json(self):
        per = [{d: {"statistic": m[d]["statistic"] if "statistic" in m[d] else m[d].get("q", m[d].get("z")),
                    "p_value": m[d]["p_value"]} for d in (*VERDICT_DETECTORS, "kurtosis")} for m in self.per]
        return {"combined_p": self.p, "per_measurement": per, "systematic_rms": self.systematic,
                "noise_sigma": self.sigma, "relevance_floor": RELEVANT * self.sigma}


def _noise_sigma(det):
    """Noise standard deviation: the smaller of the high-frequency and within-angle-bin estimates."""
    v = det["noise_level"]["sigma"] ** 2
    if det["synchronous_f"]["applicable"]:
        v = min(v, det["synchronous_f"]["within_var"])
    return math.sqrt(v)


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
    verdict = _Verdict(current, datasets, len(state.names))
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
        state, current = _drop_superseded(run, state, current, steps, effects, history)
        verdict = _Verdict(current, datasets, len(state.names))
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
    # phase over the record (_stationary_at_its_speed)
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


def _measurement(name: str) -> int:
    """The measurement a per-measurement fit name (speed@1) belongs to; 0 for a plain name."""
    return int(name.split("@")[1]) if "@" in name else 0


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
              e.stderr > SPEED_DETERMINED * half_band(cfg, run.datasets[_measurement(n)]))]
    for n in loose:
        m = run.speed_info["measurements"][_measurement(n)]
        why = ("torque depends on mu omega^2 only" if base.estimates[n].value is None
               else "standard error above a third of the band")
        held_at = {"nominal": "nominal", "speed column": "speed column's mean"}.get(m["source"], "synchronous-scan")
        run.notes.append(f"speed of measurement {_measurement(n)} not determined by the fit ({why}): held at the "
                         f"{held_at} value {m['value']:.6g} rad/s")
    if loose:
        keep = [b for b in base_names if b != "speed"] if K == 1 or len(loose) == len(run.free) else base_names
        if keep != base_names:
            base = _fit(cfg, run.full_data, keep, values, 1, run.screen_data, screen_hold=scanned)
    names = [n for n in base.estimates if base.estimates[n].identifiable and base.estimates[n].value is not None]
    for n in base.estimates:
        if base_name(n) == "speed" and n in names:
            e = base.estimates[n]
            run.speed_info["measurements"][_measurement(n)].update(source="fitted in band", value=e.value,
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
    detected, examined = _detected_ripple_orders(run, current, set(effects), len(candidates(state.cfg, set(effects))))
    scored = []
    for c in candidates(state.cfg, set(effects), detected):
        run.say(f"screening {c.label}")
        scored.append((c, score_test(scr, c)))
    tests = len(scored) + (examined and not detected)  # the detector counts as one candidate
    ranking = _rank(scr, scored, tests)
    screens.append(_screen_table(ranking, SCORE_ALPHA / tests, effects, scr))
    _note_confounded(scored, SCORE_ALPHA / tests, run.confounded, state.cfg)
    # the best by the one criterion, and the best by score p-value (a smooth effect whose
    # one-step fit a probe grid happened to beat)
    sig = [r for r in ranking if r["significant"]]
    contenders = sig[:CONTENDERS] + [r for r in sorted(sig, key=lambda r_: r_["score"]["p_value"])[:2]
                                     if r not in sig[:CONTENDERS]]
    lowest = _lowest_orders(sig)
    contenders += [r for r in lowest if not any(r is c_ for c_ in contenders)]
    if not contenders:
        return {"ranking": ranking}
    rho = _ar1(_on(current.residual, current.keep))
    fits = []
    for r in contenders:
        c, s = r["cand"], r["score"]
        if fits and run.out_of_time(f"the refit of {c.label}"):
            continue
        run.say(f"refitting with {c.label}")
        st, res = _refit(scr, c, s, polar=any(r is r_ for r_ in lowest) or (c.symmetric and not c.kind.harmonic_pair))
        if not c.symmetric:
            st, res = _rephased(st, res)
        fits.append({"cand": c, "score": s, "screen_state": st, "screen_res": res})
    base = _screen_base(scr)
    for f in fits:  # each contender against the current model on the screen, on their common samples
        lr, _, bic0, bic1 = _lr_bic(base, len(state.names), f["screen_res"], len(f["screen_state"].names), rho,
                                    _kept(base, f["screen_res"]))
        f["bic_screen"] = _bic(*_whitened_rss(base.residual, rho, base.keep), len(state.names)) + bic1 - bic0
    fits.sort(key=lambda f: f["bic_screen"])
    level0 = SCORE_ALPHA / tests
    accepted = _accept(run, fits, state, current, verdict, rho, level0)
    if accepted is None:
        return {"ranking": ranking}
    pair = _rival(run, fits, accepted, state, current, rho)
    if pair is not None:
        return {"ranking": ranking, "rival_pair": pair}
    return {"ranking": ranking, "accepted": accepted, "bic0": accepted["bic0"]}


def _rephased(st: State, res):
    """A smooth contender's fit (no polar starts: its one-step start is good in its own parameters)
    also fitted from the phase-and-speed scan start (identification/start.py) at its values, the
    better kept. Its cost is a staircase in theta0 and speed (each friction reversal falls on one
    side of a sample or the other), and a Gauss-Newton fit from the one-step start stays on the
    step it starts on: the grid's tilted3 torque offset at SNR 10 was refitted to 1.028 sigma, its
    own optimum is 1.020, and the viscous rival, at 1.023, was named instead. Two non-nested
    contenders are compared only at their optima."""
    if not any(base_name(n) in ("theta0", "speed") for n in st.names):
        return st, res
    again = _refit_on(st, st.data, multistart=True)
    return again if again[1].rms < res.rms else (st, res)


def _lowest_orders(sig) -> list:
    """Per housing-shape effect (a harmonic pair per order), its lowest significant order: a
    machined or clamped housing's out-of-round is dominated by its lowest orders (ovality k = 2,
    then trilobing), while the one-step fits that rank the orders cannot be trusted for a defect
    that acts through the friction reversals (F13/F14: a 15 um oval's one-step fit left 5.4 sigma,
    its refit 1.0) -- so it is refitted whatever its one-step rank."""
    out = {}
    for r in sig:
        c = r["cand"]
        if c.kind.harmonic_pair and (c.effect not in out or c.order < out[c.effect]["cand"].order):
            out[c.effect] = r
    return list(out.values())


@dataclass
class _Fitted:
    """A model's residual, fitted torque and reversal-aware mask (what a comparison needs)."""

    residual: np.ndarray
    fitted: np.ndarray
    keep: np.ndarray | None


def _screen_base(scr) -> _Fitted:
    """The current model on the screening window (no refit)."""
    prob = scr.problem()
    m = prob.model(prob.x0)
    return _Fitted(prob.y - m, m, prob.keep_at(prob.x0))


def _full_fit(run, f):
    """A contender's state and fit on the whole record (refitted from its screening fit)."""
    if run.screen_data is run.full_data:
        return f["screen_state"], f["screen_res"]
    return _refit_on(f["screen_state"], run.full_data)


def _lr_bic(current, k0, res, k1, rho, keep):
    """The current fit against a larger one on the common samples `keep`: (prewhitened LR,
    plain LR, BIC of the current, BIC of the larger)."""
    (rss0, nw), (rss1, _) = _whitened_rss(current.residual, rho, keep), _whitened_rss(res.residual, rho, keep)
    (p0, n), (p1, _) = _rss(current.residual, keep), _rss(res.residual, keep)
    ratio = lambda a, b: math.log(max(a, 1e-300) / max(b, 1e-300))  # noqa: E731
    return nw * ratio(rss0, rss1), n * ratio(p0, p1), _bic(rss0, nw, k0), _bic(rss1, nw, k1)


def _accept(run, fits, state, current, verdict, rho, score_level):
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
        st, res = _full_fit(run, f)
        disagreement = _speed_column_disagrees(run, st, res)
        if disagreement:
            run.rejected.append({"effect": f["cand"].label, "reasons": [disagreement]})
            run.notes.append(f"{f['cand'].label} rejected: {disagreement}")
            continue
        keep = _kept(current, res)
        q = len(st.names) - len(state.names)
        # the plain LR too: an AR(1) filter fitted to a large unmodelled line amplifies high
        # frequencies, where moved friction reversals can buy a spurious whitened gain
        lr, lr_plain, bic0, bic1 = _lr_bic(current, len(state.names), res, len(st.names), rho, keep)
        f.update(state=st, res=res, bic=bic1, bic0=bic0,
                 lr_p=max(float(stats.chi2.sf(lr, max(q, 1))), float(stats.chi2.sf(lr_plain, max(q, 1)))))
        level = LR_ALPHA if f["score"]["p_value"] < score_level else LR_ALPHA / SEARCHED
        # an effect is named only if it changes the model torque by more than a quarter of the
        # noise sigma: a statistically significant but smaller change is noise fitted through moved
        # friction reversals. Its size is the smaller of that change's RMS and the RMS it explains
        # (the drop of the residual's mean square): a change that moves friction reversals across
        # samples is a step's height there but explains little (a 3.9 us lag on an independent
        # no-effect record changed the torque by more than a quarter sigma, 9.6e-5 N m, and explained
        # 5.2e-5). The noise sigma is its whole standard deviation (_noise_scatter): coloured noise
        # has a high-frequency level well below it, and a lobe fitted to its slow wander is not a
        # quarter of what the noise does to each sample (F17). It is estimated on the candidate's
        # residual, the noise under the hypothesis being tested (as an F-test takes its variance from
        # the larger model): the current residual still holds the candidate's effect, which inflated
        # the yardstick by the effect's own remainder (grid eccentric5 eccentricity SNR 10: 1.77e-4
        # against the noise's 1.71e-4, a true effect's 4.42e-5 refused); with no effect the two
        # differ by the q fitted parameters' share, O(q/n)
        (rss0, n), (rss1, _) = _rss(current.residual, keep), _rss(res.residual, keep)
        size = min(float(np.sqrt(np.mean(_on(res.fitted - current.fitted, keep) ** 2))),
                   math.sqrt(max(rss0 - rss1, 0.0) / max(n, 1)))
        scatter = _noise_scatter(run, res, verdict)
        if size < NAMED_SIZE * scatter:
            run.notes.append(f"{f['cand'].label} not named: it changes (explains) the torque by {size:.3g} N m "
                             f"RMS, below {NAMED_SIZE:g} x the noise's scatter {scatter:.3g} N m")
            continue
        if f["lr_p"] < level and bic1 < bic0 and not run.implausible(st):
            h, st, res = _stationary_at_its_speed(run, st, res, [n for n in st.names if n not in state.names],
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


SPEED_COLUMN_ALPHA = LR_ALPHA / MAX_EFFECTS  # a speed hypothesis against a measured speed column


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


# Stationarity of an accepted effect (F16). A pump effect is stationary: the same parameter values
# explain every part of the record. The synchronous shadow of an out-of-library disturbance at a
# non-shaft frequency (a pulse train over a short record) is not: it changes with the pulses'
# phases, segment by segment. Each segment of whole revolutions gets its own linearised estimate of
# the effect's parameters about the whole-record fit (the base parameters and a held speed refitted
# per segment and profiled out; held at the record's fit where collinear with the effect's in a
# segment); under the null (stationary effect, white noise of a robust sigma -- the MAD of first
# differences, at most the detectors' --, a fit close enough for the linearisation)
# the estimates' weighted scatter about their pooled mean is chi-square with (S - 1) q degrees of
# freedom. The samples next to the model's friction reversals are left out of it (F14: there a
# reversal moved by a fraction of a sample is a model error as large as the noise, which scattered
# a true eccentricity's segment estimates to chi2 28-62 on 6 dof). Tested at LR_ALPHA / MAX_EFFECTS:
# the chance of dropping a true effect in one diagnosis stays below LR_ALPHA (Bonferroni over the
# effects a search may name).
STATIONARY_SEGMENTS = 4  # at most; each of at least STATIONARY_MIN_REVS whole revolutions
STATIONARY_MIN_REVS = 2
STATIONARY_ALPHA = LR_ALPHA / MAX_EFFECTS
# The test is made only where the candidate's fit leaves a large remainder, its residual RMS (off the
# reversals) above STATIONARY_GATE x the robust sigma: the situation of F16 (pulse trains leave 4.5-10
# x). Where the fit leaves little, the scatter the test sees is the reversal staircase's model error
# (the samples next to a reversal moved by a whole sample interval are not all left out): true
# eccentricities on the 4-vane ellipse left 1.4-2.1 x and gave chi2 ~200 on 6 dof (measured).
STATIONARY_GATE = 3.0


def homogeneity(J, r, segments, sigma, nuisance=None) -> dict:
    """Chi-square test that the least-squares estimates of b in r ~ J b (+ N c, the nuisance
    columns N refitted in each segment and profiled out), one per segment label in `segments`,
    agree (white noise of standard deviation sigma): statistic, dof, p_value, per-segment
    estimates. Segments whose columns are not of full rank are left out."""
    q = J.shape[1]
    A = J if nuisance is None else np.column_stack([J, nuisance])
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    A = A / scale
    est, info = [], []
    for s in np.unique(segments):
        m = segments == s
        F = A[m].T @ A[m]
        if np.linalg.matrix_rank(F, tol=1e-10 * max(np.trace(F), 1e-300)) < A.shape[1]:
            continue
        Finv = np.linalg.inv(F)
        est.append((Finv @ (A[m].T @ r[m]))[:q])
        info.append(np.linalg.inv(Finv[:q, :q]) / sigma ** 2)  # the profiled (Schur) information
    if len(est) < 2:
        return {"statistic": 0.0, "dof": 0, "p_value": 1.0, "estimates": []}
    W = sum(info)
    pooled = np.linalg.solve(W, sum(I @ b for I, b in zip(info, est)))
    stat = float(sum((b - pooled) @ I @ (b - pooled) for I, b in zip(info, est)))
    dof = (len(est) - 1) * q
    return {"statistic": stat, "dof": dof, "p_value": float(stats.chi2.sf(stat, dof)),
            "estimates": [(b / scale[:q]).tolist() for b in est]}


def _revolution_segments(angle, rows):
    """Per sample, its segment: each measurement cut into up to STATIONARY_SEGMENTS runs of whole
    revolutions (None when no measurement has 2 x STATIONARY_MIN_REVS revolutions)."""
    labels, usable = [], False
    for a in _split(angle, rows):
        rev = np.floor((a - a[0]) / (2 * math.pi)) if a.size else a
        revs = int(rev[-1]) + 1 if a.size else 0
        S = min(STATIONARY_SEGMENTS, revs // STATIONARY_MIN_REVS)
        usable |= S >= 2
        per = max(revs // max(S, 1), 1)
        labels.append(np.minimum(rev // per, max(S - 1, 0)))
    return np.concatenate(labels) if usable else None


def _stationary(run, st, res, new_names, sigma) -> dict | None:
    """The homogeneity test of the effect's parameters `new_names` over segments of the record;
    None when the record is too short to cut."""
    rows = np.cumsum([0] + [d.n for d in run.datasets])
    seg = None if res.angle is None else _revolution_segments(np.asarray(res.angle, float), rows)
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
    keep = _every(prob.keep_at(prob.x0), res.residual.size)
    # the noise level from the median absolute first difference (robust to a pulse train, whose
    # few large samples inflate the detectors' high-frequency estimate), never above theirs
    robust = noise_sigma(res.residual[keep]) if keep.sum() > 1 else sigma
    args = (J[keep], res.residual[keep], seg[keep], min(sigma, robust) if robust > 0 else sigma)
    if np.sqrt(np.mean(args[1] ** 2)) < STATIONARY_GATE * args[3]:
        return None  # no large remainder: the effect explains the record (see STATIONARY_GATE)
    h = homogeneity(*args, N[keep])
    # base columns collinear with the effect's within a segment: the base held at the record's fit
    return h if h["dof"] or not N.size else homogeneity(*args)


def _stationary_at_its_speed(run, st, res, new_names, sigma):
    """(homogeneity test, state, fit) of an effect; if it fails while a speed column's mean is
    held, again with the speed refined in the column's band (_try_speed): a held speed a little off
    turns a large effect's phase over the record, and its segments disagree although the effect is
    stationary (independent eccentric5 record, 0.3 % noisy speed column: its mean 1.6e-5 low left a
    true 0.57 % ripple at chi2 2580 on 6 dof; at the fitted speed the ripple leaves the noise). The
    refined speed is kept only if it makes the effect stationary."""
    h = _stationary(run, st, res, new_names, sigma)
    column = any(run.datasets[i].speed is not None for i in run.free)  # a column's speed in its band
    # a held speed (a column's mean, or the nominal where the baseline torque did not determine it:
    # a concentric rig's torque has no shaft orders until the effect gives it some) is refined
    if (h is None or h["p_value"] >= STATIONARY_ALPHA or not run.free
            or any(base_name(n) == "speed" for n in st.names)):
        return h, st, res
    info, notes = {"measurements": [dict(m) for m in run.speed_info["measurements"]]}, []
    st2, res2 = _try_speed(st, res, run.full_data, run.screen_data, info, notes)
    if st2 is st:
        return h, st, res
    h2 = _stationary(run, st2, res2, new_names, sigma)  # None: no remainder left to test
    if h2 is not None and h2["p_value"] < STATIONARY_ALPHA:
        return h, st, res
    run.speed_info["measurements"] = info["measurements"]
    band = (f"the speed column's band (its mean +- {SPEED_COLUMN_Z:g} standard errors)" if column else
            f"its tolerance band (+- {100 * run.cfg.speed_tolerance:g} %)")
    run.notes.append(f"speed refined in {band}: at the held speed the effect's parameters disagreed between "
                     "segments of the record")
    return h2, st2, res2


def _rival(run, fits, accepted, state, current, rho):
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
    st, res = _full_fit(run, rival)
    keep = _kept(current, accepted["res"], res)
    k0 = len(state.names)
    lr, _, bic0, bic_r = _lr_bic(current, k0, res, len(st.names), rho, keep)
    bic_a = _lr_bic(current, k0, accepted["res"], len(accepted["state"].names), rho, keep)[3]
    rival.update(bic=bic_r, lr_p=float(stats.chi2.sf(lr, max(len(st.names) - k0, 1))))
    if rival["lr_p"] < LR_ALPHA and bic_r < bic0 and bic_r - bic_a < BIC_DECISIVE:
        pair = [accepted["cand"].effect, rival["cand"].effect]
        if pair not in run.confounded:
            run.confounded.append(pair)
        return pair
    return None


def _add_effect(run, found, state, current, steps, effects, screens):
    """Record the accepted effect as a step; the new state (with a held speed tried again)."""
    accepted = found["accepted"]
    c, s, res, new_state = accepted["cand"], accepted["score"], accepted["res"], accepted["state"]
    # a speed refined with it (_stationary_at_its_speed) is the measurement's, not the effect's
    new_names = [n for n in new_state.names if n not in state.names and base_name(n) != "speed"]
    steps.append({"effect": c.effect, "params": _effect_params(c, res, new_names, new_state.cfg),
                  "rms_before": current.rms, "rms_after": res.rms, "p_value": s["p_value"],
                  "score": s["lm"], "score_dof": s["dof"], "second_order_score": s["second_order"],
                  "lr_p_value": accepted["lr_p"], "bic_before": found["bic0"], "bic_after": accepted["bic"],
                  "all_params": _params_json(res, new_state.names, new_state.cfg)})
    effects.append(c.effect)
    run.added.append(new_names)
    screens[-1]["chosen"] = c.label
    if run.free and not any(base_name(n) == "speed" for n in new_state.names):
        return _try_speed(new_state, res, run.full_data, run.screen_data, run.speed_info, run.notes)
    return new_state, res


def _drop_superseded(run, state, current, steps, effects, history):
    """Backward check after a new effect (forward selection is greedy: an effect named first can
    be one that a later, right effect makes unnecessary -- a speed ripple of order 1 standing in
    for a 1-vane eccentricity). Each earlier-named effect is judged by the acceptance test's own
    criteria given the others: its part of the final model torque (its parameters set absent, the
    rest unchanged) must be at least NAMED_SIZE x the noise sigma, and removing it (the others
    refitted) must fail the prewhitened LR test (p < LR_ALPHA) with a higher BIC. The least
    needed failing one is dropped, with a note, and the check repeats. Assumes, like the
    acceptance test, that the residual's AR(1) coefficient stands for the noise."""
    while len(effects) >= 2:
        sigma = _Verdict(current, run.datasets, len(state.names)).sigma
        rho = _ar1(_on(current.residual, current.keep))
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
    needed (see _drop_superseded), else None."""
    absent = _absent(run, names)
    prob = make_problem(state.cfg, run.full_data, state.names, initial=state.values,
                        extra={k: v for k, v in state.values.items() if k not in state.names},
                        ripple_order=state.ripple_order)
    x = prob.x0.copy()
    for n in names:
        x[state.names.index(n)] = absent[n]
    size = float(np.sqrt(np.mean(_on(prob.model(prob.x0) - prob.model(x), current.keep) ** 2)))
    st, res = _without(run, state, names, absent)
    if size < NAMED_SIZE * sigma:
        return 2.0, f"its part of the torque is {size:.3g} N m RMS, below {NAMED_SIZE:g} x the noise sigma", st, res
    lr, _, bic0, bic1 = _lr_bic(res, len(st.names), current, len(state.names), rho, _kept(current, res))
    p = float(stats.chi2.sf(lr, len(names)))
    if p >= LR_ALPHA or bic0 <= bic1:
        return p, f"without it the likelihood ratio p is {p:.2g} (or BIC no higher)", st, res
    return None


def _absent(run, names) -> dict:
    """The absent values: an added harmonic pair at zero amplitude, a config key at its configured
    value, a ripple, lag or offset at zero."""
    return {n: 0.0 if _is_harmonic_amplitude(n) or n not in run.cfg.values else run.cfg.values[n] for n in names}


def _without(run, state, names, absent):
    """The state refitted on the whole record with `names` at their `absent` values."""
    cfg = dataclasses.replace(state.cfg, values={**state.cfg.values,
                                                 **{k: v for k, v in absent.items() if k in state.cfg.values}})
    keep = [n for n in state.names if n not in names]
    values = {**state.values, **absent}
    held = {k: v for k, v in values.items() if k not in keep}
    res = identify(cfg, run.full_data, keep, initial={n: values[n] for n in keep}, multistart=False,
                   ripple_order=state.ripple_order, extra=held)
    return _state_from(cfg, run.full_data, keep, values, res, state.ripple_order), res


def _result(run, base, state, current, verdict, steps, effects, ranking, screens, rival_pair, history, wall0):
    """Step 5: the verdict (exactly one of three), notes, the reported mu, the DiagnosisResult."""
    # a last screen for collinearity, whatever the residual: a white residual can hide an effect
    # that a fitted parameter absorbed (an offset inside mu at one speed)
    scr = state.on(run.screen_data)
    scored = [(c, score_test(scr, c, start=False)) for c in candidates(state.cfg, set(effects)) if not c.symmetric]
    _note_confounded(scored, SCORE_ALPHA / max(len(scored), 1), run.confounded, state.cfg)
    consistent = verdict.consistent()
    notes = run.notes
    if rival_pair is not None:
        notes.append(f"{rival_pair[0]} and {rival_pair[1]} explain the remaining residual equally well "
                     f"(within {BIC_DECISIVE:g} BIC): neither is named")
    if consistent and verdict.p["family"] < UNEXPLAINED_ALPHA:
        notes.append(f"a systematic residual of {verdict.systematic:.3g} N m remains, below "
                     f"{RELEVANT:g} x the noise sigma ({verdict.sigma:.3g} N m): not claimed as a discrepancy")
    for m, k in zip(verdict.per, _kurtosis_off_reversals(run, state, current)):
        m["kurtosis"] = k  # reported as tested: on the samples off the model's reversals
    kurt = verdict.per[0]["kurtosis"]
    # claimed like a systematic residual: significant AND relevant (the tails add at least
    # RELEVANT x the noise sigma in RMS; a lone sample a fit's moved reversal leaves is not)
    if kurt["p_value"] < UNEXPLAINED_ALPHA and kurt["excess_rms"] >= RELEVANT * kurt["mad_sigma"]:
        notes.append(f"heavy-tailed residual (kurtosis test): spikes or non-Gaussian noise add "
                     f"{kurt['excess_rms']:.3g} N m RMS above the noise sigma {kurt['mad_sigma']:.3g} N m")
    notes += _notes(run.confounded, state, run.screen_data, len(run.datasets))
    drifts = _drifts(run, state)
    notes += [f"{d.text()} (a straight line through {len(d.segments)} segment fits, p {d.p_value:.2g}): the "
              "model's constant value is its mean over the record" for d in drifts]
    if run.budget.get("bound"):
        notes.append(f"time budget of {run.budget['seconds']:g} s reached: not done -- "
                     + "; ".join(run.budget["cut"]) + " (a larger --budget does them)")
    per_vane, mu_mean = vane_cofs(current, state.cfg)
    final_params = _params_json(current, state.names, state.cfg)
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
        baseline={"rms": base.rms, "params": _params_json(base, list(base.estimates), run.cfg)},
        steps=steps, effects=effects,
        final={"rms": current.rms, "params": final_params, "residual_white": consistent,
               "runs_p_value": verdict.p["runs_test"], "ljung_box_p_value": verdict.p["ljung_box"],
               "synchronous_f_p_value": verdict.p["synchronous_f"],
               "noise_level_p_value": verdict.p["noise_level"], "vane_mu": per_vane,
               "mu_definition": MU_DEFINITION},
        unexplained=not consistent, confounded=run.confounded,
        unexplained_where=[] if consistent else _where(current, run.datasets, verdict), verdict=label,
        notes=notes, detectors=verdict.to_json(), speed=run.speed_info,
        ranking=[{"effect": r["cand"].label, "score_p_value": r["score"]["p_value"],
                  "one_step_bic": r["bic"], "significant": r["significant"]} for r in ranking],
        screens=screens, rejected=run.rejected, method=METHOD,
        wall_time=_time.perf_counter() - wall0, history=history, drift=[d.to_json() for d in drifts],
        budget=run.budget)


def _drifts(run, state) -> list:
    """The COF's drift over a single measurement's record (identification.drift), at the final
    model's other values; [] with several measurements or no fitted mu."""
    if len(run.datasets) > 1 or "mu" not in state.names or run.out_of_time("the drift test"):
        return []
    data = run.datasets[0]
    speed = state.values.get("speed", data.mean_speed() if data.speed is not None else state.cfg.speed)

    def fit(seg, names, init):
        held = {k: v for k, v in state.values.items() if k not in names}
        return identify(state.cfg, seg, names, initial=init, multistart=False, ripple_order=state.ripple_order,
                        extra=held)

    found = parameter_drift(fit, data, "mu", state.values, speed)
    return [found] if found is not None else []


METHOD = ("detectors: runs, Ljung-Box, synchronous-average F-test, high-frequency noise level "
          f"(family {UNEXPLAINED_ALPHA:g}, Bonferroni over detectors and measurements); candidates: "
          "prewhitened score tests (second order where symmetry cancels the first) and one-step "
          f"nonlinear fits ranked by BIC; the {CONTENDERS} best refitted, physical ranges enforced, "
          f"acceptance by prewhitened likelihood ratio (p < {LR_ALPHA:g}) and BIC on the whole record")


def _rank(state, scored, tests=None):
    """All candidates by one criterion: the BIC of their one-step nonlinear fit (score step, or
    second-order/probe start where the first order is blind). Significant: score p or one-step
    likelihood ratio below alpha / (number of tests: the candidates, by default)."""
    k0 = len(state.names)
    alpha = SCORE_ALPHA / max(tests or len(scored), 1)
    out = []
    for c, s in scored:
        q = len(s["params"])
        # each one-step fit against the current model on the samples both keep (reversal-aware
        # cost); the candidates compared by that BIC difference, added to the current model's BIC
        # on its own samples (the intersection of ~30 candidates' masks would keep few samples)
        n, rss0 = s["n"], s["base_rss"]
        rss1 = min(s["one_step_rss"], rss0)
        lr = n * math.log(max(rss0, 1e-300) / max(rss1, 1e-300))
        lr_p = float(stats.chi2.sf(lr, max(q, 1)))
        sig = s["p_value"] < alpha or ((s["second_order"] or s.get("searched", False)) and lr_p < alpha / SEARCHED)
        rss_b, n_b = s["base"]
        out.append({"cand": c, "score": s, "bic": _bic(rss_b, n_b, k0) - lr + q * math.log(n),
                    "significant": bool(sig)})
    out.sort(key=lambda r_: r_["bic"])
    return out


def _screen_table(ranking, alpha, effects, state) -> dict:
    """One screen's candidates for the report, by score p-value: what was tested, how strongly."""
    rows = [{"candidate": r["cand"].label, "effect": r["cand"].effect, "order": r["cand"].order,
             "p_value": r["score"]["p_value"], "score": r["score"]["lm"], "dof": r["score"]["dof"],
             "significant": r["significant"], "one_step_bic": r["bic"],
             "one_step_rms": math.sqrt(r["score"]["one_step_rss"] / r["score"]["n"])
             if "one_step_rss" in r["score"] else None,
             "collinear_with": r["score"]["partner"]} for r in ranking]
    rows.sort(key=lambda r: (r["p_value"], -r["score"]))
    return {"after": effects[-1] if effects else "baseline", "alpha": alpha, "candidates": rows, "chosen": None}


def _kurtosis_off_reversals(run, state, current) -> list:
    """The kurtosis test per measurement on the residual at the samples the reversal-aware cost
    keeps at the final fit (independent finding F8: a phase within its standard error moves a few
    Coulomb steps across a sample, each leaving one residual sample of the step's height; those
    samples are the ones next to a model step)."""
    prob = state.problem(reversals=0.0)
    keep = _every(prob.keep_at(prob.x0), current.residual.size)
    rows = np.cumsum([0] + [d.n for d in run.datasets])
    return [kurtosis_test(r[k]) for r, k in zip(_split(current.residual, rows), _split(keep, rows))]


def _noise_scatter(run, fit, verdict) -> float:
    """The noise's standard deviation whatever its colour: the residual of `fit` without its narrow
    spectral lines (diagnostics.broadband_sigma), per measurement, the largest; at least the
    detectors' noise sigma (`verdict`'s). Coloured noise keeps its full variance (under AR(1) noise, phi 0.85,
    the high-frequency level is 0.4 x it); the misfit a named effect leaves at a few orders does
    not count as noise (an independent two-effect record: a 2.8 % speed ripple's misfit made the
    within-angle-bin scatter 2.3 x the noise, and the true offset was refused)."""
    rows = np.cumsum([0] + [d.n for d in run.datasets])
    return max([verdict.sigma] + [broadband_sigma(r) for r in _split(fit.residual, rows)])


def _where(res, datasets, verdict):
    """Where an unexplained residual lies: spectral peaks (shaft orders, Hz) of the first
    measurement and, when the synchronous F-test rejects, the rotor angles of the largest
    departures of the angle-domain average."""
    n0 = datasets[0].n
    r = res.residual[:n0]
    spec = order_spectrum(r, datasets[0].time[1] - datasets[0].time[0], res.speed)
    out = [{"order": round(p["order"], 3), "frequency": round(p["frequency"], 3), "amplitude": p["amplitude"]}
           for p in spec["peaks"][:5]]
    sf = verdict.per[0]["synchronous_f"]
    if sf["applicable"] and sf["p_value"] < UNEXPLAINED_ALPHA:
        avg = np.nan_to_num(sf["average"])
        B = avg.size
        se = math.sqrt(sf["within_var"] / max(np.mean(sf["counts"][sf["counts"] > 0]), 1))
        for b in np.argsort(-np.abs(avg))[:5]:
            if abs(avg[b]) > 3 * se:
                out.append({"angle_deg": round(float((b + 0.5) * 360.0 / B), 2), "amplitude": float(avg[b])})
    return out


def _note_confounded(scored, alpha, confounded, cfg):
    """A candidate nearly collinear with a fitted parameter whose own (projected) score is not
    significant could hide inside that parameter: report the pair."""
    for c, s in scored:
        if s["partner"] is not None and s["p_value"] >= alpha:
            pair = [c.effect, _owner(s["partner"], cfg)]
            if pair not in confounded:
                confounded.append(pair)


def _owner(name, cfg) -> str:
    """A fitted name as the engineer reads it: a named effect's parameter as that effect (as the
    library declares its parameters: an out-of-round's harmonic amplitude, the housing centre, the
    ripple pair, the lag), a baseline parameter as itself."""
    n = base_name(name)
    for e in EFFECTS:
        if (e.claims is not None and e.claims(n)) or any(n in e.params(cfg, k) for k in e.orders(cfg)):
            return e.name
    return n


def _separable_at_another_speed(state, effect, partner):
    """Would a second measurement at 0.6 x this speed separate `effect` from `partner`? The pair's
    sensitivities at both speeds stacked: still collinear means no speed separates them."""
    cand = next((c for c in candidates(state.cfg, set()) if c.effect == effect), None)
    partner_names = [n for n in state.names if _owner(n, state.cfg) == partner]  # a fitted effect: all its names
    if cand is None or not partner_names or isinstance(state.data, (list, tuple)):
        return None
    d = state.data
    w = d.mean_speed() if d.speed is not None else state.values.get("speed", state.cfg.speed)
    other = Dataset(d.time, d.torque, speed=np.full(d.n, 0.6 * w))
    cols = []
    for data in (Dataset(d.time, d.torque, speed=np.full(d.n, w)), other):
        held = {k: v for k, v in state.values.items() if base_name(k) != "speed"}  # the data's speed
        st = State(state.cfg, data, partner_names, held, state.ripple_order)
        prob = cand.problem(st)
        cols.append(prob.model_and_jacobian(prob.x0)[1])
    J = np.vstack(cols)
    P, B = J[:, :len(partner_names)], J[:, len(partner_names):]
    P = P[:, np.linalg.norm(P, axis=0) > 0]
    if not P.size:
        return None
    Q = np.linalg.qr(P)[0]
    for j in range(B.shape[1]):  # a candidate direction inside the partner's span at both speeds
        b = B[:, j]
        if np.linalg.norm(Q.T @ b) > COLLINEAR * (np.linalg.norm(b) + 1e-300):
            return False
    return True


def _notes(confounded, state, screen_data, measurements):
    notes = []
    scr = state.on(screen_data)
    for a, b in confounded:
        if measurements > 1:
            notes.append(f"{a} and {b} have nearly collinear effects even on these {measurements} measurements")
            continue
        sep = _separable_at_another_speed(scr, a, b)
        if sep is False:
            notes.append(f"{a} and {b} have nearly collinear effects on this data, and would at any speed")
        else:
            notes.append(f"{a} and {b} have nearly collinear effects on this data: a measurement at a "
                         "second speed would separate them")
    N = state.cfg.vanes
    notes.append(f"with {N} identical, equally spaced vanes, housing-fixed defects appear only at "
                 f"multiples of {N} shaft orders")
    return notes


REFIT_STARTS = 8  # polar starts of a geometric refit, besides its one-step start
REFIT_SCOUT_STEPS = 4  # Gauss-Newton steps from each start before the best is fitted to convergence
REFIT_RADIUS = 2e-4  # their least radius, of the housing's larger semi-axis (~5 um on a 22 mm housing)
# the radii of the polar starts, of that radius: the one-step estimate's size is itself read off a
# staircase (F13/F14), so the starts also sample half of it (finding 4, eccentric5's 10 um k=2
# oval: every start at the one-step radius, 12 um, stops at 1.49-2.7 sigma, the named oval 5.5 um
# then an eccentricity; one at half of it reaches 1.24 sigma and the oval is named alone)
REFIT_RADII = (0.5, 1.0)


def _refit(state: State, cand: Candidate, score, polar=False):
    """_refit_from the score step and from each tied subset's (score_test), the lowest RMS kept:
    the subsets' one-step fits rank them only to first order (independent 4-vane ellipse, one vane
    25 % smoother with the baseline's phase a vane pitch off, so that vane is not vane 3 but vane 2:
    the best one-step subset, vane 3's factor, refitted to 1.266 at 1.05 sigma -- vane 2's to 0.749
    at the noise -- and a 0.0045 % speed ripple was named for the difference)."""
    fits = [_refit_from(state, cand, s, polar) for s in [score] + score.get("tied", [])]
    return min(fits, key=lambda f: f[1].rms)


def _refit_from(state: State, cand: Candidate, score, polar=False):
    """Fit the current names plus the candidate's parameters, starting from the score step (on the
    state's data). A geometric defect (eccentricity, out-of-round) is fitted with the interval
    Jacobian columns (identification/problem.py: they carry the friction reversals' motion), and
    with `polar` also from REFIT_STARTS directions about its absent value at the one-step
    estimate's radius (at least REFIT_RADIUS) and at half of it, a few steps each, the lowest cost fitted to
    convergence: the cost is a staircase in its parameters (F13/F14) whose valley a fit from the
    one-step start often misses (the grid's 15 um oval on the 4-vane ellipse: 1.61 sigma from the
    one-step start, 1.02 from a polar start, the truth's valley 1.017; an eccentricity's one-step
    estimate can be the mirror image of the truth)."""
    cfg = cand.config(state.cfg)
    values = dict(state.values)
    values.update(score.get("start", {}))  # the joint one-step estimate
    for name, least in cand.kind.start_floor:
        values[name] = max(values.get(name, 0.0), least)
    ripple = cand.ripple_order if cand.ripple_order is not None else state.ripple_order
    names = state.names + list(score["params"])
    held = {k: v for k, v in values.items() if k not in names}
    starts = [{n: values[n] for n in names if n in values}]
    if polar and len(score["params"]) == 2:
        starts += _polar_starts(state, cand, score["params"], values)
    fit = lambda init, data=state.data, **kw: identify(  # noqa: E731
        cfg, data, names, initial=init, multistart=False, ripple_order=ripple, extra=held,
        interval=cand.symmetric, **kw)
    if len(starts) == 1:
        res = fit(starts[0])
    else:  # a few steps from every start (on the probe window), then the best one to convergence
        scout = _scout_window(state.data)
        res = min((fit(init, scout, max_iter=REFIT_SCOUT_STEPS) for init in starts), key=lambda r: r.rms)
        if scout is not state.data or not res.converged:
            res = fit({n: res.estimates[n].value for n in names if res.estimates[n].value is not None})
    return _state_from(cfg, state.data, names, values, res, ripple), res


def _scout_window(data):
    """The first PROBE_SAMPLES samples of one measurement (the polar starts only choose a start; the
    probe search's window, long enough to place the reversals), else the data itself. A shorter
    window (1000 samples, of the reduced grid's 1001) chose starts that lost 2 of its 87 named
    cases (concentric4 oval SNR 5, ellipse4 eccentricity SNR 5)."""
    if isinstance(data, (list, tuple)) or data.n <= PROBE_SAMPLES:
        return data
    return data.window(0, PROBE_SAMPLES)


def _polar_starts(state, cand, params, values) -> list:
    """REFIT_STARTS directions x REFIT_RADII starts of a two-parameter geometric defect about its
    absent value (a harmonic pair's zero, the configured centre), the fitted names at the current fit."""
    v = state.cfg.values
    centre = np.array([0.0 if cand.kind.harmonic_pair else v[n] for n in params])
    radius = max(REFIT_RADIUS * max(v["housing.a"], v["housing.b"]),
                 float(np.hypot(*(np.array([values.get(n, 0.0) for n in params]) - centre))))
    return [{**{n: state.values[n] for n in state.names},
             **dict(zip(params, centre + f * radius * np.array([math.cos(b), math.sin(b)])))}
            for b in np.arange(REFIT_STARTS) * 2 * math.pi / REFIT_STARTS for f in REFIT_RADII]


def _state_from(cfg, data, names, values, res, ripple):
    fitted = {n: (res.estimates[n].value if res.estimates[n].value is not None else values.get(n)) for n in names}
    fitted = {n: v for n, v in fitted.items() if v is not None}
    vals = dict(cfg.values)
    for n_, v in fitted.items():
        if n_ in vals:
            vals[n_] = v
    allv = {**values, **fitted}
    return State(dataclasses.replace(cfg, values=vals), data, [n for n in names if n in fitted], allv, ripple)


def _refit_on(st: State, data, multistart=False):
    """The state's names refitted on `data` from the state's values (the others held): a screening
    window's fit on the whole record, or (multistart) from the phase-and-speed scan start."""
    held = {k: v for k, v in st.values.items() if k not in st.names}
    res = identify(st.cfg, data, st.names, initial={n: st.values[n] for n in st.names},
                   multistart=multistart, ripple_order=st.ripple_order, extra=held)
    return _state_from(st.cfg, data, st.names, st.values, res, st.ripple_order), res


def _try_speed(state, current, full_data, screen_data, speed_info, notes):
    """After an effect has made the torque depend on the angle, refine a held speed in its band if
    the data now determines it (and BIC agrees)."""
    names = state.names + ["speed"]
    held = {k: v for k, v in state.values.items() if k not in names}
    init = {n: state.values[n] for n in state.names}
    init["speed"] = state.values.get("speed", state.cfg.speed)
    res = identify(state.cfg, full_data, names, initial=init, multistart=False,
                   ripple_order=state.ripple_order, extra=held)
    datasets = full_data if isinstance(full_data, (list, tuple)) else [full_data]
    sp = [(e, half_band(state.cfg, datasets[_measurement(n)])) for n, e in res.estimates.items()
          if base_name(n) == "speed"]
    keep = _kept(current, res)
    (rss1, n), (rss0, _) = _rss(res.residual, keep), _rss(current.residual, keep)
    if (all(e.value is not None and e.stderr is not None and e.stderr <= SPEED_DETERMINED * half for e, half in sp)
            and _bic(rss1, n, len(res.estimates)) < _bic(rss0, n, len(state.names))):
        for nm, e in res.estimates.items():
            if base_name(nm) == "speed":
                speed_info["measurements"][_measurement(nm)].update(source="fitted in band", value=e.value,
                                                                    stderr=e.stderr)
        notes.append("speed refined in its band once the named effect made the torque depend on the angle")
        return _state_from(state.cfg, full_data, list(res.estimates), state.values, res, state.ripple_order), res
    return state, current


def _fmt_param(k, v):
    if not isinstance(v, dict):
        return f"{k} {v:.4g}"
    if v["value"] is None:
        return f"{k} not determined"
    return f"{k} {v['value']:.4g} ± {v['stderr']:.2g}"


def step_table(result) -> str:
    lines = [f"{'step':<28}{'RMS before':>13}{'RMS after':>13}{'p-value':>11}  parameters"]
    lines.append(f"{'baseline':<28}{'':>13}{result['baseline']['rms']:>13.5g}{'':>11}  " + ", ".join(
        parameter_text(k, v["value"], v["stderr"]) for k, v in result["baseline"]["params"].items()))
    for s in result["steps"]:
        ps = ", ".join(step_parameters(s))  # amplitude/phase with units; (a, b) in the JSON only
        lines.append(f"{s['effect']:<28}{s['rms_before']:>13.5g}{s['rms_after']:>13.5g}{s['p_value']:>11.2g}  {ps}")
    f = result["final"]
    lines.append(f"final: RMS {f['rms']:.5g}, mu (mean over vanes) {_fmt_param('', f['params'].get('mu', {'value': None})).strip()}; "
                 f"detectors p: runs {f['runs_p_value']:.2g}, Ljung-Box {f['ljung_box_p_value']:.2g}, "
                 f"synchronous F {f['synchronous_f_p_value']:.2g}, noise level {f['noise_level_p_value']:.2g}")
    if "effects.vane_friction_factor.1" in f["params"]:
        lines.append("vane COFs: " + ", ".join(f"{i}: {v['value']:.4g}" for i, v in enumerate(f["vane_mu"])))
    where = ", ".join((f"order {w['order']}" if "order" in w else f"{w['angle_deg']} deg")
                      for w in result["unexplained_where"]) or "broadband"
    lines.append(f"verdict: {result['verdict'].upper()}" + (f" (at {where})" if result["unexplained"] else ""))
    for a, b in result["confounded"]:
        lines.append(f"confounded: {a} ~ {b}")
    for n in result["notes"]:
        lines.append(f"note: {n}")
    lines.append(PLUS_MINUS)
    if not f["residual_white"]:
        lines.append(OPTIMISTIC)
    return "\n".join(lines)


def tty_progress():
    if not sys.stderr.isatty():
        return None
    return lambda msg: print(f"\r\033[Kpumpsim: {msg}", end="", file=sys.stderr, flush=True)
