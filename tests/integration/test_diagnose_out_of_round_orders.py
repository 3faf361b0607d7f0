"""Out-of-round orders the vane count hides or mixes (review findings on `pumpsim diagnose`, s11-C):
an order-3 lobing on a concentric 4-vane rig is absorbed by the baseline (with N identical vanes
the torque repeats every 2 pi / N: only orders that are multiples of N survive the sum, and order 3
reaches them through nonlinear terms only), and an order-6 lobing on the eccentric 5-vane rig must
be named as itself, not as another order plus whatever mops up the rest."""
import dataclasses

import numpy as np
import pytest

import pumpsim
from bench.diagnose_grid import rig
from pumpsim.data import Dataset
from pumpsim.diagnosis import diagnose
from pumpsim.identification import identify

NOISE = 0.02  # of the nominal torque's standard deviation (a quarter of its mean where it is constant)


def _record(family, order, amplitude, phase, seed=0, slip=1.003):
    """The rig with an out-of-round [order, amplitude, phase] added, run 0.3 % fast (no speed
    column), 0.1 s at 10 kHz; white noise NOISE x the nominal torque's spread. Returns (nominal,
    clean record, noisy record, sigma)."""
    nominal = dataclasses.replace(rig(family), angle=0.0)
    angle = 0.4 + 0.37 * seed
    truth = dataclasses.replace(nominal.with_harmonics(nominal.harmonics + [[order, amplitude, phase]]),
                                speed=nominal.speed * slip, angle=angle)
    ref = pumpsim.simulate(dataclasses.replace(nominal, speed=nominal.speed * slip, angle=angle), duration=0.1,
                           rate=10000.0)
    sim = pumpsim.simulate(truth, duration=0.1, rate=10000.0)
    sd = float(np.std(ref.torque))
    sigma = NOISE * (sd if sd > 1e-3 * abs(np.mean(ref.torque)) else 0.25 * abs(float(np.mean(ref.torque))))
    y = sim.torque + np.random.default_rng(seed).normal(0, sigma, sim.torque.size)
    return nominal, Dataset(sim.time, sim.torque), Dataset(sim.time, y), sigma


def test_trilobe_on_a_concentric_four_vane_rig_is_absorbed_and_nothing_is_named():
    """60 um of order 3 changes the concentric 4-vane rig's torque by ~0.8 sigma, and the baseline
    (mu, theta0, speed) absorbs all but ~0.19 sigma of it (a change of mean torque: mu) -- below
    the quarter sigma a named effect must explain. Consistent with noise is the right answer, and
    the notes say why (the vane count's multiples)."""
    nominal, clean, noisy, sigma = _record("concentric4", 3, 6e-5, 0.3)
    absorbed = identify(nominal, clean, ["mu", "theta0", "speed"], multistart=True, speed_in_band=True,
                        adequacy=False)
    assert absorbed.rms < 0.25 * sigma
    out = diagnose(nominal, noisy)
    assert out["effects"] == [] and not out["unexplained"], out["verdict"]
    assert any("multiples of 4 shaft orders" in n for n in out["notes"]), out["notes"]


@pytest.mark.slow  # ~10 s under load
@pytest.mark.xfail(strict=True, reason="every significant out-of-round order is refitted from its one-step "
                   "start (refit.contender_fits), 4/4 right on this rig's other draws; this draw names order 4 + "
                   "an eccentricity + a speed ripple: it needs order 6's polar search too (2x the grid's CPU)")
def test_order_six_lobing_on_the_eccentric_five_vane_rig_is_named_as_order_six():
    """10 um of order 6 (~17 sigma of torque change): the screen finds orders 4 and 6 significant,
    the one-step fits rank 4 (13.9 sigma left) ahead of 6 (15.3), and only the lowest significant
    order is refitted from polar starts -- order 4 refits to 1.65 sigma and an eccentricity is
    named for the rest. Order 6 refitted from its one-step start alone reaches the noise (0.99)."""
    nominal, _, noisy, sigma = _record("eccentric5", 6, 1e-5, 1.0)
    out = diagnose(nominal, noisy)
    assert out["effects"] == ["housing_out_of_round"], out["effects"]
    assert out["steps"][0]["params"]["order"] == 6
    assert out["final"]["rms"] < 1.2 * sigma
