"""The fits' shortcuts where the general formula would only add zeros or build a list: the numeric
parameter map, the angle without a speed ripple and the drive tangents without a fitted ripple
give the general path's numbers bit for bit (a diagnosis's polar fits amplify any rounding change
into a different valley, so "close" would not do)."""
import casadi as ca
import numpy as np

from pumpsim.config import load_config
from pumpsim.data import Dataset
from pumpsim.identification import make_problem
from pumpsim.identification.problem import parameter_map
from pumpsim.identification.sampled import drive_tangents
from pumpsim.motion import ripple_motion
from tests.conftest import ROOT


def _problem(names, initial=None):
    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml").with_harmonics([[4, 1e-5, 0.3]])
    t = np.arange(2001) / 20000.0
    return make_problem(cfg, Dataset(t, np.zeros(t.size)), names, initial=initial)


def test_the_numeric_parameter_map_is_the_expression_path_bit_for_bit():
    prob = _problem(["mu", "theta0", "housing.harmonics.0.amplitude", "rotor.radius"])
    val = {"mu": 0.1234567, "housing.harmonics.0.amplitude": 1.7e-5, "rotor.radius": 0.0187654,
           "theta0": 0.3}
    fast = parameter_map(prob._index, prob.p0, val, prob.fixed["mu_slot"], prob._ratios, prob._follow)
    general = parameter_map(prob._index, ca.DM(prob.p0), val, prob.fixed["mu_slot"], prob._ratios,
                            prob._follow)
    assert isinstance(fast, np.ndarray) and fast.shape == (prob.p0.size, 1)
    np.testing.assert_array_equal(fast, np.asarray(general, dtype=float))
    assert not np.array_equal(fast.ravel(), prob.p0)  # the values went in


def test_the_angle_without_ripple_is_the_ripple_formula_at_zero_bit_for_bit():
    prob = _problem(["mu", "theta0", "speed"], initial={"theta0": 0.77})
    x = prob.x0
    theta, J = prob.angle_and_jacobian(x)
    d = prob._values(x)
    thn = d["theta0"] + d["speed"] * (prob.tau - d["delay"])
    ref, g, _ = ripple_motion(thn, d["theta0"], 1.0, 0.0, 0.0, prob.ripple_order)
    np.testing.assert_array_equal(theta, ref)
    np.testing.assert_array_equal(J[:, 1], g - 0.0 * np.cos(0.77) + 0.0 * np.sin(0.77))
    np.testing.assert_array_equal(J[:, 2], (prob.tau - d["delay"]) * g)


def test_drive_tangents_without_a_fitted_ripple_are_the_general_columns_bit_for_bit():
    n, rng = 500, np.random.default_rng(1)
    tau, g, gd = np.arange(n) / 1e4, 1 + 0.01 * rng.random(n), 0.1 * rng.standard_normal(n)
    zs = (0.4, 150.0, 1e-5, 0.0, 0.0, 0.0)
    seeds = np.zeros((6, 3))
    seeds[0, 0] = seeds[1, 1] = seeds[2, 2] = 1.0  # theta0, speed, delay: no ripple seed
    with_ripple = np.column_stack([seeds, np.eye(6)[:, 4]])  # a ripple column: the general path
    fast = drive_tangents(tau, zs, 3, g, gd, seeds)
    general = drive_tangents(tau, zs, 3, g, gd, with_ripple)
    for a, b in zip(fast, general):
        assert a.shape == (n, 3)
        np.testing.assert_array_equal(a, b[:, :3])


def test_a_fit_without_its_final_jacobian_ends_where_the_full_one_does():
    """identify(final_jacobian=False) (a polar search's quick look): the same values and RMS, bit for
    bit, as the fit that evaluates the Jacobian where its last step lands -- one model_and_jacobian
    call fewer, its estimates without standard errors."""
    from pumpsim.identification import identify
    from pumpsim.simulate import simulate

    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml")
    truth = cfg.with_harmonics([[4, 1.5e-5, 0.3]])
    sim = simulate(truth, duration=0.05, rate=20000.0)
    y = sim.torque + np.random.default_rng(1).normal(0, 0.02 * np.std(sim.torque), sim.time.size)
    data = Dataset(sim.time, y)
    geo = cfg.with_harmonics([[4, 0.0, 0.0]])
    names = ["mu", "theta0", "housing.harmonics.0.amplitude"]
    init = {"mu": 0.17, "theta0": cfg.angle, "housing.harmonics.0.amplitude": 8e-6}
    full = identify(geo, data, names, initial=init, multistart=False, max_iter=1, interval=True, polish=False)
    quick = identify(geo, data, names, initial=init, multistart=False, max_iter=1, interval=True, polish=False,
                     final_jacobian=False)
    assert quick.rms == full.rms and len(quick.iterations) == len(full.iterations) == 2
    assert {n: e.value for n, e in quick.estimates.items()} == {n: e.value for n, e in full.estimates.items()}
    assert all(e.stderr is None for e in quick.estimates.values()) and quick.correlation is None
    assert quick.n_evaluations == full.n_evaluations  # the end's model (remembered from the trial) counted


def test_a_second_fit_from_the_same_start_reuses_its_sub_sample_runs(monkeypatch):
    """The interval columns' sub-sample runs at a point are remembered (runs.DESIGN_RUNS): another
    fit that evaluates them there (a polar search's finalist scouted again, a completed search) runs
    none, and its fit is the same bits as one that runs them again."""
    from pumpsim.identification import identify, problem
    from pumpsim.identification.runs import DESIGN_RUNS, JACOBIAN_RUNS, MODEL_RUNS
    from pumpsim.simulate import simulate

    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml")
    sim = simulate(cfg.with_harmonics([[4, 1.5e-5, 0.3]]), duration=0.05, rate=20000.0)
    data = Dataset(sim.time, sim.torque + np.random.default_rng(1).normal(0, 0.02 * np.std(sim.torque), sim.time.size))
    geo = cfg.with_harmonics([[4, 0.0, 0.0]])
    names = ["mu", "theta0", "housing.harmonics.0.amplitude"]
    init = {"mu": 0.17, "theta0": cfg.angle, "housing.harmonics.0.amplitude": 8e-6}

    def scout():
        return identify(geo, data, names, initial=init, multistart=False, max_iter=2, interval=True, polish=False)
    if problem.ConstantSpeedProblem(geo, data, names)._simd is None:
        return  # no SIMD library: the CasADi map's path runs every sample, nothing remembered
    runs = []
    orig = problem.simd_torque_designs
    monkeypatch.setattr(problem, "simd_torque_designs", lambda *a: runs.append(1) or orig(*a))
    for memo in (DESIGN_RUNS, JACOBIAN_RUNS, MODEL_RUNS):
        memo.entries.clear()
    alone = scout()
    assert len(runs) >= 2  # at its start and after its first step
    runs.clear()
    identify(geo, data, names, initial=init, multistart=False, max_iter=1, interval=True, polish=False,
             final_jacobian=False)  # the quick look
    assert not runs  # the scout before it left them (the same start)
    again = scout()
    assert not runs
    assert again.rms == alone.rms
    assert {n: e.value for n, e in again.estimates.items()} == {n: e.value for n, e in alone.estimates.items()}


def _phase_costs_by_interpolation(t, y, one_rev, w, delay):
    """The phase scan as it interpolated every sample for every phase."""
    from pumpsim.identification.start import _GRID, PHASE_STEPS

    grid, values = np.append(_GRID, 2 * np.pi), np.append(one_rev, one_rev[0])
    yc = y - y.mean()
    out = []
    for th0 in np.linspace(0, 2 * np.pi, PHASE_STEPS, endpoint=False):
        m = np.interp(np.mod(th0 + w * (t - delay), 2 * np.pi), grid, values)
        m -= m.mean()
        scale = (m @ yc) / (m @ m)
        out.append((float(np.sum((scale * m - yc) ** 2)), scale > 0))
    return np.array(out)


def test_the_phase_scan_by_correlation_is_the_interpolated_scan():
    """start._phase_costs (circular correlations of the grid) against interpolating every sample at
    every phase: the costs to 1e-12 of the largest, the same positive-scale phases, and
    _phase_start's choice the same on records with a scale, an offset, noise and a delay; a
    one-revolution model without ripple keeps the initial guess."""
    from pumpsim.identification import start

    rng = np.random.default_rng(5)
    grid = np.append(start._GRID, 2 * np.pi)
    for n in (300, 2001, 7000):
        t = np.arange(n) / 20000.0
        one_rev = 1 + 0.3 * np.cos(3 * start._GRID + 1.0) + 0.1 * (rng.random(start._GRID.size) < 0.03)
        w, delay, th = rng.uniform(150, 400), rng.uniform(-1e-3, 1e-3), rng.uniform(0, 2 * np.pi)
        y = 1.7 * np.interp(np.mod(th + w * (t - delay), 2 * np.pi), grid, np.append(one_rev, one_rev[0]))
        y += 0.4 + rng.normal(0, 0.05, n)
        cost, positive = start._phase_costs(t, y, one_rev, w, delay)
        ref = _phase_costs_by_interpolation(t, y, one_rev, w, delay)
        assert np.max(np.abs(cost - ref[:, 0])) <= 1e-12 * np.max(ref[:, 0])
        assert np.array_equal(positive, ref[:, 1].astype(bool))

        class Prob:
            tau = t
        Prob.y = y
        picked = start._phase_start(Prob, one_rev, w, delay, 0.5)
        valid = ref[:, 1].astype(bool)
        best = np.linspace(0, 2 * np.pi, start.PHASE_STEPS, endpoint=False)[valid][np.argmin(ref[valid, 0])]
        assert picked == best
        assert start._phase_start(Prob, np.full(start._GRID.size, 2.5), w, delay, 0.5) == 0.5


def test_the_diagnose_benchs_counts_are_the_fits_own():
    """bench/diagnose_scale.py --counts: inside `Counts` one fit's SIMD model runs and Jacobians are
    counted with their samples, its Gauss-Newton steps are the fit's history and its rejected trials
    the model calls beyond them; the library's call is restored after."""
    import sys

    sys.path.insert(0, str(ROOT / "bench"))
    import diagnose_scale
    from pumpsim.identification import identify
    from pumpsim.kernels import simd

    run = simd.FastInverseDynamics._run
    base, data = diagnose_scale.record("oval4", 1200)
    with diagnose_scale.Counts() as c:
        res = identify(base, data, ["mu", "theta0"], initial={"mu": 0.12, "theta0": 0.3}, multistart=False)
    got = c.to_json()
    assert simd.FastInverseDynamics._run is run
    steps = len(res.iterations) - 1
    assert got["gauss_newton"]["fits"] == 1 and got["gauss_newton"]["accepted_steps"] == steps > 0
    assert got["kernel"]["jacobian"]["calls"] == steps + 1  # the start's and each step's
    assert got["kernel"]["jacobian"]["samples"] == (steps + 1) * data.n
    assert got["kernel"]["model"]["calls"] >= steps + got["gauss_newton"]["rejected_trials"]
    assert got["kernel"]["casadi map"]["calls"] == 0


def _counting_runs(monkeypatch):
    """Count the SIMD library's calls (model runs and Jacobians)."""
    from pumpsim.kernels import simd
    calls, run = [], simd.FastInverseDynamics._run

    def counted(lib, fns, n, *a, **kw):
        calls.append(n)
        return run(lib, fns, n, *a, **kw)
    monkeypatch.setattr(simd.FastInverseDynamics, "_run", counted)
    return calls


def test_a_run_without_ripple_is_the_same_bits_at_any_ripple_order_and_shared(monkeypatch):
    from pumpsim.identification.runs import MODEL_RUNS
    from pumpsim.identification.sampled import simd_torque
    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml")
    t = np.arange(1500) / 10000.0
    probs = [make_problem(cfg, Dataset(t, np.zeros(t.size)), ["mu", "theta0"], ripple_order=k) for k in (1, 7)]
    fast = probs[0]._simd
    if fast is None:
        return  # no SIMD library on this machine: the CasADi path keeps the order in its key
    x = probs[0].x0
    theta, z, kin = probs[0].angle(x), probs[0].z(x), (probs[0].tau, *probs[0]._rates)
    ref = [simd_torque(fast, theta, z, k, *kin) for k in (1, 7)]
    np.testing.assert_array_equal(ref[0], ref[1])  # what sharing the run relies on
    MODEL_RUNS.entries.clear()
    calls = _counting_runs(monkeypatch)
    got = [p.model(x) for p in probs]
    assert len(calls) == 1
    np.testing.assert_array_equal(got[1], ref[1])
    z1 = np.array(z)
    z1[fast.n_params + 4] = 1e-3  # a ripple: the order matters again
    MODEL_RUNS.entries.clear()
    for p in probs:
        p._torque(theta, z1, kin)
    assert len(calls) == 3


def test_the_ripple_orders_columns_share_one_library_jacobian_and_keep_their_own_tangents(monkeypatch):
    """At zero ripple amplitude the speed-ripple candidates of every order linearise at the same
    kernel inputs (the order enters only through the drive's tangents, chained after the call): one
    library Jacobian serves them all, and each order's columns are those computed alone."""
    from pumpsim.identification.runs import JACOBIAN_RUNS, MODEL_RUNS
    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml")
    t = np.arange(1500) / 10000.0
    names = ["mu", "theta0", "ripple_cos", "ripple_sin"]
    probs = [make_problem(cfg, Dataset(t, np.zeros(t.size)), names, ripple_order=k) for k in (2, 5)]
    if probs[0]._simd is None or not probs[0]._simd.has_jacobian:
        return  # the CasADi map's path: nothing shared
    alone = []
    for p in probs:
        JACOBIAN_RUNS.entries.clear()
        MODEL_RUNS.entries.clear()
        alone.append(p.model_and_jacobian(p.x0))
    assert not np.array_equal(alone[0][1][:, 2:], alone[1][1][:, 2:])  # the orders' columns differ
    JACOBIAN_RUNS.entries.clear()
    MODEL_RUNS.entries.clear()
    jac = []
    from pumpsim.kernels import simd
    orig = simd.FastInverseDynamics.jacobian
    monkeypatch.setattr(simd.FastInverseDynamics, "jacobian", lambda *a, **k: jac.append(1) or orig(*a, **k))
    shared = [p.model_and_jacobian(p.x0) for p in probs]
    assert len(jac) == 1
    for (m0, J0), (m1, J1) in zip(alone, shared):
        np.testing.assert_array_equal(m0, m1)
        np.testing.assert_array_equal(J0, J1)


def test_the_diagnose_benchs_stages_add_up_to_its_counts():
    """bench/diagnose_stages.py: every SIMD call of a diagnosis is charged to one stage and one
    purpose (their totals are `Counts`' totals), the baseline's fit is the baseline's, and the
    workflow's functions are restored after."""
    import sys

    sys.path.insert(0, str(ROOT / "bench"))
    import diagnose_scale
    import diagnose_stages
    from pumpsim.diagnosis import diagnose, workflow

    score_test = workflow.score_test
    base, data = diagnose_scale.record("none", 1200)
    with diagnose_scale.Counts() as c, diagnose_stages.Stages() as st:
        diagnose(base, data, max_effects=1)
    counts, stages = c.to_json()["kernel"], st.to_json()
    assert workflow.score_test is score_test
    total = {k: sum(v.get(k, 0) for v in stages["stages"].values()) for k in ("runs", "jacobians")}
    assert total == {"runs": counts["model"]["calls"], "jacobians": counts["jacobian"]["calls"]}
    assert sum(v["calls"] for v in stages["purposes"].values()) == sum(total.values())
    assert stages["stages"]["workflow._baseline"]["jacobians"] > 0
    last_screen = stages["stages"]["workflow.score_test (conclusion)"]  # a white record: no search
    assert last_screen["jacobians"] > 0 and last_screen["cpu_seconds"] > 0


def test_a_quick_looks_smooth_columns_run_no_sub_samples(monkeypatch):
    """interval=SMOOTH_COLUMNS (a polar search's quick look, which only ranks starts): the geometric
    columns from the smooth formula on every sample, without the sub-sample runs -- the interval
    columns' own bits wherever those take that formula, different only at and next to the friction
    reversals; the model and the other columns the same bits."""
    from pumpsim.identification import SMOOTH_COLUMNS, make_problem, problem
    from pumpsim.identification.runs import DESIGN_RUNS
    from pumpsim.simulate import simulate

    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml")
    sim = simulate(cfg.with_harmonics([[4, 1.5e-5, 0.3]]), duration=0.05, rate=20000.0)
    data = Dataset(sim.time, sim.torque)
    geo = cfg.with_harmonics([[4, 0.0, 0.0]])
    names = ["mu", "theta0", "housing.harmonics.0.amplitude"]
    init = {"mu": 0.17, "theta0": cfg.angle, "housing.harmonics.0.amplitude": 8e-6}
    runs = []
    orig = problem.simd_torque_designs
    monkeypatch.setattr(problem, "simd_torque_designs", lambda *a: runs.append(1) or orig(*a))
    DESIGN_RUNS.entries.clear()
    smooth = make_problem(geo, data, names, initial=init, interval=SMOOTH_COLUMNS)
    m_s, J_s = smooth.model_and_jacobian(smooth.x0)
    assert not runs
    full = make_problem(geo, data, names, initial=init, interval=True)
    m_i, J_i = full.model_and_jacobian(full.x0)
    assert np.array_equal(m_s, m_i) and np.array_equal(J_s[:, :2], J_i[:, :2])
    differ = J_s[:, 2] != J_i[:, 2]
    assert 0 < differ.mean() < 0.5  # a minority of the samples: the rest are the same bits


def test_a_long_records_jacobian_blocks_are_not_remembered():
    """The Jacobian's blocks (SAMPLE_BLOCK samples each) are remembered only for a record of one
    block: a long record's would fill the memory with runs that are rarely repeated (32 blocks of a
    10^6-sample fit held ~120 MiB). The columns are the same bits either way."""
    from pumpsim.identification.runs import JACOBIAN_RUNS
    from pumpsim.identification.sampled import SAMPLE_BLOCK

    names = ["mu", "theta0"]
    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml")
    for n, remembered in ((SAMPLE_BLOCK, True), (SAMPLE_BLOCK + 1000, False)):
        t = np.arange(n) / 20000.0
        prob = make_problem(cfg, Dataset(t, np.zeros(n)), names)
        if prob._simd is None or not prob._simd.has_jacobian:
            return  # no SIMD Jacobian entries on this machine: the CasADi map's path remembers nothing
        JACOBIAN_RUNS.entries.clear()
        m, J = prob.model_and_jacobian(prob.x0)
        assert bool(JACOBIAN_RUNS.entries) == remembered
        if remembered:
            m2, J2 = prob.model_and_jacobian(prob.x0)  # from the memory: the same bits
            assert np.array_equal(J, J2) and np.array_equal(m, m2)
