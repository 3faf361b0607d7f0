"""The workflow's levels, sizes and budgets, each with why it has its value
(docs/explanation/discrepancy-workflow.md tells the longer story)."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class DiagnosisOptions:
    """What a diagnosis decides with. The defaults are the calibrated workflow: the diagnose
    benchmark grid's rates are measured with them."""

    # a candidate's score test, Bonferroni over the candidates of one screen
    score_alpha: float = 0.01
    # an accepted effect's prewhitened likelihood-ratio test against the current model
    lr_alpha: float = 0.01
    # |cos| of a candidate's direction with a fitted one above which the pair is reported confounded
    collinear: float = 0.995
    # effects one diagnosis may name; also the Bonferroni count of the per-effect tests
    max_effects: int = 4
    # detector family level that keeps the search going (four detectors each at 5 % would search
    # on ~19 % of pure-noise records)
    search_alpha: float = 0.05
    # detector family level behind `unexplained`
    unexplained_alpha: float = 0.01
    # systematic residual, RMS over the noise sigma, below which nothing is claimed: what a fit's
    # sample-level artefacts (friction reversals moved by less than a sample) leave on exact data
    relevant: float = 0.5
    # a named effect's torque change, RMS over the noise's scatter, at least
    named_size: float = 0.25
    # refitted per step: the best by the one-step BIC
    contenders: int = 3
    # a BIC lead below this does not decide between two effects (Kass & Raftery: "strong")
    bic_decisive: float = 10.0
    # the search's window of a long record (all measurements together): cost ~ linear in its length
    screen_samples: int = 5000
    # a one-step fit found by searching ~150 probe configurations is the best of many: its
    # likelihood-ratio level is divided by this (Bonferroni over the probes)
    searched: int = 150
    # a refined speed's standard error must be below this fraction of its band's half-width
    speed_determined: float = 1 / 3
    # the fits' cost: None = every sample; 0.0 = the reversal-aware cost. On the benchmark rigs a
    # small geometric defect is seen only through which side of a sample the friction reversals
    # fall, so the fits stay on every sample; the kurtosis note uses the reversal-aware samples
    reversal_sigma: float | None = None
    # highest speed-ripple order tried where the residual holds a line of its own at that order:
    # a small motor's cogging order lcm(slots, poles) (12, 18, 24) or twice its commutator segments
    ripple_order_max: int = 24
    # the probe search's window: >= 10 revolutions at 10-20 kHz, enough to place the reversals
    probe_samples: int = 2000
    # at most this many equivalent parameter subsets tried by their one-step fits
    tied_subsets: int = 12
    # Gauss-Newton steps of the fitted parameters at a candidate's one-step value
    profile_steps: int = 2
    # a first-order column below this fraction of its pair's largest: blind in that direction
    blind_direction: float = 0.05
    # stationarity: at most this many segments, each of at least `stationary_min_revs` revolutions
    stationary_segments: int = 4
    stationary_min_revs: int = 2
    # the stationarity test runs only where the candidate's fit leaves a residual RMS above this
    # many robust noise sigmas: below it the test sees the friction-reversal staircase's model error
    stationary_gate: float = 3.0
    # polar starts of a geometric refit, besides its one-step start
    refit_starts: int = 8
    # Gauss-Newton steps from each finalist start before the best is fitted to convergence
    refit_scout_steps: int = 4
    # the starts scouted in full: those whose quick look (refit_quick_steps steps on the interval
    # columns' smooth formula, no exact polish) ends lowest (refit._finalists: what that cost and
    # saved on the grid)
    refit_finalists: int = 3
    refit_quick_steps: int = 1
    # the RMS a polar search's other starts may still gain over its finalists': a search whose
    # finalists' fit trails the best contender by more (and the decisive margin) is not completed.
    # Twice the largest gain seen on the reduced grid's geometric refits (4.5 %, tilted3 oval). Its
    # best scout's fit to convergence may gain as much again: a scout that trails by (1 + gain)^2 is
    # not fitted to convergence (refit._trails; completed if the selection reaches it)
    refit_gain: float = 0.1
    # how much lower in RMS a contender's scout (refit_scout_steps steps on the interval columns)
    # may end than its quick look: up to 2.0x seen on the reduced grid. A contender whose quick look
    # trails by this much more than a scout may is not scouted (refit._refit_from)
    quick_look_gain: float = 3.0
    # the polar starts' least radius, of the housing's larger semi-axis (~5 um on a 22 mm housing)
    refit_radius: float = 2e-4
    # the polar starts' radii, of that radius: the one-step size is itself read off a staircase
    refit_radii: tuple = (0.5, 1.0)

    @property
    def stationary_alpha(self) -> float:
        """Level of the stationarity test: dropping a true effect in one diagnosis stays below
        lr_alpha (Bonferroni over the effects a search may name)."""
        return self.lr_alpha / self.max_effects

    @property
    def speed_column_alpha(self) -> float:
        """Level at which a measured speed column refutes a speed hypothesis (as stationarity)."""
        return self.lr_alpha / self.max_effects


OPTIONS = DiagnosisOptions()
