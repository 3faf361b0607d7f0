"""SIMD inverse dynamics (codegen.simd, pumpsim.kernels.simd) against the scalar library; p per
design, per block and per sample; the cache refuses stale libraries."""
import subprocess

import numpy as np
import pytest

import pumpsim.codegen.simd as simd
from pumpsim.kernels import simd as kernel_simd
from pumpsim.model_spec import manifest as mf
from pumpsim.model_spec import simd as simd_contract
from pumpsim.errors import CodegenError, ConfigError
from pumpsim.model_spec.parameters import Structure
from pumpsim.kernels import inverse_dynamics
from tests.conftest import kernel_and_p, make_config
from tests.tolerances import SIMD_REL

CASES = {"plain": {}, "harmonics": {"housing.harmonics": [[3, 3e-5, 0.1], [5, 1e-5, 0.7]]}}


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    cfg = make_config("ellipse_4vanes", **{"rotor.slot_tilt": 0.1, "vane.tip_radius": 0.001},
                      **CASES[request.param])
    kern, p, pv = kernel_and_p(cfg)
    return kern, kernel_simd.load_fast_kernel(pv.structure, fallback=False), p, pv


def random_motion(rng, n):
    """Angles over several turns, speeds of both signs including near-standstill, accelerations."""
    theta = rng.uniform(0, 6 * np.pi, n)
    omega = rng.uniform(-600, 600, n)
    omega[: n // 10] = rng.uniform(-0.02, 0.02, n // 10)
    return theta, omega, rng.normal(0, 2e4, n)


def assert_agree(fast, ref, length):
    for name, r in ref.items():
        a, r = np.asarray(fast[name]), np.asarray(r)
        assert a.shape == r.shape, name
        if name == "position_residual":  # rounding noise in both
            assert np.max(np.abs(a - r)) <= SIMD_REL * length, name
            continue
        scale = max(np.max(np.abs(r)), 1e-300)
        assert np.max(np.abs(a - r)) <= SIMD_REL * scale, (name, np.max(np.abs(a - r)) / scale)


def test_simd_equals_scalar_at_random_points(case):
    kern, fk, p, pv = case
    assert fk.simd and any(s.startswith("_ZGV") for s in fk.manifest["vector_symbols"])
    theta, omega, omegadot = random_motion(np.random.default_rng(3), 3001)  # not a multiple of a vector
    ref = inverse_dynamics(kern, p, theta, omega, omegadot)
    assert set(ref) == set(fk.outputs)
    assert_agree(fk(theta, omega, omegadot, p), ref, pv.values["housing.a"])


def designs(pv, rng, k):
    """k designs around the base: masses, friction, slot radius and ellipse a few per cent apart."""
    names = list(pv.names)
    P = np.tile(np.asarray([pv.values[nm] for nm in names]), (k, 1))
    for key, rel in (("vane.mass", 0.3), ("friction.housing.dynamic", 0.3), ("rotor.slot_radius", 0.05),
                     ("housing.a", 0.01), ("rotor.first_slot_angle", 1.0)):
        P[:, names.index(key)] *= 1 + rel * rng.uniform(-1, 1, k)
    return P


def test_parameters_per_block_and_per_sample(case):
    kern, fk, p, pv = case
    rng = np.random.default_rng(5)
    P = designs(pv, rng, 5)
    block = 37
    theta, omega, omegadot = random_motion(rng, 5 * block - 11)  # the last block is shorter
    n = theta.size
    blocks = fk(theta, omega, omegadot, P, block=block)
    per_sample = fk(theta, omega, omegadot, np.repeat(P, block, axis=0)[:n])
    for b in range(5):
        sl = slice(b * block, min(n, (b + 1) * block))
        ref = inverse_dynamics(kern, P[b], theta[sl], omega[sl], omegadot[sl])
        assert_agree({k: v[..., sl] for k, v in blocks.items()}, ref, pv.values["housing.a"])
        assert_agree({k: v[..., sl] for k, v in per_sample.items()}, ref, pv.values["housing.a"])


def test_a_design_gets_the_same_bits_alone_or_in_a_batch(case):
    """Blocks are evaluated exactly as separate calls (chunks restart at each block), so a design
    study's numbers do not depend on how designs are batched over workers."""
    _, fk, _, pv = case
    rng = np.random.default_rng(11)
    P = designs(pv, rng, 4)
    n = 361  # blocks start at every alignment
    theta = rng.uniform(0, 7, n)
    omega = rng.uniform(100, 500, 4)
    batch = {k: v.copy() for k, v in fk(np.tile(theta, 4), np.repeat(omega, n), 0.0, P, block=n).items()}
    for d in range(4):
        alone = fk(theta, omega[d], 0.0, P[d])
        for k, v in alone.items():
            np.testing.assert_array_equal(batch[k][..., d * n:(d + 1) * n], v, err_msg=k)


def test_threads_and_reused_output_give_the_same_numbers(case):
    _, fk, p, pv = case
    theta, omega, omegadot = random_motion(np.random.default_rng(9), 2000)
    one = {k: v.copy() for k, v in fk(theta, omega, omegadot, p).items()}
    out = fk.output_array(theta.size)
    two = fk(theta, omega, omegadot, p, out=out, threads=2)
    assert np.shares_memory(two["torque"], out) and np.shares_memory(two["normal"], out)
    wide = np.full((fk.rows, theta.size + 13), np.nan)
    plain = fk(theta, omega, omegadot, p, out=wide[:, 5:-8])  # rows of a wider array
    assert np.isnan(wide[:, :5]).all() and np.isnan(wide[:, -8:]).all()
    for k in one:  # threads split at the library's chunk boundaries: the same bits
        np.testing.assert_array_equal(two[k], one[k], err_msg=k)
        np.testing.assert_array_equal(plain[k], one[k], err_msg=k)
    P = designs(pv, np.random.default_rng(4), 3)
    a = {k: v.copy() for k, v in fk(theta[:1998], omega[:1998], omegadot[:1998], P, block=666).items()}
    b = fk(theta[:1998], omega[:1998], omegadot[:1998], P, block=666, threads=2)
    for k in a:
        np.testing.assert_array_equal(b[k], a[k], err_msg=k)


def test_output_subsets_compute_only_their_rows_and_agree(case):
    """The reduced entry points (the torque alone; the simulation's reported columns) against the
    CasADi map and the full entry point, for one design, blocks and p per sample; the buffer has
    only their rows; threads split them at the same bits."""
    kern, fk, p, pv = case
    rng = np.random.default_rng(21)
    theta, omega, omegadot = random_motion(rng, 2501)
    n, N = theta.size, fk.vanes
    ref = inverse_dynamics(kern, p, theta, omega, omegadot)
    P = designs(pv, rng, 3)
    block = -(-n // 3)
    Ps = np.repeat(P, block, axis=0)[:n]
    for key, stored in simd_contract.SUBSETS.items():
        names = ("torque", *stored)
        assert fk.entry_for(names) == key and fk.entry_for(stored[:1] or "torque") == key
        out = fk.output_array(n, names)
        assert out.shape == (1 + len(stored) * N, n)
        got = fk(theta, omega, omegadot, p, out=out, outputs=names)
        assert list(got) == list(names) and np.shares_memory(got["torque"], out)
        assert_agree(got, {k: ref[k] for k in names}, pv.values["housing.a"])
        assert_agree(fk(theta, omega, omegadot, p, outputs=names, threads=2), got, pv.values["housing.a"])
        for args in ((P,), (Ps,)):
            full = fk(theta, omega, omegadot, *args, **({"block": block} if args[0] is P else {}))
            sub = fk(theta, omega, omegadot, *args, outputs=names, **({"block": block} if args[0] is P else {}))
            assert_agree(sub, {k: full[k] for k in names}, pv.values["housing.a"])
        a = {k: v.copy() for k, v in got.items()}
        b = fk(theta, omega, omegadot, p, outputs=names, threads=2)
        for k in a:  # threads split at the library's chunk boundaries: the same bits
            np.testing.assert_array_equal(b[k], a[k], err_msg=k)
    assert fk.entry_for(("torque", "alpha")) is None  # not in a reduced set: the full entry point
    with pytest.raises(ConfigError, match="no inverse-dynamics output 'torq'; available: torque"):
        fk(theta, omega, omegadot, p, outputs=("torq",))
    with pytest.raises(ConfigError, match=r"out must be .* shape \(1, 2501\)"):
        fk(theta, omega, omegadot, p, out=fk.output_array(n), outputs="torque")


def test_bad_arguments_are_named(case):
    _, fk, p, _ = case
    th = np.zeros(10)
    with pytest.raises(ConfigError, match="omega must be a scalar or have 10 samples"):
        fk(th, np.zeros(9), 0.0, p)
    with pytest.raises(ConfigError, match="parameters per row"):
        fk(th, 0.0, 0.0, p[:-1])
    with pytest.raises(ConfigError, match="blocks of 4 need 3"):
        fk(th, 0.0, 0.0, np.tile(p, (2, 1)), block=4)
    with pytest.raises(ConfigError, match="give block="):
        fk(th, 0.0, 0.0, np.tile(p, (3, 1)))
    with pytest.raises(ConfigError, match="out must be"):
        fk(th, 0.0, 0.0, p, out=np.empty((3, 10)))


@pytest.fixture
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("PUMPSIM_GENERATED", str(tmp_path))
    monkeypatch.setattr(kernel_simd, "_LOADED", {})
    return tmp_path


def test_stale_foreign_or_tampered_simd_library_is_refused(private_cache, monkeypatch):
    st = Structure(vanes=2, harmonics=0)
    k = kernel_simd.load_fast_kernel(st, fallback=False)
    assert k.manifest["options"]["cpu"] == simd_contract.cpu_signature()

    def refused():
        monkeypatch.setattr(kernel_simd, "_LOADED", {})
        with pytest.raises(CodegenError, match="missing or stale"):
            kernel_simd.load_fast_kernel(st, build=False)

    with monkeypatch.context() as m:  # a worker with other instruction-set flags builds its own
        m.setattr(simd_contract, "cpu_signature", lambda: "another-cpu")
        refused()
    with monkeypatch.context() as m:  # an edited model source
        m.setattr(mf, "source_fingerprint", lambda: "edited")
        refused()
    lib = k.folder / k.manifest["library"]
    tampered = lib.with_suffix(".new")  # a new file in its place (the loaded one stays mapped)
    tampered.write_bytes(lib.read_bytes() + b"\0")
    tampered.replace(lib)
    refused()


def test_a_scalar_loop_fails_the_build_and_falls_back(private_cache, monkeypatch):
    """Without -fno-math-errno libm calls set errno, so gcc keeps the loops scalar: no library
    (a scalar loop is refused by name); by default the scalar kernel behind the same interface."""
    cfg = make_config("ellipse_4vanes", **{"rotor.vanes": 2})
    kern, p, pv = kernel_and_p(cfg)
    monkeypatch.setattr(simd, "SIMD_CFLAGS", [f for f in simd.SIMD_CFLAGS if f != "-fno-math-errno"])
    with pytest.raises(CodegenError, match="left loop_vane_shared, loop_vane_samples, loop_vane_torque_shared, "
                                           ".* scalar"):
        kernel_simd.load_fast_kernel(pv.structure, fallback=False)
    monkeypatch.setattr(kernel_simd, "_LOADED", {})
    fb = kernel_simd.load_fast_kernel(pv.structure)
    assert not fb.simd and "scalar" in fb.reason
    theta, omega, omegadot = random_motion(np.random.default_rng(1), 50)
    P = designs(pv, np.random.default_rng(2), 2)
    got = fb(theta, omega, omegadot, P, block=25)
    ref = inverse_dynamics(kern, P[1], theta[25:], omega[25:], omegadot[25:])
    for name, r in ref.items():
        np.testing.assert_array_equal(got[name][..., 25:], r)
    torque = fb(theta, omega, omegadot, P, block=25, outputs="torque")  # the reduced entries too
    assert list(torque) == ["torque"]
    np.testing.assert_array_equal(torque["torque"][25:], ref["torque"])


def test_vane_loops_vectorise_on_avx2_too(case, tmp_path):
    """A worker without AVX-512 builds its own library: the same source must vectorise with AVX2
    alone (selects as bit blends; with C conditionals gcc 12 left these loops scalar there)."""
    _, fk, _, _ = case
    if "-mavx2" not in simd.native_target():
        pytest.skip("this CPU has no AVX2")
    flags = [f for f in simd.SIMD_CFLAGS if f != "-shared"]
    proc = subprocess.run([simd.CC, *flags, "-mno-avx512f", "-fopt-info-vec-optimized", "-c",
                           str(fk.folder / fk.manifest["c_source"]), "-o", str(tmp_path / "avx2.o")],
                          capture_output=True, text=True, check=True)
    assert simd.unvectorised_loops(fk.manifest["loop_lines"], proc.stderr) == []
    assert "using 32 byte vectors" in proc.stderr


def test_simulate_on_the_simd_library_equals_the_casadi_map(monkeypatch):
    """simulate (constrained, prescribed speed with a ripple) computes its reported columns with
    the SIMD library's reduced entry point and any other output on first use with the full one:
    the same columns, warnings and outputs as through the CasADi map (PUMPSIM_FIT_KERNEL=scalar)."""
    from pumpsim.kernels import fast_kernel
    from pumpsim.simulate import simulate

    cfg = make_config("ellipse_4vanes", **{"effects.speed_ripple": [2, 0.02, 0.4]})
    if fast_kernel(cfg.parameters().structure) is None:
        pytest.skip("no SIMD library on this machine: simulate uses the CasADi map")
    fast = simulate(cfg, duration=0.03, rate=20000)
    monkeypatch.setenv("PUMPSIM_FIT_KERNEL", "scalar")
    ref = simulate(cfg, duration=0.03, rate=20000)
    assert fast.warnings == ref.warnings and fast.column_names() == ref.column_names()
    cols, rcols = fast.columns(), ref.columns()
    for name in ("torque", "s_0", "sdot_1", "normal_2", "slot1_3", "slot2_0"):
        assert np.max(np.abs(cols[name] - rcols[name])) <= SIMD_REL * np.max(np.abs(rcols[name])), name
    for name in ("alpha", "mu_housing", "torque_share", "ambiguity"):  # lazily evaluated outputs
        a, r = fast.extra[name], ref.extra[name]
        assert a.shape == r.shape and np.max(np.abs(a - r)) <= SIMD_REL * max(np.max(np.abs(r)), 1e-300), name
