"""Finding F14: with Coulomb reversals between samples the all-samples least-squares cost is a
staircase in theta0 (and in every parameter that moves a reversal); the reversal-aware cost (the
samples bracketing the model's steps dropped, the mask recomputed at every point, two points
compared on their common samples) is smooth."""
import dataclasses
import math

import numpy as np

import pumpsim
from bench.diagnose_grid import rig
from pumpsim.data import Dataset
from pumpsim.signals import kurtosis_test
from pumpsim.identification import identify, make_problem
from tests.tolerances import KURTOSIS_SITUATION_P, PROFILE_SMOOTH_CHI2


def _record(sigma_share=0.02, seed=1):
    truth = dataclasses.replace(rig("ellipse4"), angle=0.4)
    sim = pumpsim.simulate(truth, duration=0.5, rate=10000.0)
    sigma = sigma_share * float(np.std(sim.torque))
    return truth, Dataset(sim.time, sim.torque + np.random.default_rng(seed).normal(0, sigma, sim.time.size))


def _profile_steps(prob, thetas):
    """n ln(RSS ratio) between neighbouring theta0 values, mu refitted linearly, on the samples
    both points keep."""
    pts = []
    for th in thetas:
        x = np.array([prob.x0[0], th])
        m, J = prob.model_and_jacobian(x)
        keep = prob.keep_at(x)
        pts.append((prob.y - m, J[:, :1], np.ones(m.size, bool) if keep is None else keep))
    out = []
    for (r1, J1, k1), (r2, _, k2) in zip(pts[:-1], pts[1:]):
        k = k1 & k2

        def rss(r):
            d = np.linalg.lstsq(J1[k], r[k], rcond=None)[0]
            e = r[k] - J1[k] @ d
            return float(e @ e)
        out.append(k.sum() * math.log(rss(r2) / rss(r1)))
    return np.array(out)


def test_theta0_profile_is_a_staircase_on_all_samples_and_smooth_on_the_reversal_aware_cost():
    truth, ds = _record()
    thetas = truth.angle + np.linspace(-2e-3, 2e-3, 21)
    steps_all = _profile_steps(make_problem(truth, ds, ["mu", "theta0"]), thetas)
    steps_rev = _profile_steps(make_problem(truth, ds, ["mu", "theta0"], reversals=0.0), thetas)
    # a smooth cost: the neighbour steps change linearly (a parabola); a staircase: they jump
    assert np.max(np.abs(np.diff(steps_all, 2))) > 100 * PROFILE_SMOOTH_CHI2
    assert np.max(np.abs(np.diff(steps_rev, 2))) < PROFILE_SMOOTH_CHI2


def test_reversal_aware_fit_keeps_most_samples_and_reports_its_mask():
    """identify(reversals=0): the mask drops only samples next to steps (a few per vane passage),
    rms is over the kept samples and matches the noise."""
    truth, ds = _record(seed=2)
    res = identify(truth, ds, ["mu", "theta0"], reversals=0.0, multistart=False)
    sigma = 0.02 * float(np.std(ds.torque))
    assert res.keep is not None and 0.5 < res.keep.mean() < 1.0
    assert abs(res.rms / sigma - 1) < 0.1


def test_kurtosis_on_the_samples_off_the_reversals_of_a_gaussian_record_holds_its_null():
    """Independent finding F8: the fitted phase, within its standard error, moves a few Coulomb
    steps across a sample; each leaves one residual sample of the step's height and the kurtosis
    test on all samples rejects on exactly Gaussian noise. On the samples the reversal-aware cost
    keeps at the fit (those next to a model step dropped) it does not."""
    nominal = rig("ellipse3")
    ref = pumpsim.simulate(dataclasses.replace(nominal, angle=0.4), duration=0.5, rate=10000.0)
    y = ref.torque + np.random.default_rng(1).normal(0, 0.2 * float(np.std(ref.torque)), ref.time.size)
    ds = Dataset(ref.time, y)
    res = identify(nominal, ds, ["mu", "theta0"])
    fit = {n: e.value for n, e in res.estimates.items()}
    keep = make_problem(nominal, ds, ["mu", "theta0"], initial=fit, reversals=0.0).keep_at([fit["mu"], fit["theta0"]])
    assert kurtosis_test(res.residual)["p_value"] < KURTOSIS_SITUATION_P  # the situation
    assert kurtosis_test(res.residual[keep])["p_value"] > KURTOSIS_SITUATION_P
