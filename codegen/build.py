"""Compile a model variant to a C shared library in generated/<variant>-<key>/ with a manifest.

The one entry point the runtime uses is `build_library(structure, simd=False)` (imported lazily,
only when no trusted library exists). The key and the trust rules are the contract's
(`pumpsim.model_spec.manifest`): the key hashes the generated C source, the codegen options, the
CasADi version and the compiler flags. A build whose key already exists reuses that library and
only records this tree's source fingerprint in its manifest -- no compiler run. Builds go to a
temporary folder that is renamed into place (atomic on one file system).

`python -m pumpsim.codegen.build --structure '{"model": "constrained", "vanes": 4, ...}'` builds one
variant; `make codegen` builds the bundled examples' variants through the runtime
(`python -m pumpsim.variants`).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import casadi as ca

from pumpsim.errors import CodegenError
from pumpsim.model_spec import manifest as mf
from pumpsim.model_spec.parameters import Structure

from .install import CC, install_library

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
# The gas models' right-hand side runs once per Newton iteration of a long pump-down: CasADi's
# helpers (casadi_sq, casadi_fmax, ...) are global functions, which -fPIC code calls through the
# PLT unless they may not be interposed; inlined, pump_rhs and its Jacobian are ~10 % faster (same
# operations, same results).
MODEL_CFLAGS = {"pneumatic": ["-fno-semantic-interposition"],
                "pneumatic-contact": ["-fno-semantic-interposition"]}


def cflags_of(structure) -> list:
    return CFLAGS + MODEL_CFLAGS.get(structure.model, [])


def options_of(structure) -> dict:
    """The codegen options of a variant (part of its key)."""
    return {**OPTIONS, "cflags": cflags_of(structure)}


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
    cmd = [CC, *cflags_of(structure), str(source), "-o", str(lib), "-lm"]
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


def build_library(structure, simd: bool = False, log=None) -> Path:
    """The entry point the runtime uses (pumpsim.kernels.build_library): the variant's library, or
    with simd=True its SIMD inverse dynamics (codegen/simd.py); returns the folder."""
    if simd:
        from .simd import build_simd

        return build_simd(structure, log=log)
    return build_variant(structure, log=log)


def build_model(structure: Structure):
    """Every exported CasADi function of one variant (a `BuiltModel`; no compilation here), from
    the variant's own builder."""
    if structure.model == "pneumatic":  # spec §8: gas cells, valves, booster, motor
        from .pneumatic_model import build_pneumatic_model

        return build_pneumatic_model(structure)
    if structure.model == "pneumatic-contact":  # spec §8 with Model 1: vanes free in their slots
        from .pneumatic_contact_model import build_pneumatic_contact_model

        return build_pneumatic_contact_model(structure)
    if structure.model == "contact":  # Model 1
        from .contact_model import build_contact_model

        return build_contact_model(structure)
    from .constrained_model import build_constrained_model

    return build_constrained_model(structure)


def build_variant(structure, log=None) -> Path:
    """Generate C, compile unless a library with the same key exists, write the manifest; return
    the variant folder."""
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

    return install_library(structure, structure, options_of(structure), generate, compile_, built, log,
                           stage="model")


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
