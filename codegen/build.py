"""Compile a model variant to a C shared library in generated/<variant>-<key>/ with a manifest.

The cache key hashes everything that decides the generated code: the model source (codegen/ and the
runtime modules it embeds), the structure, the CasADi version, the compiler and its flags and a
schema version. The runtime compares the key before it trusts a library, so a stale library is never
used. Builds go to a temporary folder that is renamed into place (atomic on one file system).

`python -m codegen.build [--vanes N ...]` builds the bundled examples' variants (`make codegen`).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import casadi as ca

SCHEMA_VERSION = 1
ROOT = Path(__file__).resolve().parent.parent
# sources whose content decides the generated code
MODEL_SOURCES = sorted(
    [*(ROOT / "codegen").glob("*.py"), ROOT / "pumpsim" / "parameters.py", ROOT / "pumpsim" / "laws.py"]
)
CC = os.environ.get("PUMPSIM_CC", "gcc")
CFLAGS = ["-O2", "-fPIC", "-shared", "-std=c99"]
# derivative functions compiled into the library (CasADi's external() finds them by name)
# (forward mode: CVODES and the fits need few directions, and a full jacobian() over all of p would
# multiply the C size by ten). The contact model's ODEs carry their own exported Jacobians in x
# (ode_speed_jac, ode_torque_jac, assembled from one vane's scalar AD), which the runtime gives
# CVODES as the right-hand side's custom Jacobian.
FORWARD_DERIVATIVES = ("ode_rhs", "inverse_dynamics")
# second-order forward derivatives: CVODES forward sensitivities (transient fits) differentiate the
# first-order ones
SECOND_ORDER = ("ode_rhs",)


def generated_dir() -> Path:
    return Path(os.environ.get("PUMPSIM_GENERATED", ROOT / "generated"))


def compiler_version() -> str:
    try:
        out = subprocess.run([CC, "--version"], capture_output=True, text=True, check=True)
        return out.stdout.splitlines()[0]
    except (OSError, subprocess.CalledProcessError):
        return "unavailable"


def source_digest() -> str:
    h = hashlib.sha256()
    for path in MODEL_SOURCES:
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def cache_key(structure) -> str:
    payload = json.dumps({
        "schema": SCHEMA_VERSION, "structure": structure.as_dict(), "casadi": ca.__version__,
        "compiler": compiler_version(), "cflags": CFLAGS, "derivatives": FORWARD_DERIVATIVES,
        "second_order": SECOND_ORDER, "source": source_digest(),
    }, sort_keys=True)
    return hashlib.sha256(payload.encode()).hexdigest()[:20]


def variant_dir(structure, key: str | None = None) -> Path:
    return generated_dir() / f"{structure.variant}-{key or cache_key(structure)}"


def library_name(structure) -> str:
    return f"pumpsim_{structure.variant.replace('-', '_')}"


def build_variant(structure, log=None) -> Path:
    """Generate C, compile, write the manifest; return the variant folder."""
    from .model import build_model

    key = cache_key(structure)
    final = variant_dir(structure, key)
    if (final / "manifest.json").exists():
        return final
    log = log or (lambda msg: None)
    final.parent.mkdir(parents=True, exist_ok=True)
    _sweep_stale_temporaries(final.parent)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.tmp-", dir=final.parent))
    try:
        t0 = time.perf_counter()
        spec = build_model(structure)
        t_model = time.perf_counter() - t0
        name = library_name(structure)
        cg = ca.CodeGenerator(f"{name}.c", {"with_header": False})
        for fname, f in spec.functions.items():
            cg.add(f)
            if fname in FORWARD_DERIVATIVES:
                cg.add(f.forward(1))
            if fname in SECOND_ORDER:
                cg.add(f.forward(1).forward(1))
        cwd = os.getcwd()
        os.chdir(tmp)
        try:
            cg.generate()
        finally:
            os.chdir(cwd)
        t1 = time.perf_counter()
        lib = tmp / f"{name}.so"
        cmd = [CC, *CFLAGS, str(tmp / f"{name}.c"), "-o", str(lib), "-lm"]
        log(f"compiling {structure.variant} ({(tmp / f'{name}.c').stat().st_size // 1024} KiB of C)")
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            from pumpsim.errors import CodegenError

            raise CodegenError(f"compiling {structure.variant} failed:\n{proc.stderr[-2000:]}")
        t_compile = time.perf_counter() - t1
        manifest = {
            "key": key, "variant": structure.variant, "structure": structure.as_dict(),
            "library": lib.name, "library_sha256": hashlib.sha256(lib.read_bytes()).hexdigest(),
            "casadi": ca.__version__, "compiler": compiler_version(), "cflags": CFLAGS,
            "source_sha256": source_digest(), "schema": SCHEMA_VERSION,
            "functions": {
                n: {"inputs": f.name_in(), "outputs": f.name_out()} for n, f in spec.functions.items()
            },
            "parameters": [{"name": q.name, "unit": q.unit} for q in spec.parameters],
            "vane_outputs": list(spec.vane_outputs),
            "seconds": {"model": round(t_model, 3), "compile": round(t_compile, 3)},
        }
        (tmp / "manifest.json").write_text(json.dumps(manifest, indent=1))
        try:
            os.replace(tmp, final)
        except OSError:  # another process won the race: its build is as good as ours
            if not (final / "manifest.json").exists():
                raise
        log(f"built {final.name} in {t_model + t_compile:.1f} s "
            f"(model {t_model:.1f} s, C compile {t_compile:.1f} s)")
        return final
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def _sweep_stale_temporaries(folder: Path, age_s: float = 3600.0) -> None:
    now = time.time()
    for p in folder.glob(".*.tmp-*"):
        try:
            if now - p.stat().st_mtime > age_s:
                shutil.rmtree(p, ignore_errors=True)
        except OSError:
            pass


def main(argv=None) -> int:
    from pumpsim.config import load_config

    ap = argparse.ArgumentParser(description="Build the compiled kernels for configuration files.")
    ap.add_argument("configs", nargs="*", help="TOML configs whose variants to build")
    ap.add_argument("--model", choices=["constrained", "contact"], action="append")
    args = ap.parse_args(argv)
    configs = args.configs or sorted(str(p) for p in (ROOT / "examples").glob("*.toml"))
    seen = set()
    for path in configs:
        cfg = load_config(path, check_geometry=False)
        for model in args.model or ["constrained"]:
            st = cfg.structure_for(model)
            if st in seen:
                continue
            seen.add(st)
            d = build_variant(st, log=lambda m: print(m, flush=True))
            print(f"{st.variant}: {d}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
