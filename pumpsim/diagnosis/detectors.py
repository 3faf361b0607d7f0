"""Is a residual noise? The detector family on one fit, per measurement and combined, and where
an unexplained residual lies."""
from __future__ import annotations

import math

import numpy as np

from ..signals import (VERDICT_DETECTORS, broadband_sigma, combined_p, detectors, kurtosis_test, order_spectrum,
                           systematic_rms)

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
        self.systematic = max(systematic_rms(r, d) for (r, _), d in zip(pieces, self.per))
        self.sigma = max(_noise_sigma(d) for d in self.per)

    def searching(self):
        """The residual departs from noise at the family level `search_alpha` (Bonferroni over the
        detectors and measurements): four detectors each at 5 % would search on ~19 % of pure-noise
        records (and pay for it in time and false-name chances); naming is guarded further by the
        score and LR tests."""
        return self.p["family"] < self.opts.search_alpha

    def consistent(self):
        return self.p["family"] >= self.opts.unexplained_alpha or self.systematic < self.opts.relevant * self.sigma

    def to_json(self):
        per = [{d: {"statistic": m[d]["statistic"] if "statistic" in m[d] else m[d].get("q", m[d].get("z")),
                    "p_value": m[d]["p_value"]} for d in (*VERDICT_DETECTORS, "kurtosis")} for m in self.per]
        return {"combined_p": self.p, "per_measurement": per, "systematic_rms": self.systematic,
                "noise_sigma": self.sigma, "relevance_floor": self.opts.relevant * self.sigma}


def _noise_sigma(det):
    """Noise standard deviation: the smaller of the high-frequency and within-angle-bin estimates."""
    v = det["noise_level"]["sigma"] ** 2
    if det["synchronous_f"]["applicable"]:
        v = min(v, det["synchronous_f"]["within_var"])
    return math.sqrt(v)


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
