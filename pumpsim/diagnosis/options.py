"""The workflow's levels, sizes and budgets, each with why it has its value."""
from __future__ import annotations






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


PROBE_SAMPLES = 2000  # the probe search's window: >= 10 revolutions at 10-20 kHz, enough to place the reversals


TIED_SUBSETS = 12  # at most this many equivalent parameter subsets tried by their one-step fits


PROFILE_STEPS = 2  # Gauss-Newton steps of the fitted parameters at the candidate's one-step value


BLIND_DIRECTION = 0.05  # a first-order column below this fraction of its pair's largest: blind


SPEED_COLUMN_ALPHA = LR_ALPHA / MAX_EFFECTS  # a speed hypothesis against a measured speed column


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


REFIT_STARTS = 8  # polar starts of a geometric refit, besides its one-step start


REFIT_SCOUT_STEPS = 4  # Gauss-Newton steps from each start before the best is fitted to convergence


REFIT_RADIUS = 2e-4  # their least radius, of the housing's larger semi-axis (~5 um on a 22 mm housing)


# the radii of the polar starts, of that radius: the one-step estimate's size is itself read off a
# staircase (F13/F14), so the starts also sample half of it (finding 4, eccentric5's 10 um k=2
# oval: every start at the one-step radius, 12 um, stops at 1.49-2.7 sigma, the named oval 5.5 um
# then an eccentricity; one at half of it reaches 1.24 sigma and the oval is named alone)
REFIT_RADII = (0.5, 1.0)
