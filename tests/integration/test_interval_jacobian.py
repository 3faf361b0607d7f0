"""F13/F14: a geometric defect (out-of-round, eccentricity) acts on the sampled torque partly
through the instants of Coulomb friction reversals between the samples, so the point-sampled cost
is a staircase in its parameters. The exact pointwise Jacobian sees only the smooth part and a
Gauss-Newton fit stalls on the stairs; the columns from the sample-interval average of the model
(identify(..., interval=True)) carry the reversals' motion and the fit reaches the truth's valley."""
import dataclasses
import math

import numpy as np
import pytest

import pumpsim
from bench.diagnose_grid import make_case, rig
from pumpsim.data import Dataset
from pumpsim.diagnosis.effects import with_harmonic_pair
from pumpsim.identification import identify, make_problem, problem
from tests.tolerances import INTERVAL_COS_GAIN, INTERVAL_SMOOTH_REL, INTERVAL_VALLEY_RMS

AMPLITUDE, PHASE, K = 1.5e-5, 0.3, 2  # a 15 um oval on the 3-vane tilted-slot ellipse


def _oval_record():
    nominal = dataclasses.replace(rig("tilted3"), angle=0.4)
    truth = nominal.with_harmonics(nominal.harmonics + [[K, AMPLITUDE, PHASE]])
    sim = pumpsim.simulate(truth, duration=0.1, rate=10000.0)
    ref = pumpsim.simulate(nominal, duration=0.1, rate=10000.0)
    cfg = with_harmonic_pair(nominal, K)
    j = len(nominal.harmonics)
    names = [f"housing.harmonics.{j}.amplitude", f"housing.harmonics.{j + 1}.amplitude"]
    effect = float(np.sqrt(np.mean((sim.torque - ref.torque) ** 2)))
    ab = (AMPLITUDE * math.cos(K * PHASE), AMPLITUDE * math.sin(K * PHASE))
    return cfg, Dataset(sim.time, sim.torque, speed=np.full(sim.time.size, nominal.speed)), names, ab, effect


@pytest.fixture(scope="module")
def oval():
    return _oval_record()


def _cos(a, b):
    return (a * b).sum(axis=0) / (np.linalg.norm(a, axis=0) * np.linalg.norm(b, axis=0))


def test_interval_columns_follow_the_reversals_the_exact_ones_miss(oval):
    """Model and non-geometric columns unchanged; the geometric columns point closer to the
    derivative of the interval average resolved 8x finer than the exact pointwise columns do, much
    closer where the reversals' motion dominates (the exact column sees the smooth part only,
    nearly orthogonal to it)."""
    cfg, ds, names, ab, _ = oval
    init = {"theta0": 0.4, names[0]: ab[0] + 3e-6, names[1]: ab[1] - 2e-6}
    exact = make_problem(cfg, ds, ["mu", "theta0"] + names, initial=init)
    prob = make_problem(cfg, ds, ["mu", "theta0"] + names, initial=init, interval=True)
    m0, J0 = exact.model_and_jacobian(exact.x0)
    m1, J1 = prob.model_and_jacobian(prob.x0)
    assert np.array_equal(m0, m1) and np.array_equal(J0[:, :2], J1[:, :2])
    saved = problem.INTERVAL_SUBPOINTS
    try:
        problem.INTERVAL_SUBPOINTS = 8 * saved
        fine = prob.model_and_jacobian(prob.x0)[1][:, 2:]
    finally:
        problem.INTERVAL_SUBPOINTS = saved
    gain = _cos(J1[:, 2:], fine) - _cos(J0[:, 2:], fine)
    assert np.all(gain >= 0) and np.max(gain) > INTERVAL_COS_GAIN  # the b column: reversals dominate


def test_gauss_newton_on_interval_columns_reaches_the_oval_where_the_exact_jacobian_stalls():
    """The reduced grid's tilted3 record with a 15 um oval at SNR 5, no speed column (mu, theta0
    and the speed fitted with the oval), starts 2 um off the truth: with the interval columns (and
    the exact polish) the fit reaches the truth's valley -- it leaves the noise, 1.008 sigma there --
    while the exact pointwise Jacobian stalls on the staircase at 1.5-2.4 sigma."""
    nominal, ds, info = make_case("tilted3", "housing_out_of_round", 5, 0, False)
    base = identify(nominal, ds, ["mu", "theta0", "speed"])
    cfg = with_harmonic_pair(nominal, K)
    j = len(nominal.harmonics)
    names = [f"housing.harmonics.{j}.amplitude", f"housing.harmonics.{j + 1}.amplitude"]
    params = ["mu", "theta0", "speed"] + names
    for b in (0.3, 0.3 + math.pi / 2):
        init = {**{n: base.estimates[n].value for n in params[:3]},
                names[0]: AMPLITUDE * math.cos(K * PHASE) + 2e-6 * math.cos(b),
                names[1]: AMPLITUDE * math.sin(K * PHASE) + 2e-6 * math.sin(b)}
        with_interval = identify(cfg, ds, params, initial=init, multistart=False, interval=True)
        exact = identify(cfg, ds, params, initial=init, multistart=False)
        assert with_interval.rms < INTERVAL_VALLEY_RMS * info["sigma"]
        assert exact.rms > INTERVAL_VALLEY_RMS * info["sigma"]


def test_interval_columns_from_exact_derivatives_match_the_sub_sample_runs_everywhere(oval):
    """The geometric columns take the sub-sample runs only at and next to the friction reversals'
    steps (interval.stepped_samples) and the exact derivatives' interval average elsewhere: against
    the sub-sample runs on every sample they are identical on the stepped samples and within
    INTERVAL_SMOOTH_REL of the column's norm overall (the smooth formula's O(h^4) remainder)."""
    cfg, ds, names, ab, _ = oval
    init = {"theta0": 0.4, names[0]: ab[0] + 3e-6, names[1]: ab[1] - 2e-6}
    prob = make_problem(cfg, ds, ["mu", "theta0"] + names, initial=init, interval=True)
    x = prob.x0
    _, J = prob.model_and_jacobian(x)
    step = problem.INTERVAL_STEP * max(prob.pv.values["housing.a"], prob.pv.values["housing.b"])
    points = [x + sgn * step * np.eye(x.size)[j] for j in (2, 3) for sgn in (1, -1)]
    avg = prob._interval_averages(points, np.arange(ds.n))
    for k, j in enumerate((2, 3)):
        every = (avg[2 * k] - avg[2 * k + 1]) / (2 * step)
        same = J[:, j] == every  # the stepped samples (sub-sample runs, the same bits)
        assert same.any() and not same.all()
        assert np.linalg.norm(J[:, j] - every) < INTERVAL_SMOOTH_REL * np.linalg.norm(every)


def test_the_exact_polish_starts_from_the_interval_fits_own_exact_evaluation(oval, monkeypatch):
    """An interval problem keeps, from its last full evaluation, the model and the Jacobian before
    the interval columns replace the exact ones: bit for bit what a problem without interval
    columns computes there; nothing at another point or after a column subset. The exact polish of
    an interval fit starts from them: the same fit, to the bit, as recomputing them."""
    cfg, ds, names, ab, _ = oval
    params = ["mu", "theta0"] + names
    init = {"theta0": 0.4, names[0]: ab[0] + 3e-6, names[1]: ab[1] - 2e-6}
    exact = make_problem(cfg, ds, params, initial=init)
    prob = make_problem(cfg, ds, params, initial=init, interval=True)
    assert prob.exact_at(prob.x0) is None
    prob.model_and_jacobian(prob.x0)
    kept, fresh = prob.exact_at(prob.x0), exact.model_and_jacobian(exact.x0)
    assert np.array_equal(kept[0], fresh[0]) and np.array_equal(kept[1], fresh[1])
    assert prob.exact_at(prob.x0 + np.eye(prob.x0.size)[2] * 1e-7) is None
    prob.model_and_jacobian(prob.x0 + np.eye(prob.x0.size)[2] * 1e-7, cols=[2])
    assert np.array_equal(prob.exact_at(prob.x0)[1], fresh[1])
    reused = identify(cfg, ds, params, initial=init, multistart=False, interval=True)
    monkeypatch.setattr(problem.ConstantSpeedProblem, "exact_at", lambda self, x: None)
    recomputed = identify(cfg, ds, params, initial=init, multistart=False, interval=True)
    assert reused.iterations == recomputed.iterations and reused.rms == recomputed.rms
    assert np.array_equal(reused.fitted, recomputed.fitted)
    assert all(reused.estimates[n].value == recomputed.estimates[n].value
               and reused.estimates[n].stderr == recomputed.estimates[n].stderr for n in params)
    assert reused.n_evaluations < recomputed.n_evaluations  # the polish's start not evaluated again
