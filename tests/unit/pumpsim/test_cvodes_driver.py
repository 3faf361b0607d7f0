"""The direct CVODES driver on a compiled oscillator with a known answer: accuracy, carrying on
across calls without a restart, root finding, and the clean fall-back to CasADi's plugin."""
import math
import subprocess

import casadi as ca
import numpy as np
import pytest

import pumpsim
from pumpsim import cvodes_driver
from tests.conftest import make_config
from tests.tolerances import CROSSING_REL, OSCILLATOR_REL, OSCILLATOR_RTOL

W = 30.0


@pytest.fixture(scope="module")
def oscillator(tmp_path_factory):
    """x'' = -W^2 x as a compiled kernel `f`(x, p) and its Jacobian `f_jac`, as the codegen
    writes them (CasADi's C calling convention)."""
    if not cvodes_driver.available()[0]:
        pytest.skip(f"direct CVODES driver not available: {cvodes_driver.available()[1]}")
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p")
    xdot = ca.vertcat(x[1], -p**2 * x[0])
    f = ca.Function("f", [x, p], [xdot])
    fj = ca.Function("f_jac", [x, p], [ca.jacobian(xdot, x)])
    return _compiled(tmp_path_factory.mktemp("osc"), "osc", f, fj), fj.sparsity_out(0)


def _compiled(folder, name, *functions):
    """The functions compiled as the codegen writes them (CasADi's C calling convention)."""
    gen = ca.CodeGenerator(f"{name}.c")
    for f in functions:
        gen.add(f)
    gen.generate(str(folder) + "/")
    so = folder / f"{name}.so"
    subprocess.run(["cc", "-O2", "-fPIC", "-shared", str(folder / f"{name}.c"), "-o", str(so)], check=True)
    return so


def _driver(oscillator, atol=1e-12):
    so, sp = oscillator
    x, p = np.zeros(2), np.array([W])
    rhs = cvodes_driver.KernelCall(so, "f", [x, p], 0)
    jac = cvodes_driver.KernelCall(so, "f_jac", [x, p], 0)
    return cvodes_driver.Driver(2, rhs, [0], jac, [(sp, 0)], OSCILLATOR_RTOL, np.full(2, atol)), rhs


def test_direct_driver_solves_the_oscillator(oscillator):
    d, _ = _driver(oscillator)
    t = np.linspace(0.0, 0.5, 51)
    X = d.run(0.0, np.array([0.0, 1.0]), t[1:])
    exact = np.sin(W * t[1:]) / W
    assert np.max(np.abs(X[:, 0] - exact)) <= OSCILLATOR_REL * np.max(np.abs(exact))
    assert d.stats["njevals"] < d.stats["nlinsetups"]  # CVODES reuses its Jacobian


def test_a_call_from_where_the_last_ended_carries_on_without_a_restart(oscillator):
    """Two calls, the second from the first's end, are the one call: the same steps and states
    to the last bit (a restart would begin again at order 1 with a new first step)."""
    t = np.linspace(0.0, 0.5, 51)
    x0 = np.array([0.0, 1.0])
    one, _ = _driver(oscillator)
    X1 = one.run(0.0, x0, t[1:])
    two, _ = _driver(oscillator)
    A = two.run(0.0, x0, t[1:21])
    B = two.run(t[20], A[-1], t[21:])
    assert np.array_equal(np.vstack([A, B]), X1)
    assert two.stats["nsteps"] == one.stats["nsteps"]
    three, _ = _driver(oscillator)  # from another state: restarted, and more steps
    A = three.run(0.0, x0, t[1:21])
    three.run(t[20], A[-1] * (1 + 1e-9), t[21:])
    assert three.stats["nsteps"] > one.stats["nsteps"]


def test_roots_are_located_on_the_interpolant(oscillator):
    """x = A sin(W (t - t0)) changes sign at t0 + k pi / W: the run stops at the first one, with
    the rows before it."""
    d, rhs = _driver(oscillator)
    d.set_roots(rhs, [], [], 0, 0, [0], 0.0)
    t = np.linspace(0.0, 0.2, 21)
    x0 = np.array([1e-3, 1.0])  # off zero: the start is not a root
    X = d.run(0.0, x0, t[1:])
    t_root, x_root, found = d.root
    t_exact = math.pi / W - math.atan2(1e-3 * W, 1.0) / W  # x = A sin(W (t - t_0)), phase from x0
    assert list(found) == [0]
    # the root is the integrated solution's: its error (OSCILLATOR_REL of the amplitude 1 / W)
    # over the slope |x'| = 1 there
    assert abs(t_root - t_exact) <= OSCILLATOR_REL / W
    assert len(X) == np.searchsorted(t[1:], t_root)
    assert abs(x_root[0]) <= OSCILLATOR_REL / W


def test_without_the_driver_the_casadi_plugin_gives_the_same_crossing(monkeypatch):
    """PUMPSIM_CVODES=casadi (or a machine without SUNDIALS) integrates through CasADi's plugin:
    the contact model's free-flight crossing at the same time as the direct driver's."""
    cfg = make_config("test_rig", **{f"friction.housing.{k}": 0.0 for k in ("static", "dynamic")})
    monkeypatch.setenv(cvodes_driver.ENV, "")
    direct = cvodes_driver.available()[0]
    runs = {}
    for mode in ("", "casadi"):
        monkeypatch.setenv(cvodes_driver.ENV, mode)
        res = pumpsim.simulate(cfg, model="contact", duration=0.004, rate=2000, initial="bottom")
        runs[mode] = res
    hit = {m: [e["time"] for e in r.events if e["kind"] == "housing_contact" and e["vane"] == 0][0]
           for m, r in runs.items()}
    assert runs["casadi"].stats["driver"] == "cvodes (casadi)"
    assert runs[""].stats["driver"] == ("cvodes (direct)" if direct else "cvodes (casadi)")
    assert abs(hit[""] - hit["casadi"]) <= CROSSING_REL * hit["casadi"]


def test_a_driver_that_cannot_be_built_falls_back(monkeypatch, tmp_path):
    """A missing SUNDIALS (here: a library that does not exist) leaves available() False with the
    compiler's reason, and the runtime on CasADi's plugin."""
    monkeypatch.setattr(cvodes_driver, "_LIB", {})
    monkeypatch.setattr(cvodes_driver, "LIBS", cvodes_driver.LIBS + ["-lsundials_no_such_library"])
    monkeypatch.setenv("PUMPSIM_GENERATED", str(tmp_path))
    ok, why = cvodes_driver.available()
    assert not ok and "CVODES driver" in why
    res = pumpsim.simulate(make_config("test_rig"), model="contact", duration=0.002, rate=2000)
    assert res.stats["driver"] == "cvodes (casadi)" and res.termination == "completed"


@pytest.fixture(scope="module")
def oscillator_with_quadrature(tmp_path_factory):
    """The oscillator with a quadrature riding along as a third state, q' = x'^2, as the gas
    model's budgets do: kernel `g`(y, p) -> (xdot, qdot) and `g_jac` with zero quadrature rows."""
    if not cvodes_driver.available()[0]:
        pytest.skip(f"direct CVODES driver not available: {cvodes_driver.available()[1]}")
    y, p = ca.SX.sym("y", 3), ca.SX.sym("p")
    xdot, qdot = ca.vertcat(y[1], -p**2 * y[0]), y[1] ** 2
    g = ca.Function("g", [y, p], [xdot, qdot])
    gj = ca.Function("g_jac", [y, p], [ca.jacobian(xdot, y), ca.SX(1, 3)])
    return _compiled(tmp_path_factory.mktemp("oscq"), "oscq", g, gj), gj.sparsity_out(0), gj.sparsity_out(1)


def test_the_leading_block_solver_gives_the_full_solvers_steps_and_states(oscillator_with_quadrature):
    """lin_size: the Newton systems solved on the states' block alone, or on the whole system by
    the driver's own LU, are SUNDIALS' dense solver's to the last bit (same steps, states and
    quadrature), and the quadrature is the integral."""
    so, sp_x, sp_q = oscillator_with_quadrature
    t = np.linspace(0.0, 0.5, 51)
    runs = {}
    for lin_size in (None, 2, 3):
        y, p = np.zeros(3), np.array([W])
        rhs = cvodes_driver.KernelCall(so, "g", [y, p], 0)
        jac = cvodes_driver.KernelCall(so, "g_jac", [y, p], 0)
        d = cvodes_driver.Driver(3, rhs, [0, 2], jac, [(sp_x, 0), (sp_q, 2)], OSCILLATOR_RTOL,
                                 np.full(3, 1e-12), lin_size=lin_size)
        runs[lin_size] = (d.run(0.0, np.array([0.0, 1.0, 0.0]), t[1:]), d.stats)
    (full, st_full), (block, st_block), (own, st_own) = runs[None], runs[2], runs[3]
    assert np.array_equal(full, block) and st_full == st_block
    assert np.array_equal(full, own) and st_full == st_own  # the driver's LU on the whole system
    exact = t[1:] / 2 + np.sin(2 * W * t[1:]) / (4 * W)  # integral of cos^2(W t)
    assert np.max(np.abs(block[:, 2] - exact)) <= OSCILLATOR_REL * np.max(exact)


def test_the_step_profile_is_the_runs_steps_and_error_test(oscillator):
    """Driver.profile takes the steps a run takes (same count and failures as a run to the same
    end), every accepted step's weighted local errors pass the error test (rms <= 1), and the
    step count stays cumulative across the restart it makes."""
    x0, t_end = np.array([0.0, 1.0]), 0.5
    ref, _ = _driver(oscillator)
    ref.run(0.0, x0, np.array([t_end]))
    d, _ = _driver(oscillator)
    pr = d.profile(0.0, x0, t_end)
    n = len(pr["time"])
    assert pr["time"][-1] >= t_end > pr["time"][-2]
    assert n == ref.stats["nsteps"]  # an output time inside the last step ends it by interpolation
    assert pr["error_test_failures"].sum() == ref.stats["netfails"]
    assert pr["newton_failures"].sum() == ref.stats["nncfails"]
    rms = np.sqrt(np.mean(pr["weighted_error"] ** 2, axis=1))
    assert np.all(rms <= 1.0) and np.median(rms) > 1e-3  # near the tolerance, not zero
    assert np.allclose(np.diff(pr["time"]), pr["step"][1:])
    assert set(pr["order"]) <= set(range(1, 6))
    assert np.max(np.abs(pr["angle"] - np.sin(W * pr["time"]) / W)) <= OSCILLATOR_REL / W  # y[0] per step
    d.run(0.0, x0, np.array([t_end]))  # restarted after the profile: the counts go on from it
    assert d.stats["nsteps"] == 2 * n


def test_rows_evaluates_the_kernel_at_every_row_as_casadi_does(oscillator):
    """KernelCall.rows: the compiled kernel at each row of X in one C loop, the values of CasADi's
    map of the same compiled function bit for bit; an output not wanted is not computed into."""
    so, _ = oscillator
    X = np.random.default_rng(3).normal(size=(7, 2))
    call = cvodes_driver.KernelCall(so, "f", [np.zeros(2), np.array([W])], 0)
    (out,) = call.rows(X, [2])
    ref = np.asarray(ca.external("f", str(so)).map(7)(X.T, W)).T
    assert np.array_equal(out, ref) and np.array_equal(out[:, 1], -W**2 * X[:, 0])
    assert call.rows(X, [2], wanted=[False]) == [None]


@pytest.fixture(scope="module")
def driven(tmp_path_factory):
    """x0' = v, x1' = v - a x1 with v = p[0] the drive and a = p[1]: x0 is the drive's integral."""
    if not cvodes_driver.available()[0]:
        pytest.skip(f"direct CVODES driver not available: {cvodes_driver.available()[1]}")
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p", 2)
    xdot = ca.vertcat(p[0], p[0] - p[1] * x[1])
    f, fj = ca.Function("g", [x, p], [xdot]), ca.Function("g_jac", [x, p], [ca.jacobian(xdot, x)])
    return _compiled(tmp_path_factory.mktemp("drv"), "drv", f, fj), fj.sparsity_out(0)


RAMP_STEP = 0.01
RAMP = np.r_[np.zeros(40), np.ones(61)]  # 0, then up to 1 between samples 39 and 40: kinks there


def _ramp_integral(t):
    s = np.clip(t - 0.39, 0.0, RAMP_STEP)
    return 0.5 * s ** 2 / RAMP_STEP + np.maximum(t - 0.40, 0.0)


def _driven_run(driven, stops, t, offset=0.0):
    so, sp = driven
    pbuf = np.array([0.0, 50.0])
    rhs = cvodes_driver.KernelCall(so, "g", [np.zeros(2), pbuf], 0)
    jac = cvodes_driver.KernelCall(so, "g_jac", [np.zeros(2), pbuf], 0)
    d = cvodes_driver.Driver(2, rhs, [0], jac, [(sp, 0)], 1e-8, np.full(2, 1e-12))
    d.set_drive(rhs.keep[1], 0, RAMP_STEP, RAMP, stops)
    d.shift_drive(offset)
    return d, d.run(0.0, np.zeros(2), t - offset)


def test_a_drive_is_the_linear_interpolation_and_its_stops_end_the_steps(driven):
    """The drive's integral at rtol 1e-8 to ~1e-10 either way; with the kinks as stops the steps no
    longer straddle them: fewer rejected steps (measured 15 against 47)."""
    t = np.array([0.2, 0.395, 0.45, 0.7, 1.0, 1.2])  # 1.2: past the grid, the last line on
    free, X = _driven_run(driven, (), t)
    stopped, Xs = _driven_run(driven, (39, 40), t)
    for Y in (X, Xs):
        assert np.max(np.abs(Y[:, 0] - _ramp_integral(t))) < 1e-9
    assert stopped.stats["netfails"] < free.stats["netfails"]


def test_a_shifted_drive_runs_on_its_own_clock(driven):
    """shift_drive(0.3): the solver's t = 0 is the drive's 0.3."""
    t = np.array([0.35, 0.395, 0.45, 0.7])
    _, X = _driven_run(driven, (39, 40), t, offset=0.3)
    assert np.max(np.abs(X[:, 0] - (_ramp_integral(t) - _ramp_integral(0.3)))) < 1e-9


@pytest.fixture(scope="module")
def van_der_pol(tmp_path_factory):
    """Van der Pol at mu = 50 (stiff, nonlinear: Newton iterations, Jacobian reuse, error-test
    failures at the relaxation jumps) with a quadrature of x^2 riding along."""
    if not cvodes_driver.available()[0]:
        pytest.skip(f"direct CVODES driver not available: {cvodes_driver.available()[1]}")
    y, p = ca.SX.sym("y", 3), ca.SX.sym("p")
    xdot = ca.vertcat(y[1], p * (1 - y[0] ** 2) * y[1] - y[0])
    g = ca.Function("v", [y, p], [xdot, y[0] ** 2])
    gj = ca.Function("v_jac", [y, p], [ca.jacobian(xdot, y), ca.SX(1, 3)])
    return _compiled(tmp_path_factory.mktemp("vdp"), "vdp", g, gj), gj.sparsity_out(0), gj.sparsity_out(1)


def _vdp_run(van_der_pol, **options):
    so, sp_x, sp_q = van_der_pol
    y, p = np.zeros(3), np.array([50.0])
    rhs = cvodes_driver.KernelCall(so, "v", [y, p], 0)
    jac = cvodes_driver.KernelCall(so, "v_jac", [y, p], 0)
    d = cvodes_driver.Driver(3, rhs, [0, 2], jac, [(sp_x, 0), (sp_q, 2)], 1e-6, np.array([1e-8, 1e-6, 1e-7]),
                             max_order=3, **options)
    return d.run(0.0, np.array([2.0, 0.0, 0.0]), np.linspace(0.0, 150.0, 301)[1:]), d.stats


@pytest.mark.parametrize("lin_size", [None, 2])
def test_the_drivers_vector_operations_are_sundials_to_the_last_bit(van_der_pol, lin_size):
    """The driver's own serial vector operations (LinearSum's special cases, norms, the error
    weights' Abs/Inv/Min) give SUNDIALS' steps, failures and states bit for bit, with SUNDIALS'
    dense solver and with the leading-block one."""
    own, st_own = _vdp_run(van_der_pol, lin_size=lin_size)
    ref, st_ref = _vdp_run(van_der_pol, lin_size=lin_size, sundials_vectors=True)
    assert st_ref["netfails"] > 0 and st_ref["nsteps"] > 500  # the stiff jumps exercise the step control
    assert st_own == st_ref
    assert np.array_equal(own, ref)


def test_keeping_steps_in_a_band_takes_other_steps_to_the_same_accuracy(van_der_pol):
    """keep_step reaches CVODES (it changes the steps: CVODES would take an invalid band as its
    default silently, so the driver refuses one) and the run stays at the tolerance's accuracy."""
    ref, st_ref = _vdp_run(van_der_pol)
    kept, st_kept = _vdp_run(van_der_pol, keep_step=(0.9, 1.2))
    assert st_kept["nsteps"] != st_ref["nsteps"]
    again, _ = _vdp_run(van_der_pol, keep_step=(0.9, 1.2))
    assert np.array_equal(kept, again)  # deterministic
    # the same solution at the tolerance: x of order 2, measured 2.8e-3 apart at the steepest
    # rows of its relaxation jumps; a step control that broke the run would be O(1) off
    assert np.max(np.abs(kept[:, 0] - ref[:, 0])) < 1e-2
    for bad in ((1.0, 1.2), (0.5, 1.0), (-0.1, 1.5)):
        with pytest.raises(ValueError, match="keep_step"):
            _vdp_run(van_der_pol, keep_step=bad)
