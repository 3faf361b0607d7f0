"""Compile a model variant to a C shared library in generated/<variant>-<key>/ with a manifest.

The one entry point the runtime uses is `build_library(structure, simd=False)` (imported lazily,
only when no trusted library exists). The key and the trust rules are the contract's
(`pumpsim.model_spec.manifest`): the key hashes the generated C source, the codegen options, the
CasADi version and the compiler flags. A build whose key already exists reuses that library and
only records this tree's source fingerprint in its manifest -- no compiler run. Builds go to a
temporary folder that is renamed into place (atomic on one file system).

`python -m pumpsim.codegen.build --structure '{"model": "constrained", "vanes": 4, ...}'` builds one
variant; `make codegen` builds the bundled examples' variants through the runtime
(`python -m pumpsim.kernels`).
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

from pumpsim.errors import CodegenError
from pumpsim.model_spec import manifest as mf
from pumpsim.model_spec.parameters import Structure

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
OPTIONS = {"cflags": CFLAGS, "forward_derivatives": list(FORWARD_DERIVATIVES),
           "second_order": list(SECOND_ORDER)}


def generate_c(spec, name: str, folder: Path) -> Path:
    """Write the C source of every exported function (and its derivatives) into folder."""
    cg = ca.CodeGenerator(f"{name}.c", {"with_header": False})
    for fname, f in spec.functions.items():
        cg.add(f)
        if fname in FORWARD_DERIVATIVES:
            cg.add(f.forward(1))
        if fname in SECOND_ORDER:
            cg.add(f.forward(1).forward(1))
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        cg.generate()
    finally:
        os.chdir(cwd)
    return folder / f"{name}.c"


def compile_library(structure, source: Path, log) -> tuple[Path, float]:
    lib = source.with_suffix(".so")
    cmd = [CC, *CFLAGS, str(source), "-o", str(lib), "-lm"]
    log(f"compiling {structure.variant} ({source.stat().st_size // 1024} KiB of C)")
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True)
    except OSError as e:
        raise CodegenError(f"compiling {structure.variant}: cannot run the C compiler '{CC}' "
                           f"({e.strerror}); install gcc or set PUMPSIM_CC") from None
    if proc.returncode != 0:
        raise CodegenError(f"compiling {structure.variant} failed:\n{proc.stderr[-2000:]}")
    return lib, time.perf_counter() - t0


def _record_fingerprint(folder: Path, fingerprint: str | None) -> None:
    m = mf.read_manifest(folder)
    if fingerprint is not None and fingerprint not in m.setdefault("source_fingerprints", []):
        m["source_fingerprints"].append(fingerprint)
        mf.write_manifest(folder, m)


def build_library(structure, simd: bool = False, log=None) -> Path:
    """The entry point the runtime uses (pumpsim.kernels.build_library): the variant's library, or
    with simd=True its SIMD inverse dynamics (codegen/simd.py); returns the folder."""
    if simd:
        from .simd import build_simd

        return build_simd(structure, log=log)
    return build_variant(structure, log=log)


def build_variant(structure, log=None) -> Path:
    """Generate C, compile unless a library with the same key exists, write the manifest; return
    the variant folder."""
    from .model import build_model

    log = log or (lambda msg: None)
    spec = None

    def generate(folder):
        nonlocal spec
        spec = build_model(structure)
        return generate_c(spec, mf.library_name(structure), folder), {}

    def compile_(source):
        lib, seconds = compile_library(structure, source, log)
        checks = {"functions": {n: {"inputs": f.name_in(), "outputs": f.name_out()} for n, f in spec.functions.items()},
                  "parameters": [{"name": q.name, "unit": q.unit} for q in spec.parameters]}
        return lib, checks, seconds

    def built(final, t_model, t_compile, checks):
        log(f"built {final.name} in {t_model + t_compile:.1f} s "
            f"(model {t_model:.1f} s, C compile {t_compile:.1f} s)")

    return install_library(structure, structure, OPTIONS, generate, compile_, built, log, stage="model")


def install_library(named, structure, options: dict, generate, compile_, built, log, stage: str) -> Path:
    """The one build procedure of every compiled library (the scalar variants here, the SIMD ones in
    simd.py): in a temporary folder under generated/, `generate(folder)` -> (C source path, manifest
    entries); its key (mf.content_key of the source, CasADi, `options`); a trusted library with that
    key is reused (only this tree's source fingerprint recorded, no compiler run); else
    `compile_(source)` -> (library path, manifest entries, seconds), the manifest is written and the
    folder renamed into place (atomic; a concurrent build of the same key wins the race harmlessly),
    and `built(final, generate seconds, compile seconds, entries)` reports it. `named` gives the
    folder's variant name, `structure` the manifest's structure; `stage` names the generation time."""
    fingerprint = mf.source_fingerprint()
    base = mf.generated_dir()
    base.mkdir(parents=True, exist_ok=True)
    _sweep_stale_temporaries(base)
    tmp = Path(tempfile.mkdtemp(prefix=f".{named.variant}.tmp-", dir=base))
    os.chmod(tmp, mf.umask_mode(directory=True))  # mkdtemp's 0700 would hide the kernels from colleagues
    try:
        t0 = time.perf_counter()
        source, generated = generate(tmp)
        t_gen = time.perf_counter() - t0
        c_sha = hashlib.sha256(source.read_bytes()).hexdigest()
        key = mf.content_key(c_sha, ca.__version__, options)
        final = mf.variant_dir(named, key)
        if mf.trusted_manifest(final, named.variant, ca.__version__, None) is not None:
            _record_fingerprint(final, fingerprint)  # same library: nothing to compile
            log(f"{final.name}: the model source changed, the generated code did not")
            return final
        lib, checks, t_compile = compile_(source)
        manifest = {
            "key": key, "variant": named.variant, "structure": structure.as_dict(), "library": lib.name,
            "library_sha256": hashlib.sha256(lib.read_bytes()).hexdigest(), "c_source": source.name,
            "c_source_sha256": c_sha, "casadi": ca.__version__, "options": options,
            "schema": mf.SCHEMA_VERSION, "source_fingerprints": [fingerprint] if fingerprint else [],
            **checks, **generated, "seconds": {stage: round(t_gen, 3), "compile": round(t_compile, 3)},
        }
        mf.write_manifest(tmp, manifest)
        try:
            os.replace(tmp, final)
        except OSError:  # another process won the race: its build is as good as ours
            if mf.read_manifest(final) is None:
                raise
            _record_fingerprint(final, fingerprint)
        built(final, t_gen, t_compile, checks)
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
    ap = argparse.ArgumentParser(description="Build compiled kernel variants (see pumpsim.kernels for configs).")
    ap.add_argument("--structure", action="append", required=True,
                    help='JSON of a Structure, e.g. \'{"model": "constrained", "vanes": 4, "harmonics": 0}\'')
    args = ap.parse_args(argv)
    for text in args.structure:
        st = Structure(**json.loads(text))
        d = build_variant(st, log=lambda m: print(m, flush=True))
        print(f"{st.variant}: {d}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
