"""The installable package: its layout, the kernel folder and `pumpsim kernels`, the bundled examples.
(.ci/wheel-check builds a wheel and runs it from a read-only site-packages.)"""
import json
import os
import shutil
import subprocess
import sys
import tomllib
from fnmatch import fnmatch
from pathlib import Path

import pytest

import pumpsim
from pumpsim import bundled, kernels, variants
from pumpsim.model_spec import manifest as mf
from tests.conftest import ROOT

PY = sys.executable


def _cli(*args, env=None, cwd=ROOT):
    return subprocess.run([PY, "-m", "pumpsim", *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          env={**os.environ, **(env or {})})


def _setuptools_layout():
    """packages, package_dir and package_data as setuptools reads them (setup.py + pyproject.toml)."""
    code = ("import json, warnings; warnings.simplefilter('ignore'); import setuptools\n"
            "from distutils.core import run_setup\n"
            "d = run_setup('setup.py', stop_after='config')\n"
            "print(json.dumps([d.packages, d.package_dir, d.package_data]))")
    r = subprocess.run([PY, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.splitlines()[-1])


def test_wheel_layout_has_every_package_and_no_top_level_codegen():
    packages, package_dir, package_data = _setuptools_layout()
    under_pumpsim = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "pumpsim").rglob("__init__.py")}
    assert under_pumpsim <= set(packages) and {"pumpsim.design", "pumpsim.pneumatics"} <= under_pumpsim
    assert package_dir == {"pumpsim.codegen": "codegen", "pumpsim.examples": "examples"}
    assert [p for p in packages if not p.startswith("pumpsim")] == []
    for pkg in packages:  # every package's folder exists: a mapped one, else its dotted path
        assert (ROOT / package_dir.get(pkg, pkg.replace(".", "/"))).is_dir(), pkg
    shipped = [f for f in (ROOT / "examples").rglob("*") if f.is_file() and f.suffix in (".toml", ".csv")]
    patterns = package_data["pumpsim.examples"]
    assert shipped and all(any(fnmatch(f.relative_to(ROOT / "examples").as_posix(), p) for p in patterns)
                           for f in shipped)
    assert "py.typed" in package_data["pumpsim"] and (ROOT / "pumpsim" / "py.typed").is_file()


def test_checkout_maps_pumpsim_codegen_to_its_codegen_folder():
    import pumpsim.codegen.build

    assert pumpsim.CHECKOUT == ROOT
    assert Path(pumpsim.codegen.build.__file__) == ROOT / "codegen" / "build.py"
    assert mf.codegen_dir() == ROOT / "codegen"


def test_version_comes_from_the_package_metadata():
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    r = _cli("--version")
    assert r.returncode == 0 and r.stdout.strip() == f"pumpsim {version}" == f"pumpsim {pumpsim.__version__}"


def test_kernel_folder_checkout_installed_and_override(monkeypatch, tmp_path):
    monkeypatch.delenv(mf.GENERATED_ENV)
    assert mf.generated_dir() == ROOT / "generated"
    monkeypatch.setattr(pumpsim, "CHECKOUT", None)  # an installed package: the per-user cache
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert mf.generated_dir() == tmp_path / "cache" / "pumpsim" / "kernels"
    monkeypatch.setenv(mf.GENERATED_ENV, str(tmp_path / "mine"))
    assert mf.generated_dir() == tmp_path / "mine"


@pytest.mark.parametrize("command", [("kernels", "build", "examples/test_rig.toml"),
                                     ("simulate", "examples/test_rig.toml", "--duration", "0.001")])
def test_unwritable_kernel_folder_is_exit_2_naming_it(tmp_path, command):
    blocked = tmp_path / "a-file"  # a file as parent: no one, root included, can create the folder
    blocked.write_text("")
    r = _cli(*command, env={mf.GENERATED_ENV: str(blocked / "kernels")})
    assert r.returncode == 2, r.stderr
    assert f"cannot write compiled kernels to {blocked / 'kernels'}" in r.stderr
    assert mf.GENERATED_ENV in r.stderr and "Traceback" not in r.stderr


def _copy_kernel(cache, dest, variant, fingerprints=None):
    """A copy of the session cache's trusted build of `variant` into dest (its manifest listing
    `fingerprints` instead, when given)."""
    src = next(f for f in sorted(cache.glob(f"{variant}-*"))
               if mf.trusted_manifest(f, variant, mf.read_manifest(f)["casadi"], mf.source_fingerprint()))
    shutil.copytree(src, dest / src.name)
    if fingerprints is not None:
        m = mf.read_manifest(dest / src.name)
        m["source_fingerprints"] = fingerprints
        mf.write_manifest(dest / src.name, m)
    return dest / src.name


def test_build_in_a_pipe_says_so_on_stderr(kernel_cache, tmp_path):
    """A library whose manifest lacks this source's fingerprint: the runtime regenerates the C
    (same key, so no compile) and says so although stderr is not a terminal."""
    kernels.load_kernels(mf_structure := pumpsim.load_config(ROOT / "examples" / "ellipse_1vane.toml")
                         .structure_for("constrained"))
    own = tmp_path / "kernels"
    folder = _copy_kernel(kernel_cache, own, mf_structure.variant, fingerprints=["another-source"])
    r = _cli("simulate", "examples/ellipse_1vane.toml", "--duration", "0.001", env={mf.GENERATED_ENV: str(own)})
    assert r.returncode == 0, r.stderr
    assert f"pumpsim: building the kernel {mf_structure.variant} in {own}" in r.stderr
    assert f"{folder.name}: the model source changed, the generated code did not" in r.stderr
    assert mf.source_fingerprint() in mf.read_manifest(folder)["source_fingerprints"]


def test_kernels_list_and_clear(kernel_cache, tmp_path):
    structure = pumpsim.load_config(ROOT / "examples" / "ellipse_1vane.toml").structure_for("constrained")
    kernels.load_kernels(structure)
    own = tmp_path / "kernels"
    ok = _copy_kernel(kernel_cache, own, structure.variant)
    stale = own / f"{structure.variant}-0123456789abcdef0123"
    shutil.copytree(ok, stale)
    m = mf.read_manifest(stale)
    m["source_fingerprints"] = ["another-source"]
    mf.write_manifest(stale, m)
    (own / "notes.txt").write_text("not a kernel")
    env = {mf.GENERATED_ENV: str(own)}
    r = _cli("kernels", "list", env=env)
    assert r.returncode == 0, r.stderr
    rows = {line.split()[-1]: line.split() for line in r.stdout.splitlines() if line.startswith(structure.variant)}
    assert rows[str(ok)][4] == "ok" and rows[str(stale)][4] == "stale" and rows[str(ok)][1] == m["key"]
    assert f"kernel folder: {own}" in r.stdout and "2 kernel(s)" in r.stdout
    r = _cli("kernels", "clear", "--stale", env=env)
    assert r.returncode == 0 and "removed 1 kernel folder(s)" in r.stdout, r.stderr
    assert ok.is_dir() and not stale.exists()
    r = _cli("kernels", "clear", env=env)
    assert r.returncode == 0 and not ok.exists() and (own / "notes.txt").is_file()


def test_kernels_build_covers_a_study_and_a_gas_config():
    grid = [st.variant for st in variants.structures_of(ROOT / "examples" / "studies" / "ellipse_grid.toml")]
    assert grid == [f"constrained-n{n}-h0" for n in range(2, 7)]
    gas = [st.variant for st in variants.structures_of(ROOT / "examples" / "evp_booster.toml")]
    assert gas[0] == "constrained-n4-h0" and "pneumatic-n4-h0" in gas


def test_example_copies_config_data_and_studies(tmp_path):
    r = _cli("example", "test_rig", tmp_path / "ex")
    assert r.returncode == 0, r.stderr
    for rel in ("test_rig.toml", "data/test_rig_measurement.csv", "studies/test_rig_tolerances.toml"):
        assert (tmp_path / "ex" / rel).read_bytes() == (ROOT / "examples" / rel).read_bytes()
    from pumpsim.design.study import load_study

    study = load_study(tmp_path / "ex" / "studies" / "test_rig_tolerances.toml")  # its ../test_rig.toml resolves
    assert study.variables
    assert _cli("example", "test_rig", tmp_path / "ex").returncode == 0  # identical files: nothing to do
    (tmp_path / "ex" / "test_rig.toml").write_text("# my edits\n")
    r = _cli("example", "test_rig", tmp_path / "ex")
    assert r.returncode == 2 and f"{tmp_path / 'ex' / 'test_rig.toml'} exists and differs" in r.stderr
    assert (tmp_path / "ex" / "test_rig.toml").read_text() == "# my edits\n"


def test_every_bundled_file_belongs_to_an_example():
    claimed = {rel for name in bundled.names() for rel in bundled.files(name)}
    shipped = {f.relative_to(ROOT / "examples").as_posix() for f in (ROOT / "examples").rglob("*")
               if f.suffix in (".toml", ".csv")}
    assert claimed == shipped
    r = _cli("example", "--list")
    assert r.returncode == 0 and all(f"{name}: " in r.stdout for name in bundled.names())
