"""The one build procedure of every compiled library (the scalar variants of build.py, the SIMD
ones of simd.py): generate into a temporary folder, reuse a trusted library of the same key, else
compile, write the manifest and rename the folder into place."""
from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import time
from pathlib import Path

import casadi as ca

from pumpsim.model_spec import manifest as mf

CC = os.environ.get("PUMPSIM_CC", "gcc")


def _record_fingerprint(folder: Path, fingerprint: str | None) -> None:
    m = mf.read_manifest(folder)
    if fingerprint is not None and fingerprint not in m.setdefault("source_fingerprints", []):
        m["source_fingerprints"].append(fingerprint)
        mf.write_manifest(folder, m)


def _retire_untrusted(final: Path, variant: str) -> None:
    """A folder at the build's final name whose library does not match its manifest (a truncated
    copy, an edited file) is moved aside and removed, so the new build takes its place; without
    this the rename fails on the folder that is there and every later run rebuilds in vain."""
    if final.exists() and mf.trusted_manifest(final, variant, ca.__version__, None) is None:
        aside = final.with_name(f".{final.name}.untrusted-{os.getpid()}")
        try:
            os.replace(final, aside)
        except OSError:  # another process moved it first
            return
        shutil.rmtree(aside, ignore_errors=True)


def install_library(named, structure, options: dict, generate, compile_, built, log, stage: str) -> Path:
    """The one build procedure of every compiled library (the scalar variants of build.py, the SIMD
    ones of simd.py): in a temporary folder under generated/, `generate(folder)` -> (C source path, manifest
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
        _retire_untrusted(final, named.variant)
        try:
            os.replace(tmp, final)
        except OSError:  # another process won the race: its build is as good as ours
            if mf.trusted_manifest(final, named.variant, ca.__version__, None) is None:
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
