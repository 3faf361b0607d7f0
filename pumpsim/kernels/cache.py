"""The kernel folder: where compiled libraries live, building them, listing and clearing them.

The runtime finds a variant's library by the contract's rules (`model_spec.manifest`): a
manifest of the same variant, schema and CasADi version whose key matches its recorded contents,
whose library has the recorded hash and which lists this tree's source fingerprint. No compiler
and no SymPy is involved in that check. A missing or stale variant is built through one entry
point, `pumpsim.codegen.build.build_library`, imported only here and only then (set
PUMPSIM_NO_BUILD=1 to refuse instead), into `model_spec.manifest.generated_dir()`:
$PUMPSIM_GENERATED, a checkout's generated/, else the per-user cache. Every build says so on
stderr.

`pumpsim kernels list|build|clear` manages the kernel folder (which variants a file needs and
building them ahead of use: `pumpsim.variants`).
"""
from __future__ import annotations

import hashlib

import logging
import os
import shutil
import sys
import tempfile
from pathlib import Path

import casadi as ca

from ..errors import KernelCacheError
from ..model_spec import manifest as mf
from ..model_spec.parameters import Structure


def memo_key(structure: Structure) -> tuple:
    """What a library loaded in this process stays valid for: the variant, this tree's model
    source and the kernel folder (loaded libraries are kept in memory under this key)."""
    return (structure, mf.source_fingerprint(), str(mf.generated_dir()))


BUILD_LOG = logging.getLogger("pumpsim")


def log_build(msg):
    """Build messages go to stderr, on a terminal or not: a build takes seconds to a minute. Under
    the command line (which sets up the `pumpsim` logger) they are its info messages, so -q hides
    them; a Python caller without logging set up still sees why a call takes a minute."""
    if BUILD_LOG.handlers:
        BUILD_LOG.info(msg)
    else:
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


def build_library(structure: Structure, log=None, simd: bool = False, ready=None):
    """The one way the runtime builds a library -- the variant's, or with simd=True its SIMD
    inverse dynamics -- through codegen's one entry point, imported here and nowhere else. One
    build per variant at a time on this kernel folder (a study's workers start together): the
    others wait for it, and `ready()` (the caller's lookup: a folder or None) then finds its
    library, so nothing is generated or compiled twice."""
    from filelock import FileLock

    log = log or log_build
    base = writable_dir()
    with FileLock(str(base / f".{structure.variant}{'-simd' if simd else ''}.build.lock")):
        found = ready() if ready is not None else None
        if found is not None:
            return found
        log(f"building the {'SIMD ' if simd else ''}kernel {structure.variant} in {base} "
            "(once per model variant; up to a minute)")
        from ..codegen.build import build_library as build

        return build(structure, simd=simd, log=log)


def _size(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def cached() -> list[dict]:
    """Every compiled library in generated_dir(): variant, key, size [bytes], folder and whether
    this installation loads it (same model source, CasADi and, for SIMD, CPU) -- else stale."""
    from ..model_spec.simd import runs_here

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
        lib = folder / str(m.get("library", ""))
        damaged = not lib.is_file() or hashlib.sha256(lib.read_bytes()).hexdigest() != m.get("library_sha256")
        out.append({"variant": variant, "key": m.get("key", "?"), "size": _size(folder),
                    "folder": folder, "usable": usable, "damaged": damaged})
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
