"""Compiled library vs the in-process CasADi functions; cache behaviour."""
import json
import subprocess

import casadi as ca
import numpy as np
import pytest

import pumpsim.codegen.build as build
from pumpsim.kernels import scalar as kernels
from pumpsim.codegen.build import build_model
from pumpsim.contact import ode_with_jacobian
from pumpsim.model_spec import manifest as mf
from pumpsim.model_spec.parameters import Structure
from tests.conftest import kernel_and_p, make_config
from tests.tolerances import COMPILED_REL


@pytest.fixture(scope="module")
def ellipse():
    cfg = make_config("ellipse_4vanes", **{"housing.harmonics": [[3, 3e-5, 0.1]],
                                            "rotor.slot_tilt": 0.1, "vane.tip_radius": 0.001})
    kern, p, pv = kernel_and_p(cfg)
    spec = build_model(pv.structure)
    return kern, p, spec


def _close(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = max(np.abs(b).max(), 1e-300)
    assert np.max(np.abs(a - b)) <= COMPILED_REL * scale, (np.max(np.abs(a - b)), scale)


@pytest.mark.parametrize("name", ["inverse_dynamics", "forward_dynamics", "positions", "constraint",
                                  "constraint_jacobian", "acceleration_rhs", "ode_rhs"])
def test_compiled_equals_in_process_at_random_points(ellipse, name):
    kern, p, spec = ellipse
    f_c, f_i = kern[name], spec.functions[name]
    rng = np.random.default_rng(7)
    for _ in range(5):
        args = []
        for k, nm in enumerate(f_i.name_in()):
            if nm == "p":
                args.append(p)
            elif nm == "q":
                th = rng.uniform(0, 6.3)
                pos = kern["positions"](th, p)
                args.append(np.concatenate([[th], np.asarray(pos[0]).ravel(), np.asarray(pos[1]).ravel()]))
            elif nm == "qd":
                args.append(rng.normal(size=f_i.size1_in(k)) * [400] + 0)
            elif nm == "x":
                args.append([rng.uniform(0, 6.3), rng.uniform(50, 600)])
            elif nm == "theta":
                args.append(rng.uniform(0, 6.3))
            elif nm == "omega":
                args.append(rng.uniform(50, 600))
            else:
                args.append(rng.normal() * 0.01)
        for a, b in zip(f_c(*args) if f_c.n_out() > 1 else [f_c(*args)],
                        f_i(*args) if f_i.n_out() > 1 else [f_i(*args)]):
            _close(a, b)


def test_compiled_jacobian_equals_in_process(ellipse):
    """Derivatives through the compiled forward-mode functions match in-process AD."""
    kern, p, spec = ellipse
    th, w, wd, pp = ca.MX.sym("th"), ca.MX.sym("w"), ca.MX.sym("wd"), ca.MX.sym("p", p.size)
    inp = ca.vertcat(th, w, pp)
    jacs = []
    for f in (kern["inverse_dynamics"], spec.functions["inverse_dynamics"]):
        tq = f(th, w, wd, pp)[0]
        jacs.append(ca.Function("j", [inp, wd], [ca.jacobian(tq, inp)]))
    rng = np.random.default_rng(3)
    for _ in range(3):
        x = np.concatenate([[rng.uniform(0, 6.3), rng.uniform(100, 500)], p])
        _close(jacs[0](x, 3.0), jacs[1](x, 3.0))
    xo = ca.MX.sym("x", 2)
    for f in (kern["ode_rhs"], spec.functions["ode_rhs"]):
        jacs.append(ca.Function("jo", [xo, pp], [ca.jacobian(f(xo, 0.01, pp), xo)]))
    _close(jacs[2]([1.0, 300.0], p), jacs[3]([1.0, 300.0], p))


@pytest.mark.parametrize("name", ["ode_speed", "ode_torque"])
def test_compiled_contact_jacobian_equals_in_process(name):
    """The contact ODEs' compiled Jacobians (<name>_jac: one vane's scalar AD, assembled; for the
    torque drive through the implicit omegadot) equal in-process AD through the whole ODE at states
    in contact, in free flight and on the slot bottom, sliding both ways (friction on both sides
    of its reversal). The runtime's right-hand side carries them as its own Jacobian: the library
    holds no other derivative of the ODE, so CasADi's AD through it can only use them."""
    cfg = make_config("ellipse_4vanes", **{"housing.harmonics": [[3, 3e-5, 0.1]], "rotor.slot_tilt": 0.1})
    kern, p, pv = kernel_and_p(cfg, "contact")
    spec = build_model(pv.structure)
    x, drive, pp = ca.MX.sym("x", 10), ca.MX.sym("d"), ca.MX.sym("p", p.size)
    f = spec.functions[name]
    ad = ca.Function("ad", [x, drive, pp], [ca.jacobian(f(x, drive, pp), x), ca.jacobian(f(x, drive, pp), drive)])
    xdot = ode_with_jacobian(kern, name, p)
    runtime = ca.Function("rt", [x, drive], [ca.jacobian(xdot(x, drive), x)])
    assert kern[f"{name}_jac"].sparsity_out(0).nnz() < 100  # the vanes' blocks only, not dense
    s_c = np.asarray(kern["constrained_state"](0.3, 400.0, p)[0]).ravel()
    rng = np.random.default_rng(5)
    d = 0.002 if name == "ode_speed" else 0.05  # omegadot [rad/s2] or torque [N m]
    for s in (s_c + 1e-5, s_c - 2e-5, np.full(4, -1e-4)):  # pressed into the housing, free, on the slot bottom
        for _ in range(3):
            xs = np.concatenate([[0.3, rng.uniform(100, 500)], s, rng.normal(0, 0.5, 4)])
            jx, jd = kern[f"{name}_jac"](xs, d, p)
            ax, ad_d = ad(xs, d, p)
            _close(jx, ax)
            _close(jd, ad_d)
            _close(runtime(xs, d), ax)


@pytest.fixture
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("PUMPSIM_GENERATED", str(tmp_path))
    monkeypatch.setattr(kernels, "_LOADED", {})
    return tmp_path


def _count_compiles(monkeypatch):
    calls = []
    real = subprocess.run

    def spy(cmd, *a, **kw):
        if cmd and cmd[0] == build.CC and "-shared" in cmd:
            calls.append(cmd)
        return real(cmd, *a, **kw)

    monkeypatch.setattr(build.subprocess, "run", spy)
    return calls


def test_cache_hit_never_runs_the_compiler(private_cache, monkeypatch):
    st = Structure(vanes=2)
    calls = _count_compiles(monkeypatch)
    kernels.load_kernels(st)
    assert len(calls) == 1
    monkeypatch.setattr(kernels, "_LOADED", {})  # a new process: only the disk cache
    kernels.load_kernels(st)
    assert len(calls) == 1


def test_changed_model_expression_triggers_rebuild(private_cache, monkeypatch):
    """A source change the fingerprint sees sends the runtime to the builder; a changed expression
    gives new C, a new key and a compile; an unchanged expression gives the old key and no
    compile (the manifest then lists both fingerprints)."""
    import pumpsim.codegen.builder

    st = Structure(vanes=2)
    calls = _count_compiles(monkeypatch)
    k1 = kernels.load_kernels(st)
    fingerprint = mf.source_fingerprint()
    monkeypatch.setattr(mf, "source_fingerprint", lambda folders=None: fingerprint + "-refactored")
    k2 = kernels.load_kernels(st)  # same expressions: SymPy runs, the compiler does not
    assert k2.key == k1.key and len(calls) == 1
    assert {fingerprint, fingerprint + "-refactored"} <= set(mf.read_manifest(k2.folder)["source_fingerprints"])
    monkeypatch.setattr(mf, "source_fingerprint", lambda folders=None: fingerprint + "-edited")
    monkeypatch.setattr(pumpsim.codegen.builder, "CONSISTENCY_TOL", 2e-9)  # an edited expression
    k3 = kernels.load_kernels(st)
    assert k3.key != k1.key and len(calls) == 2 and k3.folder != k1.folder


def test_tampered_library_is_not_trusted(private_cache, monkeypatch):
    st = Structure(vanes=2)
    k = kernels.load_kernels(st)
    lib = k.folder / k.manifest["library"]
    # a new file in its place (the loaded one stays mapped): contents differ from the manifest
    tampered = lib.with_suffix(".new")
    tampered.write_bytes(lib.read_bytes() + b"\0")
    tampered.replace(lib)
    monkeypatch.setattr(kernels, "_LOADED", {})
    with pytest.raises(Exception, match="missing or stale"):
        kernels.load_kernels(st, build=False)


def test_a_damaged_library_is_replaced_by_its_rebuild(private_cache, monkeypatch):
    """A truncated library at the key's own folder: listed as damaged, then rebuilt into that
    folder (moved aside, not a rename onto it that fails and leaves every later run rebuilding)."""
    from pumpsim.kernels import cache

    st = Structure(vanes=2)
    k = kernels.load_kernels(st)
    lib = k.folder / k.manifest["library"]
    damaged = lib.with_suffix(".new")
    damaged.write_bytes(lib.read_bytes()[:4096])
    damaged.replace(lib)
    assert [c["damaged"] for c in cache.cached()] == [True]
    monkeypatch.setattr(kernels, "_LOADED", {})
    k2 = kernels.load_kernels(st)
    assert k2.folder == k.folder and k2.key == k.key
    assert mf.trusted_manifest(k2.folder, st.variant, ca.__version__, None) is not None
    assert [c["damaged"] for c in cache.cached()] == [False]


def test_manifest_records_key_orders_and_units(private_cache):
    k = kernels.load_kernels(Structure(vanes=2))
    m = json.loads((k.folder / "manifest.json").read_text())
    assert m["key"] == k.key and m["casadi"] == ca.__version__
    assert m["parameters"][0] == {"name": "rotor.radius", "unit": "m"}
    assert m["functions"]["inverse_dynamics"]["inputs"] == ["theta", "omega", "omegadot", "p"]
    # (the compile-time target, < 60 s, is checked by `make bench`, not by a test)


def test_concurrent_builds_of_one_variant_build_once(private_cache, monkeypatch):
    """A study's workers start together: the second build waits on the variant's lock and finds
    the first one's library (its `ready` lookup) instead of generating and compiling again."""
    import threading
    import time

    from pumpsim.kernels import cache

    st = Structure(vanes=2)
    built, made = [], {}

    def fake_build(structure, simd=False, log=None):
        built.append(structure.variant)
        time.sleep(0.3)  # long enough for the other thread to reach the lock
        made["folder"] = private_cache / "done"
        return made["folder"]

    monkeypatch.setattr(build, "build_library", fake_build)
    got = []
    threads = [threading.Thread(target=lambda: got.append(cache.build_library(st, log=lambda m: None,
                                                                              ready=lambda: made.get("folder"))))
               for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert built == [st.variant] and got == [private_cache / "done"] * 2
