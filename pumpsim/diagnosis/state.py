"""The current model of a diagnosis (config, fitted names and values) and the statistics every
comparison of two fits shares: the samples both keep, (prewhitened) residual sums of squares, BIC."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import StartError
from ..identification import identify as _identification_fit
from ..identification import make_problem as _identification_problem

# The fits' cost: None = every sample (0.0 would be the reversal-aware cost, which drops the samples
# next to a model's Coulomb-reversal steps). On the benchmark rigs a 10 um oval or a 0.1 mm
# eccentricity moves the reversals by less than 1/8 of a sample and is seen only through which side
# of a sample they fall, so the fits stay on every sample; the kurtosis note uses the
# reversal-aware samples. Every comparison is made on the samples both models keep.
REVERSAL_COST = None


def identify(*args, **kw):  # the workflow refines the operating point: its speed stays in the band;
    # its own detectors and verdict judge the fits (no per-fit adequacy unless asked: the baseline's)
    return _identification_fit(*args, reversals=REVERSAL_COST, speed_in_band=True, **{"adequacy": False, **kw})


def make_problem(*args, **kw):
    return _identification_problem(*args, reversals=REVERSAL_COST, speed_in_band=True, **kw)


def common_keep(*fits):
    """The samples every fit (an IdentificationResult, a bool array or None) kept: the common
    sample set on which two models are compared (the union of their masks dropped); None: all."""
    keep = None
    for f in fits:
        k = getattr(f, "keep", f)
        if k is not None:
            keep = np.array(k, dtype=bool) if keep is None else keep & k
    return keep


def on_kept(v, keep):
    return v if keep is None else v[keep]


def full_mask(keep, n):
    """The mask `keep` as a boolean array of n samples (None: all kept)."""
    return np.ones(n, bool) if keep is None else keep


def sum_squares(r, keep=None) -> tuple:
    rk = on_kept(r, keep)
    return float(rk @ rk), rk.size


def ar1(r):
    """Lag-1 autocorrelation of r, the AR(1) coefficient of the prewhitening filter."""
    rc = r - r.mean()
    rho = float(np.dot(rc[1:], rc[:-1]) / max(np.dot(rc, rc), 1e-300))
    return min(max(rho, -0.99), 0.99)


def prewhiten(v, rho):
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

    def problem(self, extra_names=(), cfg=None, ripple_order=None, reversals=REVERSAL_COST):
        names = self.names + [n for n in extra_names if n not in self.names]
        return _identification_problem(cfg or self.cfg, self.data, names, initial=self.values,
                                    extra={k: v for k, v in self.values.items() if k not in names},
                                    ripple_order=ripple_order or self.ripple_order, reversals=reversals,
                                    speed_in_band=True)


def bic(rss, n, k):
    """The Bayesian information criterion n ln(RSS/n) + k ln n: the one definition every comparison,
    table and page of a diagnosis uses (RSS prewhitened where the residual is: `whitened_rss`)."""
    return n * math.log(max(rss, 1e-300) / n) + k * math.log(n)


def whitened_rss(r, rho, keep=None):
    """The prewhitened RSS over the kept samples (dropped, the rest in order) and their number."""
    rw = prewhiten(on_kept(r, keep), rho)
    return float(rw @ rw), rw.size


def split_rows(x, rows):
    return [x[a:b] for a, b in zip(rows[:-1], rows[1:])]


def measurement_of(name: str) -> int:
    """The measurement a per-measurement fit name (speed@1) belongs to; 0 for a plain name."""
    return int(name.split("@")[1]) if "@" in name else 0


@dataclass
class Fitted:
    """A model's residual, fitted torque and reversal-aware mask (what a comparison needs)."""

    residual: np.ndarray
    fitted: np.ndarray
    keep: np.ndarray | None


class Comparison(NamedTuple):
    """A fit against a larger one on their common samples."""

    lr: float  # prewhitened likelihood ratio
    lr_plain: float  # likelihood ratio without prewhitening
    bic0: float  # BIC of the smaller model (prewhitened)
    bic1: float  # BIC of the larger model


def lr_bic(current, k0, res, k1, rho, keep) -> Comparison:
    """The current fit against a larger one on the common samples `keep`."""
    (rss0, nw), (rss1, _) = whitened_rss(current.residual, rho, keep), whitened_rss(res.residual, rho, keep)
    (p0, n), (p1, _) = sum_squares(current.residual, keep), sum_squares(res.residual, keep)
    ratio = lambda a, b: math.log(max(a, 1e-300) / max(b, 1e-300))  # noqa: E731
    return Comparison(nw * ratio(rss0, rss1), n * ratio(p0, p1), bic(rss0, nw, k0), bic(rss1, nw, k1))


def state_from(cfg, data, names, values, res, ripple):
    fitted = {n: (res.estimates[n].value if res.estimates[n].value is not None else values.get(n)) for n in names}
    fitted = {n: v for n, v in fitted.items() if v is not None}
    vals = dict(cfg.values)
    for n_, v in fitted.items():
        if n_ in vals:
            vals[n_] = v
    allv = {**values, **fitted}
    return State(dataclasses.replace(cfg, values=vals), data, [n for n in names if n in fitted], allv, ripple)


def refit_on(st: State, data, multistart=False):
    """The state's names refitted on `data` from the state's values (the others held): a screening
    window's fit on the whole record, or (multistart) from the phase-and-speed scan start."""
    held = {k: v for k, v in st.values.items() if k not in st.names}
    res = identify(st.cfg, data, st.names, initial={n: st.values[n] for n in st.names},
                   multistart=multistart, ripple_order=st.ripple_order, extra=held)
    return state_from(st.cfg, data, st.names, st.values, res, st.ripple_order), res


def past_stall(fit, init, res) -> tuple:
    """A fit no step left from a start that is NOT a minimum (optimiser.start_test: its slope
    points standard errors away -- a step of the friction reversals' staircase) fitted once more,
    by `fit(values)`, from `init` with where its Gauss-Newton step points: (the better of the two
    by RMS, the second fit or None when there was none or its start is outside the model: StartError)."""
    if res.converged or not res.points_to:
        return res, None
    try:
        again = fit({**init, **res.points_to})
    except StartError:  # the slope points out of the pump's geometry: no start to fit from
        return res, None
    return (again if again.rms < res.rms else res), again
