"""The SIMD library's reduction entry (codegen/simd_reduce.py, design/fused.py): a design's
numbers reduced in cache are reduce_batch's on the kernel's outputs bit for bit -- through one vane
standing for alike ones and on every vane, at revolutions of any length (NumPy's pairwise sum has
three regimes), with NaNs, lift-off and several speeds -- and a study's table is the same with
and without the entry."""
import numpy as np
import pytest

from pumpsim.codegen.simd_reduce import REDUCTIONS
from pumpsim.design import evaluate
from pumpsim.design.evaluate import evaluate_designs, revolution
from pumpsim.design.fused import fused_outputs
from pumpsim.design.outputs import KERNEL_OUTPUTS, reduce_batch
from pumpsim.design.screen import position_checks
from pumpsim.design.study import study_from_dict
from pumpsim.errors import CodegenError, ConfigError
from pumpsim.kernels.simd import FastInverseDynamics
from pumpsim.model_spec.parameters import layout_names
from tests.conftest import EXAMPLES, apply_changes, example_dict, kernel_and_p, make_config, toml_text


def _designs(vanes=4):
    """Six ellipse designs: semi-axes, COF, viscous tip friction; one with a NaN COF (NaN
    outputs), one so slow the vanes lift off; the speeds of each."""
    cfgs = [make_config("test_rig", **{"housing.radius": None, "housing.shape": "ellipse", "rotor.vanes": vanes,
                                       "housing.a": 0.0225 + 2e-4 * k, "housing.b": 0.0225 - 1e-4 * k,
                                       "friction.housing.dynamic": 0.1 + 0.03 * k,
                                       "effects.viscous_tip_friction": 1e-3 * k})
            for k in range(6)]
    kern = kernel_and_p(cfgs[0])[0]
    P = np.array([kernel_and_p(c)[1] for c in cfgs])
    P[4, layout_names(kern.structure).index("friction.housing.dynamic")] = np.nan
    return kern, P, np.array([300.0, 410.0, 520.0, 630.0, 500.0, 0.5])


def _const(P, kern):
    names = layout_names(kern.structure)
    col = lambda k: P[:, names.index(k)]  # noqa: E731
    lm = np.full(len(P), 0.004) + 1e-4 * np.arange(len(P))
    return {"c_visc": col("effects.viscous_tip_friction"), "L": col("vane.length"), "lm": lm,
            "tip_area": 0.01 * col("vane.thickness")}


def _same(mine, ref, name):
    a, b = np.asarray(mine), np.asarray(ref)
    assert a.dtype.kind == b.dtype.kind and np.array_equal(a, b, equal_nan=True), name
    if a.dtype.kind == "f":
        assert np.array_equal(np.signbit(a), np.signbit(b)), name


def _check(fast, P, theta, omega, const, alike, ev, vanes):
    out, res_ok, s_min, s_max = fused_outputs(fast, P, theta, omega, const, alike)
    ref, _ = reduce_batch(ev, {k: v for k, v in const.items() if k != "bearing"}, vanes)
    assert list(out) == list(ref)
    for nm in ref:
        _same(out[nm], ref[nm], nm)
    for mine, theirs, nm in zip((res_ok, s_min, s_max), position_checks(ev["s"], ev["position_residual"]),
                                ("res_ok", "s_min", "s_max")):
        _same(mine, theirs, nm)
    return out


@pytest.fixture(scope="module")
def designs():
    kern, P, omega = _designs()
    one = evaluate.one_vane(kern.structure)
    fast = evaluate.fast_kernel(kern.structure)
    if one is None or fast is None or not fast.has_reductions:
        pytest.skip("no SIMD library with the reduction entry on this machine")
    return kern, P, omega, one, fast


@pytest.mark.parametrize("n", [360, 8, 12, 136, 1000])  # pairwise: < 8, <= 128, split (and 360 the studies')
def test_one_vane_reductions_are_reduce_batchs_bit_for_bit(designs, n):
    kern, P, omega, one, _ = designs
    theta = revolution(0.1, n)
    const = _const(P, kern)
    ev = one.evaluate(P, theta, omega, KERNEL_OUTPUTS)
    out = _check(one.fast, P[:, one.columns], theta, omega, {**const, "bearing": P[:, one.bearing]}, one.vanes,
                 ev, one.vanes)
    assert np.isnan(out["mean_torque"][4]) and np.isfinite(out["mean_torque"][:4]).all()
    assert out["lift_off"].tolist() == (out["min_normal_force"] < 0).tolist()


@pytest.mark.parametrize("n", [360, 7, 130])
def test_every_vane_reductions_are_reduce_batchs_bit_for_bit(designs, n):
    kern, P, omega, one, fast = designs
    Q = P.copy()
    Q[1, one.factors[2]] = 0.9  # vane 2 of design 1 rubs less: every vane is evaluated
    theta = revolution(0.3, n)
    const = _const(Q, kern)
    ev = evaluate_designs(kern, Q, theta, omega)
    _check(fast, Q, theta, omega, {**const, "bearing": 0.0}, 1, ev, kern.structure.vanes)


def test_the_library_names_its_reductions_and_checks_its_arguments(designs):
    _, P, omega, one, fast = designs
    assert fast.manifest["reductions"]["columns"] == list(REDUCTIONS)
    theta, tol = revolution(0.0, 360), (1e-10, 1e-6)
    with pytest.raises(ConfigError, match="consts"):
        fast.reduce_designs(theta, omega, P, np.zeros((len(P), 3)), tol)
    with pytest.raises(ConfigError, match="omega"):
        fast.reduce_designs(theta, omega[:2], P, np.zeros((len(P), 4)), tol)
    with pytest.raises(CodegenError, match="refused"):  # alike vanes need a 1-vane library
        fast.reduce_designs(theta, omega, P, np.zeros((len(P), 4)), tol, alike=4)
    with pytest.raises(CodegenError, match="refused"):  # nor a revolution they do not divide
        one.fast.reduce_designs(revolution(0.0, 362), omega, P[:, one.columns], np.zeros((len(P), 4)), tol, alike=4)


UNLIKE = "unlike"  # the test rig with one vane rubbing less and one more: every vane is evaluated
STUDIES = {
    "alike-two-speeds": {"study": {"config": str(EXAMPLES / "test_rig.toml"), "sampler": "sobol", "samples": 64,
                                   "seed": 3, "speeds": [300.0, 607.0]},
                         "vary": {"housing.radius": {"distribution": "normal", "sd": 4e-6},
                                  "friction.housing.dynamic": {"distribution": "uniform", "low": 0.12, "high": 0.28}}},
    "unlike-vanes": {"study": {"config": UNLIKE, "sampler": "sobol", "samples": 32, "seed": 4},
                     "vary": {"vane.length": {"distribution": "normal", "sd": 5e-6},
                              "effects.viscous_tip_friction": {"distribution": "uniform", "low": 0.0, "high": 0.01}}},
    "ellipse-grid": {"study": {"config": str(EXAMPLES / "ellipse_4vanes.toml"), "sampler": "grid"},
                     "vary": {"housing.b": {"values": [0.0245, 0.022273, 0.020417]}, "rotor.vanes": {"values": [3, 5]}}},
}


@pytest.mark.parametrize("name", list(STUDIES))
def test_a_studys_table_is_the_same_with_and_without_the_reduction_entry(designs, name, monkeypatch, tmp_path):
    from pumpsim.design.execute import run_study

    unlike = tmp_path / "unlike.toml"
    unlike.write_text(toml_text(apply_changes(example_dict("test_rig"),
                                              {"effects.vane_friction_factors": [1.0, 0.9, 1.0, 1.1]})))
    d = STUDIES[name]
    st = study_from_dict({**d, "study": {**d["study"], "config": str(unlike) if d["study"]["config"] == UNLIKE
                                         else d["study"]["config"]}})
    done, real = [], evaluate.fused_outputs

    def counted(*a):  # designs the reduction entry returned (a failure would send them to the per-design path)
        r = real(*a)
        done.append(len(a[1]))
        return r

    monkeypatch.setattr(evaluate, "fused_outputs", counted)
    fused = run_study(st, workers=0, progress=False)[0]
    assert sum(done) >= len(fused) // 2
    monkeypatch.setattr(FastInverseDynamics, "has_reductions", property(lambda self: False))
    plain = run_study(st, workers=0, progress=False)[0]
    assert list(fused.columns) == list(plain.columns) and len(fused) == len(plain)
    assert (fused["status"] == "ok").sum() >= len(fused) // 2  # the outputs are compared, not only statuses
    for c in fused.columns:
        if fused[c].dtype.kind == "f":
            _same(fused[c].to_numpy(), plain[c].to_numpy(), c)
        else:
            assert fused[c].tolist() == plain[c].tolist(), c
