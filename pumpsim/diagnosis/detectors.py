"""Is a residual noise? The detector family on one fit, per measurement and combined, and where
an unexplained residual lies."""
from __future__ import annotations

import math

import numpy as np

from ..signals import (VERDICT_DETECTORS, broadband_sigma, combined_p, detectors, high_frequency_noise,
                           kurtosis_test, order_spectrum)

from .options import OPTIONS, DiagnosisOptions
from .state import full_mask, split_rows


class Detection:
    """Detector results for one fit: per measurement, combined, and the systematic part."""

    def __init__(self, res, datasets, fitted, opts: DiagnosisOptions = OPTIONS):
        self.opts = opts
        # on the samples the fit's reversal-aware cost kept (dropped, not zero-filled): the mask
        # follows the model, not the noise, so under the null the kept samples are still
        # independent with one variance and every detector's null distribution holds
        rows = np.cumsum([0] + [d.n for d in datasets])
        keep = full_mask(getattr(res, "keep", None), res.residual.size)
        pieces = [(r[k], a[k]) for r, a, k in zip(split_rows(res.residual, rows), split_rows(res.angle, rows),
                                                  split_rows(keep, rows))]
        self.per = [detectors(r, a, fitted) for r, a in pieces]
        self.p = combined_p(self.per)
        # the selection's noise scale (named sizes, the stationarity gate): the detectors' estimate
        self.sigma = max(_noise_sigma(d) for d in self.per)
        # the relevance bar's: also the estimate off the model's torque steps, where lower (_floor_variance)
        model = getattr(res, "fitted", None)
        models = [None] * len(pieces) if model is None else [m[k] for m, k in zip(split_rows(model, rows),
                                                                                  split_rows(keep, rows))]
        floors = [_floor_variance(r, d, m) for (r, _), d, m in zip(pieces, self.per, models)]
        self.systematic = max(math.sqrt(max(float(np.var(r)) - v, 0.0)) for (r, _), v in zip(pieces, floors))
        self.floor_sigma = math.sqrt(max(floors))

    def searching(self):
        """The residual departs from noise at the family level `search_alpha` (Bonferroni over the
        detectors and measurements): four detectors each at 5 % would search on ~19 % of pure-noise
        records (and pay for it in time and false-name chances); naming is guarded further by the
        score and LR tests."""
        return self.p["family"] < self.opts.search_alpha

    def consistent(self):
        return self.p["family"] >= self.opts.unexplained_alpha or self.systematic < self.opts.relevant * self.floor_sigma

    def to_json(self):
        per = [{d: {"statistic": m[d]["statistic"] if "statistic" in m[d] else m[d].get("q", m[d].get("z")),
                    "p_value": m[d]["p_value"]} for d in (*VERDICT_DETECTORS, "kurtosis")} for m in self.per]
        return {"combined_p": self.p, "per_measurement": per, "systematic_rms": self.systematic,
                "noise_sigma": self.sigma, "relevance_noise_sigma": self.floor_sigma,
                "relevance_floor": self.opts.relevant * self.floor_sigma}


def _noise_sigma(det):
    """Noise standard deviation: the smaller of the high-frequency and within-angle-bin estimates."""
    v = det["noise_level"]["sigma"] ** 2
    if det["synchronous_f"]["applicable"]:
        v = min(v, det["synchronous_f"]["within_var"])
    return math.sqrt(v)


STEP_CURVATURE = 20.0  # a model step: |second difference| this many times its median (the smooth curvature)
STEP_NOISE = 0.5  # ... and at least this many noise sigmas (a smaller step leaves no relevant spike)
# the level off the steps replaces the detectors' only below this share of it: on the grid's
# no-effect and right-named records (eccentric5, ellipse4) the two agree to 0.93-1.10; the spikes of
# moved reversals raise the detectors' 2.2-4.4 x above the noise where a verdict turned on it
OFF_STEPS_RATIO = 0.8


def _off_steps(model, sigma) -> np.ndarray:
    """False at the samples next to the sampled model's torque steps (Coulomb friction reversals):
    the samples on either side of a second difference above STEP_CURVATURE x its median and
    STEP_NOISE x the noise sigma. A step between two samples shows in the second differences at
    both, a torque smooth on the sample scale as tau'' dt^2, far below."""
    d2 = np.abs(np.diff(np.asarray(model, dtype=float), 2))
    keep = np.ones(np.size(model), dtype=bool)
    if d2.size == 0:
        return keep
    step = np.nonzero(d2 > max(STEP_CURVATURE * float(np.median(d2)), STEP_NOISE * sigma))[0] + 1
    for o in (-1, 0, 1):
        keep[np.clip(step + o, 0, keep.size - 1)] = False
    return keep


def _floor_variance(r, det, model=None) -> float:
    """The noise variance behind the relevance bar: the detectors' (the smaller of the
    high-frequency and within-angle-bin estimates), or the high-frequency level off the model's
    torque steps where that is lower. A friction reversal the fit leaves on the other side of a
    sample leaves a one-sample spike of the step's height; a few per cent of the samples so spiked
    are white to every spectral estimate and scatter within the angle bins, so both estimates
    count them as noise (the eccentric 5-vane rig with a 60 um trilobe: the fit's residual 4.5 x
    the noise sigma, both estimates 4.4 x it, and "consistent with noise"). With the samples next
    to the steps set to zero (the periodogram of white noise scales by the share kept) the level
    is the noise's again (0.94-1.10 x it on those records) -- a spectral estimate, so unbiased for
    heavy-tailed noise too, which a median of differences is not. It is taken only where it is
    clearly lower (OFF_STEPS_RATIO): two estimates of one white noise differ by chance, and the
    smaller of two would lower the bar on every record."""
    v = _noise_sigma(det) ** 2
    if model is None or r.size < 64:
        return v
    keep = _off_steps(model, math.sqrt(v))
    share = float(keep.mean())
    if share < 0.5:  # too few samples off the steps for a level
        return v
    off = np.where(keep, r - np.mean(r[keep]), 0.0)
    level = high_frequency_noise(off)["sigma"] ** 2 / share
    return level if level < OFF_STEPS_RATIO ** 2 * v else v


def kurtosis_off_reversals(run, state, current) -> list:
    """The kurtosis test per measurement on the residual at the samples the reversal-aware cost
    keeps at the final fit (a phase within its standard error moves a few
    Coulomb steps across a sample, each leaving one residual sample of the step's height; those
    samples are the ones next to a model step)."""
    prob = state.problem(reversals=0.0)
    keep = full_mask(prob.keep_at(prob.x0), current.residual.size)
    rows = np.cumsum([0] + [d.n for d in run.datasets])
    return [kurtosis_test(r[k]) for r, k in zip(split_rows(current.residual, rows), split_rows(keep, rows))]


def noise_scatter(run, fit, verdict) -> float:
    """The noise's standard deviation whatever its colour: the residual of `fit` without its narrow
    spectral lines (signals.broadband_sigma), per measurement, the largest; at least the
    detectors' noise sigma (`verdict`'s). Coloured noise keeps its full variance (under AR(1) noise, phi 0.85,
    the high-frequency level is 0.4 x it); the misfit a named effect leaves at a few orders does
    not count as noise (an independent two-effect record: a 2.8 % speed ripple's misfit made the
    within-angle-bin scatter 2.3 x the noise, and the true offset was refused)."""
    rows = np.cumsum([0] + [d.n for d in run.datasets])
    return max([verdict.sigma] + [broadband_sigma(r) for r in split_rows(fit.residual, rows)])


def where_unexplained(res, datasets, verdict, opts: DiagnosisOptions = OPTIONS):
    """Where an unexplained residual lies: spectral peaks (shaft orders, Hz) of the first
    measurement and, when the synchronous F-test rejects, the rotor angles of the largest
    departures of the angle-domain average."""
    n0 = datasets[0].n
    r = res.residual[:n0]
    spec = order_spectrum(r, datasets[0].time[1] - datasets[0].time[0], res.speed)
    out = [{"order": round(p["order"], 3), "frequency": round(p["frequency"], 3), "amplitude": p["amplitude"]}
           for p in spec["peaks"][:5]]
    sf = verdict.per[0]["synchronous_f"]
    if sf["applicable"] and sf["p_value"] < opts.unexplained_alpha:
        avg = np.nan_to_num(sf["average"])
        B = avg.size
        se = math.sqrt(sf["within_var"] / max(np.mean(sf["counts"][sf["counts"] > 0]), 1))
        for b in np.argsort(-np.abs(avg))[:5]:
            if abs(avg[b]) > 3 * se:
                out.append({"angle_deg": round(float((b + 0.5) * 360.0 / B), 2), "amplitude": float(avg[b])})
    return out
