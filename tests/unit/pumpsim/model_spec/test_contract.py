"""The contract between codegen and the runtime: imports, cache key, prebuilt libraries."""
import ast
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pumpsim.model_spec import manifest as mf
from pumpsim.model_spec import outputs
from tests.conftest import ROOT

PY = sys.executable
# what codegen may load of pumpsim: the lazy package, the leaf errors module and the contract
CONTRACT_MODULES = ("pumpsim", "pumpsim.errors", "pumpsim.model_spec")


def _modules_after(code, cwd=ROOT, env=None):
    script = code + "\nimport sys, json; print(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([PY, "-c", script], cwd=cwd, env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_codegen_imports_no_runtime_module():
    mods = _modules_after("import pumpsim.codegen, pumpsim.codegen.build, pumpsim.codegen.builder, pumpsim.codegen.constrained_model, "
                          "pumpsim.codegen.contact_model, pumpsim.codegen.numpy_model")
    loaded = [m for m in mods if m.split(".")[0] == "pumpsim" and not m.startswith("pumpsim.codegen")]
    runtime = [m for m in loaded if m not in CONTRACT_MODULES and not m.startswith("pumpsim.model_spec.")]
    assert "pumpsim.model_spec" in loaded and runtime == []


def _imports(folder, package):
    """(file, absolute module) for every import in the source under ROOT/folder, installed as
    `package`, in function bodies too (relative imports resolved)."""
    for path in sorted((ROOT / folder).rglob("*.py")):
        rel = path.relative_to(ROOT / folder)
        here = [package, *rel.parent.parts]
        for node in ast.walk(ast.parse(path.read_text())):
            name = path.relative_to(ROOT).as_posix()
            if isinstance(node, ast.Import):
                yield from ((name, a.name) for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = here[:len(here) - node.level + 1] if node.level else []
                mods = [node.module] if node.module else [a.name for a in node.names]
                yield from ((name, ".".join([*base, m])) for m in mods)


def test_codegen_is_imported_as_pumpsim_codegen():
    """No top-level `codegen` is installed, so no source may import one."""
    for folder, package in (("pumpsim", "pumpsim"), ("codegen", "pumpsim.codegen"), ("tests", "tests"),
                            ("bench", "bench")):
        assert [(f, m) for f, m in _imports(folder, package) if m.split(".")[0] == "codegen"] == []


def test_no_import_anywhere_crosses_the_contract():
    """Also the imports inside functions (which the sys.modules checks cannot see unless they run):
    codegen names only the contract of pumpsim, and the runtime names codegen in one place, the
    lazily imported builder entry point."""
    crossing = [(f, m) for f, m in _imports("codegen", "pumpsim.codegen")
                if m.split(".")[0] == "pumpsim" and not m.startswith("pumpsim.codegen")
                and m not in CONTRACT_MODULES and not m.startswith("pumpsim.model_spec.")]
    assert crossing == []
    into_codegen = [(f, m) for f, m in _imports("pumpsim", "pumpsim") if m.startswith("pumpsim.codegen")]
    assert into_codegen == [("pumpsim/kernels/cache.py", "pumpsim.codegen.build")]


def test_runtime_imports_no_codegen_and_no_sympy():
    """Import, load a config and simulate with a prebuilt variant: neither codegen nor SymPy."""
    mods = _modules_after(
        "import pumpsim\n"
        "cfg = pumpsim.load_config('examples/ellipse_4vanes.toml')\n"
        "res = pumpsim.simulate(cfg, duration=0.002, rate=5000)\n"
        "assert res['torque'].size == 11\n")
    assert [m for m in mods if m.startswith("pumpsim.codegen") or m.split(".")[0] == "sympy"] == []


def test_fingerprint_ignores_comments_and_docstrings_not_expressions():
    src = (ROOT / "codegen" / "builder.py").read_text()
    base = mf.file_fingerprint(src)
    commented = src.replace("import math\n", "import math  # a new comment\n# and a line\n", 1)
    redocumented = src.replace('"""3x3 linear solve by Cramer', '"""A reworded docstring; 3x3 solve by Cramer', 1)
    assert commented != src and redocumented != src
    assert mf.file_fingerprint(commented) == base and mf.file_fingerprint(redocumented) == base
    edited = src.replace("CONSISTENCY_TOL = 1e-9", "CONSISTENCY_TOL = 2e-9", 1)
    assert edited != src and mf.file_fingerprint(edited) != base


def _tree_copy(tmp_path, edit=None):
    """A copy of the source tree (pumpsim/, codegen/) with `edit` applied to codegen/builder.py."""
    tree = tmp_path / "src"
    for pkg in ("pumpsim", "codegen"):
        shutil.copytree(ROOT / pkg, tree / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    if edit:
        model = tree / "codegen" / "builder.py"
        model.write_text(edit(model.read_text()))
    return tree


_LOAD = ("import pumpsim, pumpsim.kernels as k\n"
         "cfg = pumpsim.load_config({cfg!r})\n"
         "print(k.load_kernels(cfg.parameters().structure).key)\n")


def _load_without_compiler(tree, cfg_path):
    bare = tree.parent / "bin"  # PATH holds no compiler; PUMPSIM_NO_BUILD forbids building
    bare.mkdir(exist_ok=True)
    env = {**os.environ, "PATH": str(bare), "PUMPSIM_NO_BUILD": "1", "PYTHONPATH": str(tree)}
    assert shutil.which("gcc", path=env["PATH"]) is None
    return subprocess.run([PY, "-c", _LOAD.format(cfg=str(cfg_path))], cwd=tree, env=env,
                          capture_output=True, text=True)


def test_prebuilt_loads_without_compiler_after_comment_edit(tmp_path):
    cfg = ROOT / "examples" / "ellipse_4vanes.toml"
    tree = _tree_copy(tmp_path, lambda s: "# a comment-only change\n" + s.replace(
        "NEWTON_ITERATIONS = {", "NEWTON_ITERATIONS = {  # reworded\n    ", 1))
    out = _load_without_compiler(tree, cfg)
    assert out.returncode == 0, out.stderr
    key = out.stdout.split()[-1]
    assert any(Path(os.environ["PUMPSIM_GENERATED"]).glob(f"constrained-n4-h0-{key}"))


def test_changed_expression_is_stale_without_compiler(tmp_path):
    cfg = ROOT / "examples" / "ellipse_4vanes.toml"
    tree = _tree_copy(tmp_path, lambda s: s.replace("CONSISTENCY_TOL = 1e-9", "CONSISTENCY_TOL = 3e-9", 1))
    out = _load_without_compiler(tree, cfg)
    assert out.returncode != 0 and "missing or stale" in out.stderr


def test_every_exported_output_has_a_declared_shape():
    for model in ("constrained", "contact"):
        for name, sig in outputs.signatures(model).items():
            for o in sig.outputs:
                assert outputs.shape(o) in ("sample", "vane", "other"), (name, o)
    with pytest.raises(ValueError, match="the contract declares"):
        outputs.check_signature("constrained", "inverse_dynamics", ["theta", "omega", "omegadot", "p"],
                                ["torque", "new_output"])
