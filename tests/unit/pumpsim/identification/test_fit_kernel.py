"""The fits' model torques on the SIMD library (problem.torque_at) and their Jacobian columns
(its exact Jacobian entries, sampled.pointwise_columns) against the CasADi map they replace
(PUMPSIM_FIT_KERNEL=scalar: forward AD): same model, with a ripple, a sensor lag (the refined grid), a torque offset, a housing harmonic
and a drifting speed column (the drive time and its rates)."""
import numpy as np
import pytest

from pumpsim.config import load_config
from pumpsim.data import Dataset
from pumpsim.identification import make_problem
from pumpsim.kernels import fast_kernel
from tests.conftest import ROOT
from pumpsim.identification.identifiability import to_fix
from tests.tolerances import EQUAL_COLUMNS_REL, FIT_LAG_COLUMN_REL, SIMD_JACOBIAN_REL, SIMD_REL

NAMES = ["mu", "theta0", "speed", "ripple_cos", "ripple_sin", "torque_offset", "lag",
         "housing.harmonics.0.amplitude"]


def _problem():
    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml").with_harmonics([[4, 1e-5, 0.3]])
    t = np.arange(3001) / 10000.0
    w = cfg.speed * (1 - 0.02 * t / t[-1]) + np.random.default_rng(0).normal(0, 0.3, t.size)
    data = Dataset(t, np.zeros(t.size), speed=w)
    initial = {"ripple_cos": 0.01, "ripple_sin": -0.004, "torque_offset": 0.01, "lag": 5e-5}
    return make_problem(cfg, data, NAMES, initial=initial, ripple_order=2)


def test_simd_model_torques_equal_the_casadi_map(monkeypatch):
    prob = _problem()
    if fast_kernel(prob.kern.structure) is None:
        pytest.skip("no SIMD library on this machine: the fits use the CasADi map already")
    assert prob.tau is not prob.t  # the drifting column drives the model
    x = prob.x0.copy()
    fast_m, (fast_mj, fast_J) = prob.model(x), prob.model_and_jacobian(x)
    monkeypatch.setenv("PUMPSIM_FIT_KERNEL", "scalar")
    ref_m, (ref_mj, ref_J) = prob.model(x), prob.model_and_jacobian(x)
    scale = np.max(np.abs(ref_m))
    assert np.max(np.abs(fast_m - ref_m)) < SIMD_REL * scale
    assert np.max(np.abs(fast_mj - ref_mj)) < SIMD_REL * scale
    # every column: exact derivatives both, on every sample (the lag's: a finite step of the filter)
    _assert_columns_agree(fast_J, ref_J, NAMES, prob, ref_m)
    monkeypatch.delenv("PUMPSIM_FIT_KERNEL")
    x[NAMES.index("lag")] = 0.0  # without the filter: the lag's column is - speed x the slope
    fast_J = prob.model_and_jacobian(x)[1]
    monkeypatch.setenv("PUMPSIM_FIT_KERNEL", "scalar")
    _assert_columns_agree(fast_J, prob.model_and_jacobian(x)[1], NAMES, prob, ref_m)


def _assert_columns_agree(fast_J, ref_J, names, prob, y):
    """Each column to its scale: its largest value, at least the torque's over the parameter's size
    (the housing's for its geometry) -- a column zero in exact arithmetic (the centre of a 4-vane
    ellipse) is rounding noise in both."""
    size = [prob.pv.values["housing.a"] if n.startswith("housing.") else abs(v) or 1.0
            for n, v in zip(names, prob.x0)]
    col = np.maximum(np.max(np.abs(ref_J), axis=0), np.max(np.abs(y)) / np.array(size))
    err = np.max(np.abs(fast_J - ref_J), axis=0) / col
    tol = np.array([FIT_LAG_COLUMN_REL if n == "lag" else SIMD_JACOBIAN_REL for n in names])
    assert np.all(err <= tol), dict(zip(names, err))


def test_simd_columns_keep_what_the_diagnosis_decides_on(monkeypatch):
    """The columns decide identifiability (to_fix) and score_test's rank: (1) at a first-order-blind
    zero (an eccentricity on the 4-vane ellipse: N identical vanes see only multiples of N orders)
    AD's centre columns are ~1e-9 of the others and 'no effect' -- the SIMD library's are exact
    derivatives too, so the verdict is AD's; (2) opposite vanes of a 4-vane ellipse see the same housing:
    their COF factors' columns are equal in the model and must stay equal to well inside
    score_test's rank tolerance (1e-8 of the normalised columns), as AD's are."""
    cfg = load_config(ROOT / "examples" / "ellipse_4vanes.toml").with_harmonics([[4, 1e-5, 0.3]])
    t = np.arange(4001) / 20000.0
    names = ["mu", "theta0", "housing.harmonics.0.amplitude", "housing.center.0", "housing.center.1",
             "effects.vane_friction_factor.1", "effects.vane_friction_factor.3"]
    prob = make_problem(cfg, Dataset(t, np.zeros(t.size)), names)
    if fast_kernel(prob.kern.structure) is None:
        pytest.skip("no SIMD library on this machine: the fits use forward AD on the CasADi map")
    fast = prob.model_and_jacobian(prob.x0)
    monkeypatch.setenv("PUMPSIM_FIT_KERNEL", "scalar")
    ref = prob.model_and_jacobian(prob.x0)
    assert to_fix(names, fast[1], prob.x0, fast[0]) == to_fix(names, ref[1], prob.x0, ref[0])
    assert to_fix(names, ref[1], prob.x0, ref[0])[0] == ["housing.center.0", "housing.center.1"]
    _assert_columns_agree(fast[1], ref[1], names, prob, ref[0])
    f1, f3 = (fast[1][:, names.index(n)] for n in names[-2:])
    assert np.linalg.norm(f1 / np.linalg.norm(f1) - f3 / np.linalg.norm(f3)) < EQUAL_COLUMNS_REL


def test_many_designs_in_one_call_are_the_per_design_runs_bit_for_bit(monkeypatch):
    """sampled.simd_torque_designs (the interval averages' sub-sample runs in one call) against one
    simd_torque call per design: designs that differ in parameters, angle and drive entries (torque
    offset, phase, ripple), a length that is no multiple of the library's chunk, and groups that
    split the designs over several calls."""
    from pumpsim.identification import sampled

    prob = _problem()
    fast = fast_kernel(prob.kern.structure)
    if fast is None:
        pytest.skip("no SIMD library on this machine")
    npar, n = fast.n_params, prob.t.size
    rng = np.random.default_rng(1)
    zs = np.tile(prob.z(prob.x0), (5, 1))
    zs[:, :npar] *= 1 + 1e-3 * rng.standard_normal((5, npar))
    zs[3:, npar:] += [0.1, 0.0, 0.0, 0.02, 0.01, -0.005]  # two designs with their own drive
    thetas = prob.angle(prob.x0)[None, :] + 1e-4 * np.arange(5)[:, None]
    kin = (prob.tau, *prob._rates)
    each = np.array([sampled.simd_torque(fast, th, z, 2, *kin) for th, z in zip(thetas, zs)])
    monkeypatch.setattr(sampled, "DESIGN_SAMPLES", 2 * n)  # groups of two designs
    assert np.array_equal(sampled.simd_torque_designs(fast, thetas, zs, 2, *kin), each)
    same = np.tile(zs[0], (5, 1))  # one drive for all: computed once
    each = np.array([sampled.simd_torque(fast, th, same[0], 2, *kin) for th in thetas])
    assert np.array_equal(sampled.simd_torque_designs(fast, thetas, same, 2, *kin), each)


def test_a_problem_remembers_its_last_model_runs_and_honours_the_kernel_switch(monkeypatch):
    """The same model asked for again is not run again, comes back as a copy (the caller may write
    into it), and PUMPSIM_FIT_KERNEL=scalar set on a live problem sends it to the CasADi map."""
    from pumpsim.identification import problem as problem_module

    prob = _problem()
    if fast_kernel(prob.kern.structure) is None:
        pytest.skip("no SIMD library on this machine")
    calls = []
    run = problem_module.simd_torque
    monkeypatch.setattr(problem_module, "simd_torque", lambda *a: calls.append(1) or run(*a))
    x = prob.x0.copy()
    x[NAMES.index("lag")] = 0.0
    first = prob.model(x)
    first[:] = 0.0
    again = prob.model(x)
    assert len(calls) == 1 and np.any(again != 0.0)
    x[0] *= 1.01
    prob.model(x)
    assert len(calls) == 2
    mapped = []
    scalar = problem_module.torque_at
    monkeypatch.setattr(problem_module, "torque_at", lambda *a: mapped.append(1) or scalar(*a))
    monkeypatch.setenv("PUMPSIM_FIT_KERNEL", "scalar")
    ref = prob.model(x)
    assert len(mapped) == 1 and len(calls) == 2
    monkeypatch.delenv("PUMPSIM_FIT_KERNEL")
    simd = prob.model(x)  # the SIMD run remembered: the map's run did not replace it
    assert len(calls) == 2 and np.max(np.abs(simd - ref)) < SIMD_REL * np.max(np.abs(ref))
