"""Load compiled kernels, never stale ones.

The runtime finds a variant's library by the contract's rules (`model_spec.manifest`): a
manifest of the same variant, schema and CasADi version whose key matches its recorded contents,
whose library has the recorded hash and which lists this tree's source fingerprint. No compiler
and no SymPy is involved in that check. A missing or stale variant is built through one entry
point, `pumpsim.codegen.build.build_library`, imported only then (set PUMPSIM_NO_BUILD=1 to
refuse instead), into `model_spec.manifest.generated_dir()`: $PUMPSIM_GENERATED, a checkout's
generated/, else the per-user cache. Every build says so on stderr. Loaded kernels are cached in
memory per variant and source.

`pumpsim kernels list|build|clear` manages the kernel folder (which variants a file needs and
building them ahead of use: `variants.py`).
"""
from __future__ import annotations

import os
import shutil
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca

from .errors import CodegenError, KernelCacheError
from .model_spec import manifest as mf
from .model_spec.parameters import Structure

_LOADED: dict = {}


def default_threads() -> int:
    try:
        return max(1, int(os.environ.get("PUMPSIM_THREADS", "") or (os.cpu_count() or 1)))
    except ValueError:
        return 1


@dataclass
class Kernels:
    structure: Structure
    key: str
    folder: object
    manifest: dict
    functions: dict = field(default_factory=dict)
    _maps: dict = field(default_factory=dict)

    def __getitem__(self, name: str) -> ca.Function:
        try:
            return self.functions[name]
        except KeyError:
            raise CodegenError(f"kernel {self.structure.variant} has no function '{name}'") from None

    def mapped(self, name: str, n: int, threads: int | None = None) -> ca.Function:
        """The kernel `name` over n samples (see map_samples), cached."""
        k = (name, n, threads)
        if k not in self._maps:
            self._maps[k] = map_samples(self[name], n, threads)
        return self._maps[k]


def map_samples(f: ca.Function, n: int, threads: int | None = None) -> ca.Function:
    """f evaluated over n samples (columns) in one call; large batches are spread over threads
    (PUMPSIM_THREADS, default: the machine's cores) -- the compiled code is thread-safe."""
    if threads is None:
        threads = default_threads() if n >= 2000 else 1
    return f.map(n, "thread", threads) if threads > 1 else f.map(n, "serial")


FAST_THREADED = 20000  # samples from which a SIMD call is split over threads (below: ~1 ms, not worth it)
_FAST: dict = {}


def fast_kernel(structure: Structure):
    """The SIMD inverse dynamics of a constrained variant (pumpsim.fastkernel, built beside the
    scalar library when missing), or None where it cannot be built or PUMPSIM_FIT_KERNEL=scalar:
    then callers use the CasADi map. Looked up once per variant and process."""
    if os.environ.get("PUMPSIM_FIT_KERNEL", "") == "scalar" or structure.model != "constrained":
        return None
    memo = (structure, mf.source_fingerprint(), str(mf.generated_dir()))
    if memo not in _FAST:
        from .fastkernel import load_fast_kernel

        try:
            fk = load_fast_kernel(structure, fallback=True)
        except CodegenError:  # e.g. PUMPSIM_NO_BUILD with no SIMD library: the scalar kernel runs
            fk = None
        _FAST[memo] = fk if fk is not None and fk.simd else None
    return _FAST[memo]


def log_build(msg):
    """Build messages go to stderr, on a terminal or not: a build takes seconds to a minute."""
    print(f"pumpsim: {msg}", file=sys.stderr, flush=True)


def writable_dir() -> Path:
    """generated_dir(), created if needed, or KernelCacheError (exit 2) naming it and the way out."""
    base = mf.generated_dir()
    try:
        base.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=base):
            pass
    except OSError as e:
        raise KernelCacheError(
            f"cannot write compiled kernels to {base} ({e.strerror or e}); set {mf.GENERATED_ENV} to a "
            f"writable folder, or build them beforehand there with `pumpsim kernels build CONFIG`") from None
    return base


def building_allowed(build: bool | None) -> bool:
    """build if given, else True unless PUMPSIM_NO_BUILD is set (to anything but 0)."""
    return os.environ.get("PUMPSIM_NO_BUILD", "") in ("", "0") if build is None else build


def build_library(structure: Structure, log=None, simd: bool = False):
    """The one way the runtime builds a library -- the variant's, or with simd=True its SIMD
    inverse dynamics -- through codegen's one entry point, imported here and nowhere else."""
    log = log or log_build
    base = writable_dir()
    log(f"building the {'SIMD ' if simd else ''}kernel {structure.variant} in {base} "
        "(once per model variant; up to a minute)")
    from .codegen.build import build_library as build

    return build(structure, simd=simd, log=log)


def load_kernels(structure: Structure, build: bool | None = None, log=None) -> Kernels:
    fingerprint = mf.source_fingerprint()
    memo = (structure, fingerprint, str(mf.generated_dir()))
    if memo in _LOADED:
        return _LOADED[memo]
    folder, manifest = mf.find_variant(structure, ca.__version__, fingerprint)
    if manifest is None:
        if not building_allowed(build):
            raise CodegenError(
                f"compiled kernel for {structure.variant} is missing or stale (source "
                f"{fingerprint}, CasADi {ca.__version__}, in {mf.generated_dir()}); "
                "build it with `pumpsim kernels build CONFIG` or unset PUMPSIM_NO_BUILD")
        folder = build_library(structure, log)
        manifest = mf.trusted_manifest(folder, structure.variant, ca.__version__, fingerprint)
        if manifest is None:
            raise CodegenError(f"build of {structure.variant} did not produce a valid library")
    lib = str(folder / manifest["library"])
    fns = {name: ca.external(name, lib) for name in manifest["functions"]}
    k = Kernels(structure, manifest["key"], folder, manifest, fns)
    _LOADED[memo] = k
    return k


def _size(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def cached() -> list[dict]:
    """Every compiled library in generated_dir(): variant, key, size [bytes], folder and whether
    this installation loads it (same model source, CasADi and, for SIMD, CPU) -- else stale."""
    from .model_spec.simd import runs_here

    base = mf.generated_dir()
    fingerprint = mf.source_fingerprint()
    out = []
    for folder in sorted(base.glob("*-*")) if base.is_dir() else []:
        m = mf.read_manifest(folder)
        if not folder.is_dir() or folder.name.startswith(".") or m is None:
            continue
        variant = m.get("variant", "?")
        trusted = mf.trusted_manifest(folder, variant, ca.__version__, fingerprint)
        usable = trusted is not None and (not variant.endswith("-simd") or runs_here(trusted))
        out.append({"variant": variant, "key": m.get("key", "?"), "size": _size(folder),
                    "folder": folder, "usable": usable})
    return out


def clear(stale_only: bool = False) -> list[dict]:
    """Remove the compiled libraries of generated_dir() (stale_only: those this installation does
    not load); returns what was removed."""
    gone = [k for k in cached() if not (stale_only and k["usable"])]
    if gone:
        writable_dir()
    for k in gone:
        try:
            shutil.rmtree(k["folder"])
        except OSError as e:
            raise KernelCacheError(f"cannot remove {k['folder']} ({e.strerror or e}); "
                                   f"{mf.GENERATED_ENV} moves the kernel folder") from None
    return gone
