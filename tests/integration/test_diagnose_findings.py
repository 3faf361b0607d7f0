"""Issue 11's findings, each reproduced with our simulator (nominal config handed over, effect
hidden, white noise, time,torque files unless stated): the verdict is right and never
contradictory, speed stays a nominal, no estimate is reported with a standard error above itself."""
import dataclasses
import importlib
import math

import numpy as np
import pytest

import pumpsim
from bench.diagnose_grid import rig
from pumpsim.data import Dataset
from pumpsim.diagnosis import diagnose
from pumpsim.sensor import measured_torque
from tests.tolerances import EFFECT_PARAM_REL, KURTOSIS_SITUATION_P, SENSOR_TRUTH_SUBSTEPS

def _with(cfg, **values):
    return dataclasses.replace(cfg, values={**cfg.values, **values})


def _measure(nominal, truth, snr=5.0, seed=0, duration=0.1, rate=10000.0, speed_column=False, extra=None,
             sigma=None):
    ref = pumpsim.simulate(dataclasses.replace(nominal, angle=truth.angle, speed=truth.speed),
                           duration=duration, rate=rate)
    sim = pumpsim.simulate(truth, duration=duration, rate=rate)
    y = sim.torque
    if sigma is None:
        sigma = math.sqrt(np.mean((y - ref.torque) ** 2)) / snr
    if extra is not None:
        y = y + extra(sim.time, sigma)
    y = y + np.random.default_rng(seed).normal(0, sigma, y.size)
    speed = np.full(y.size, truth.speed) if speed_column else None
    return Dataset(sim.time, y, speed=speed), sigma


def _never_contradictory(out):
    """Exactly one of: consistent with noise; named + unexplained remainder; nothing named +
    unexplained. And no reported value with a standard error larger than itself."""
    assert out["final"]["residual_white"] == (not out["unexplained"])
    if not out["effects"] and not out["final"]["residual_white"]:
        assert out["unexplained"]
    for p in list(out["final"]["params"].values()) + list(out["baseline"]["params"].values()):
        if isinstance(p, dict) and p.get("value") is not None and p.get("stderr") is not None \
                and not isinstance(p["value"], list):
            assert p["stderr"] <= max(abs(p["value"]), 1.0) or p is None


@pytest.mark.parametrize("speed_column", [False, True])
def test_concentric_rig_off_centre_without_and_with_a_speed_column(speed_column):
    """Finding 1: concentric 4-vane rig, housing centre 0.15 mm off, 1.003 x nominal speed without a
    speed column. On the nominal (concentric) model the torque is mu omega^2 only: speed stays in
    its band, the eccentricity is named, mu right."""
    nominal = rig("concentric4")
    truth = _with(dataclasses.replace(nominal, angle=0.3, speed=nominal.speed * (1.0 if speed_column else 1.003)),
                  **{"housing.center.0": 1.5e-4 * math.cos(0.4), "housing.center.1": 1.5e-4 * math.sin(0.4)})
    ds, _ = _measure(nominal, truth, speed_column=speed_column)
    out = diagnose(nominal, ds)
    _never_contradictory(out)
    assert out["effects"][:1] == ["rotor_eccentricity"], str(out)
    assert abs(out["final"]["params"]["mu"]["value"] / 0.2 - 1) < 0.01
    for m in out["speed"]["measurements"]:
        assert abs(m["value"] / nominal.speed - 1) <= nominal.speed_tolerance + 1e-12


@pytest.mark.parametrize("lines", ["hum", "two_lines"])
def test_concentric_rig_with_non_shaft_lines_is_unexplained_not_a_ripple(lines):
    """Finding 2: an additive 37.3 Hz hum (or 50 Hz and 1.5 shaft orders) on the concentric rig:
    no spectral peak becomes the speed, nothing is named, mu stays right, unexplained at the line."""
    nominal = rig("concentric4")
    truth = dataclasses.replace(nominal, angle=0.3)
    shaft = nominal.speed / (2 * math.pi)
    freqs = [37.3] if lines == "hum" else [50.0, 1.5 * shaft]
    mean = 0.0142  # N m, the rig's torque at mu 0.2
    hum = lambda t, s: sum(3 * s * math.sqrt(2) * np.sin(2 * math.pi * f * t + 0.3) for f in freqs)  # noqa: E731
    ds, _ = _measure(nominal, truth, extra=hum, sigma=0.005 * mean)
    out = diagnose(nominal, ds)
    _never_contradictory(out)
    assert out["effects"] == [] and out["unexplained"], str(out)
    assert abs(out["final"]["params"]["mu"]["value"] / 0.2 - 1) < 0.01
    assert abs(out["speed"]["measurements"][0]["value"] / nominal.speed - 1) <= 0.02
    orders = [w["order"] for w in out["unexplained_where"] if "order" in w]
    assert any(abs(o - freqs[0] / shaft) < 0.05 for o in orders), orders


def test_off_axis_eccentricity_on_a_four_vane_ellipse_is_detected_and_named():
    """Finding 3: housing centre 0.12 mm off along 45 deg on the 4-vane ellipse. The residual is a
    train of narrow pulses where the slot-friction reversals moved (white to runs/Ljung-Box); the
    synchronous F-test sees it and the probes name it."""
    nominal = rig("ellipse4")
    c = 1.2e-4 / math.sqrt(2)
    truth = _with(dataclasses.replace(nominal, angle=0.4), **{"housing.center.0": c, "housing.center.1": c})
    ds, _ = _measure(nominal, truth)
    out = diagnose(nominal, ds)
    _never_contradictory(out)
    assert out["effects"][:1] == ["rotor_eccentricity"], str(out)


@pytest.mark.slow  # ~10-20 s under load: `make test-all` runs it
def test_oval_on_an_eccentric_five_vane_circle_is_named_alone():
    """Finding 4: 5 vanes on a circle eccentric by design (1 mm), a 10 um oval (k = 2): the oval
    is named, nothing else, no unexplained remainder."""
    nominal = rig("eccentric5")
    truth = dataclasses.replace(nominal, angle=0.4).with_harmonics([[2, 1.0e-5, 0.3]])
    ds, _ = _measure(nominal, truth)
    out = diagnose(nominal, ds)
    _never_contradictory(out)
    assert out["effects"] == ["housing_out_of_round"] and not out["unexplained"], str(out)
    assert out["steps"][0]["params"]["order"] == 2


@pytest.mark.slow  # ~60 s of make test's wall on 2 cores
def test_tip_and_slot_spread_is_one_effect_with_per_vane_cofs():
    """Finding 6: one vane's COF 30 % higher on its tip and its slot walls (3-vane ellipse: every
    factor identifiable). vane_friction_spread alone explains it; each vane's COF is reported and
    mu is their mean."""
    nominal = rig("ellipse3")
    truth = _with(dataclasses.replace(nominal, angle=0.4), **{"effects.vane_friction_factor.1": 1.3})
    ds, _ = _measure(nominal, truth)
    out = diagnose(nominal, ds)
    _never_contradictory(out)
    assert out["effects"] == ["vane_friction_spread"] and not out["unexplained"], str(out)
    cof = [v["value"] for v in out["final"]["vane_mu"]]
    assert np.allclose(cof, [0.17, 0.17 * 1.3, 0.17], rtol=0.02), cof
    assert abs(out["final"]["params"]["mu"]["value"] - np.mean(cof)) < 1e-12


def test_four_vane_ellipse_spread_leaves_no_false_ripple():
    """Finding 6 on the 4-vane ellipse (vanes i and i+2 see the same housing): still one effect."""
    nominal = rig("ellipse4")
    truth = _with(dataclasses.replace(nominal, angle=0.4), **{"effects.vane_friction_factor.1": 1.3})
    ds, _ = _measure(nominal, truth)
    out = diagnose(nominal, ds)
    _never_contradictory(out)
    assert out["effects"] == ["vane_friction_spread"] and not out["unexplained"], str(out)


@pytest.mark.parametrize("vane", [0, 2, 3])
def test_four_vane_ellipse_spread_on_any_vane_is_fitted_on_its_own_pair(vane):
    """On the 4-vane ellipse every vane factor has one first-order direction once mu is fitted
    (vanes i and i+2 see the same housing; the pair {0, 2} against {1, 3}): which factor the
    score test moves was the pivoted QR's rounding (F: a SIMD-vs-CasADi flip named factor.2 0.65
    and a false ripple). Each tied choice is tried by its one-step fit: a rough vane 0 or 2 comes
    out as its pair's COF raised, a rough vane 3 as its pair's, never the other pair lowered."""
    nominal = rig("ellipse4")
    factor = {f"effects.vane_friction_factor.{vane}": 1.3} if vane else \
        {f"effects.vane_friction_factor.{i}": 1 / 1.3 for i in (1, 2, 3)}
    truth = _with(dataclasses.replace(nominal, angle=0.4), **factor)
    ds, _ = _measure(nominal, truth, seed=vane)
    out = diagnose(nominal, ds)
    _never_contradictory(out)
    assert out["effects"] == ["vane_friction_spread"] and not out["unexplained"], str(out)
    cof = np.array([v["value"] for v in out["final"]["vane_mu"]])
    rough = (0, 2) if vane in (0, 2) else (1, 3)
    ratio = cof[list(rough)].sum() / np.delete(cof, list(rough)).sum()
    assert ratio == pytest.approx((1.3 + 1) / 2, rel=0.02), cof


@pytest.mark.slow
def test_long_no_effect_record_is_consistent_with_noise():
    """Finding 5: 4-vane ellipse, no effect, 2 s at 20 kHz (40,000 samples), no speed column:
    nothing named and no false unexplained (its wall time is in make bench-diagnose)."""
    nominal = rig("ellipse4")
    truth = dataclasses.replace(nominal, angle=0.4)
    ref = pumpsim.simulate(truth, duration=2.0, rate=20000.0)
    sigma = 0.02 * float(np.std(ref.torque))
    y = ref.torque + np.random.default_rng(3).normal(0, sigma, ref.time.size)
    out = diagnose(nominal, Dataset(ref.time, y))
    _never_contradictory(out)
    assert out["effects"] == [] and not out["unexplained"], str(out)


@pytest.mark.slow  # ~60 s of make test's wall on 2 cores
def test_lowpass_sensor_of_a_vane_passing_period_is_named_alone():
    """Independent finding F6: a first-order low-pass torque sensor with T = 0.25 / (N omega)
    (1.7 samples at 10 kHz on the 3-vane ellipse) attenuates and shifts every vane-passing order;
    it was explained by viscous friction + speed ripple + out-of-round. The sensor filters the
    continuous torque (made here on a grid SENSOR_TRUTH_SUBSTEPS times finer than the samples):
    the lag alone is named, sized, and nothing remains."""
    nominal = rig("ellipse3")
    truth = dataclasses.replace(nominal, angle=0.4)
    T = 0.25 / (nominal.vanes * nominal.speed)
    m = SENSOR_TRUTH_SUBSTEPS
    fine = pumpsim.simulate(truth, duration=0.1, rate=10000.0 * m)
    ref = pumpsim.simulate(truth, duration=0.1, rate=10000.0)
    y = measured_torque(fine.time, fine.torque, lag=T, every=m)[:ref.time.size]
    sigma = math.sqrt(np.mean((y - ref.torque) ** 2)) / 5.0
    ds = Dataset(ref.time, y + np.random.default_rng(5).normal(0, sigma, y.size))
    out = diagnose(nominal, ds)
    _never_contradictory(out)
    assert out["effects"] == ["sensor_lag"] and not out["unexplained"], str(out)
    assert abs(out["final"]["params"]["lag"]["value"] / T - 1) < EFFECT_PARAM_REL


def test_no_heavy_tail_note_on_gaussian_noise():
    """Independent finding F8: on a no-effect record with exactly Gaussian noise (3-vane ellipse,
    sigma = 20 % of the torque's ripple, 5000 samples) the fitted phase moves a friction reversal
    by part of a sample and leaves one outlier (on all samples the kurtosis test rejects, p ~ 1e-25;
    tests/integration/test_reversal_cost.py). Diagnose tests the samples off the final model's
    reversals: no rejection there, no 'heavy-tailed residual' note, nothing named, not unexplained."""
    nominal = rig("ellipse3")
    ref = pumpsim.simulate(dataclasses.replace(nominal, angle=0.4), duration=0.5, rate=10000.0)
    sigma = 0.2 * float(np.std(ref.torque))
    y = ref.torque + np.random.default_rng(1).normal(0, sigma, ref.time.size)
    out = diagnose(nominal, Dataset(ref.time, y))
    _never_contradictory(out)
    assert out["effects"] == [] and not out["unexplained"], str(out)
    assert out["detectors"]["per_measurement"][0]["kurtosis"]["p_value"] >= KURTOSIS_SITUATION_P
    assert not [n for n in out["notes"] if "heavy-tailed" in n], out["notes"]


@pytest.mark.slow  # ~40-55 s: make test-all
def test_eccentricity_on_a_one_vane_ellipse_off_its_axes_is_named_alone():
    """Independent finding F3: a 95 um eccentricity at 298 deg on the 1-vane ellipse. At zero
    eccentricity the first-order sensitivity to the y shift vanishes (the centred ellipse is
    symmetric about its x axis), so the linear step moved x only, a speed ripple of order 1 came
    first and an out-of-round or the ripple stayed beside the eccentricity. With finite probes
    wherever a direction is first-order blind: the eccentricity alone, sized."""
    nominal = rig("ellipse1")
    e, beta = 9.5e-5, 5.2
    truth = _with(dataclasses.replace(nominal, angle=3.807),
                  **{"housing.center.0": e * math.cos(beta), "housing.center.1": e * math.sin(beta)})
    ds, _ = _measure(nominal, truth, duration=0.4, rate=12500.0, speed_column=True)
    out = diagnose(nominal, ds)
    _never_contradictory(out)
    assert out["effects"] == ["rotor_eccentricity"] and not out["unexplained"], str(out)
    ex, ey = (out["final"]["params"][f"housing.center.{i}"]["value"] for i in (0, 1))
    # the mirror eccentricity gives the same torque: compare up to sign
    assert min(math.hypot(ex - truth.values["housing.center.0"], ey - truth.values["housing.center.1"]),
               math.hypot(ex + truth.values["housing.center.0"], ey + truth.values["housing.center.1"])) \
        < EFFECT_PARAM_REL * e


@pytest.mark.slow  # ~60 s of make test's wall on 2 cores
def test_an_effect_a_later_one_supersedes_is_dropped(monkeypatch):
    """Independent finding F11: forward selection is greedy -- on the 1-vane ellipse with an
    eccentricity a speed ripple of order 1 was named first and kept, though once the eccentricity
    was in its part of the torque collapsed to a few % of its first size. That greedy path is
    forced here (the eccentricity is hidden from the first screen, so another effect stands in
    for it) and the backward check must drop the stand-in, with a note, and keep the
    eccentricity alone."""
    dg = importlib.import_module("pumpsim.diagnosis.workflow")  # where the search step calls the score test
    nominal = rig("ellipse1")
    e, beta = 9.5e-5, 5.2
    truth = _with(dataclasses.replace(nominal, angle=3.807),
                  **{"housing.center.0": e * math.cos(beta), "housing.center.1": e * math.sin(beta)})
    ds, _ = _measure(nominal, truth, duration=0.2, rate=12500.0, speed_column=True)
    # a noisy encoder column (1 %): it cannot refute the stand-in's 0.01 % ripple, which an exact
    # column would (that rejection is tested in test_diagnose_speed_column.py)
    ds = Dataset(ds.time, ds.torque, speed=ds.speed * (1 + 1e-2 * np.random.default_rng(3).standard_normal(ds.n)))
    score = dg.score_test

    def hidden_at_first(state, cand, start=True, **kw):
        out = score(state, cand, start, **kw)
        if start and cand.effect == "rotor_eccentricity" and len(state.names) <= 2:  # mu, theta0
            out = dataclasses.replace(out, one_step_rss=1e9, p_value=1.0, searched=False, second_order=False)
        return out

    monkeypatch.setattr(dg, "score_test", hidden_at_first)
    out = diagnose(nominal, ds, max_effects=2)  # the stand-in, then the eccentricity
    _never_contradictory(out)
    assert out["effects"] == ["rotor_eccentricity"] and not out["unexplained"], str(out)
    assert any(" dropped once rotor_eccentricity was added" in n for n in out["notes"]), out["notes"]
    assert len(out["steps"]) == 1


@pytest.mark.slow  # ~60-70 s per SNR on 2 cores
@pytest.mark.parametrize("snr", [5.0, 10.0])
def test_pulse_train_at_a_non_shaft_frequency_names_no_pump_effect(snr):
    """F16: a 3-sample pulse every 1/1.37 revolution over 10 revolutions has a non-zero
    shaft-synchronous average, which a rotor eccentricity lowers the RSS by (LR passes); its
    parameters fitted on segments of the record disagree -- not a pump effect: unexplained."""
    from bench.diagnose_grid import make_case

    nominal, data, _ = make_case("eccentric5", "non_shaft_impulses", snr, 0, True)
    out = diagnose(nominal, data)
    _never_contradictory(out)
    assert out["effects"] == [] and out["unexplained"]
    assert any("not stationary" in n for n in out["notes"])


def test_named_size_measured_against_the_noise_under_the_candidate():
    """The named-size yardstick (a quarter of the noise's scatter) is the scatter of the candidate
    fit's residual: the current residual still holds the effect's remainder, which inflated it
    (the reduced grid's eccentric5 eccentricity at SNR 10 without a speed column: 1.77e-4 N m
    against the noise's 1.71e-4, the true eccentricity's 4.42e-5 N m refused as too small)."""
    from bench.diagnose_grid import make_case

    nominal, data, _ = make_case("eccentric5", "rotor_eccentricity", 10.0, 0, False)
    out = diagnose(nominal, data)
    _never_contradictory(out)
    assert out["effects"] == ["rotor_eccentricity"], str(out["effects"]) + str(out["notes"])


@pytest.mark.slow  # ~55-70 s on 2 cores: make test-all (make test was 9 min 50 s quiet)
def test_smooth_rivals_compared_at_their_optima():
    """A smooth contender's fit is also started from the phase-and-speed scan (its cost is a
    staircase in theta0 and speed, and a fit from the one-step start stays on its step): the reduced
    grid's tilted3 torque offset at SNR 10 without a speed column was refitted to 1.028 sigma (its
    optimum 1.020), and the viscous tip friction (1.023) was named instead of reporting the pair
    that one speed cannot separate."""
    from bench.diagnose_grid import make_case

    nominal, data, _ = make_case("tilted3", "torque_offset", 10.0, 0, False)
    out = diagnose(nominal, data)
    _never_contradictory(out)
    assert out["effects"] in ([], ["torque_offset"]), out["effects"]
    if not out["effects"]:
        assert any(sorted(p) == ["torque_offset", "viscous_tip_friction"] for p in out["confounded"]), out["confounded"]
