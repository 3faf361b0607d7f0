"""Load compiled kernels, never stale ones.

The variant folder name carries the cache key (a hash of the model source, structure, CasADi
version and compiler flags). Before a library is loaded its manifest key and the library's own
hash are checked; a missing or mismatched variant is rebuilt (set PUMPSIM_NO_BUILD=1 to refuse
instead). Loaded kernels are cached in memory per key.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
from dataclasses import dataclass, field

import casadi as ca

from .errors import CodegenError
from .parameters import Structure

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


def _check(folder, key) -> dict | None:
    mpath = folder / "manifest.json"
    if not mpath.exists():
        return None
    manifest = json.loads(mpath.read_text())
    lib = folder / manifest.get("library", "")
    if manifest.get("key") != key or not lib.exists():
        return None
    if hashlib.sha256(lib.read_bytes()).hexdigest() != manifest.get("library_sha256"):
        return None
    return manifest


def load_kernels(structure: Structure, build: bool | None = None, log=None) -> Kernels:
    from codegen.build import build_variant, cache_key, variant_dir  # no SymPy import here

    key = cache_key(structure)
    if key in _LOADED:
        return _LOADED[key]
    folder = variant_dir(structure, key)
    manifest = _check(folder, key)
    if manifest is None:
        if build is None:
            build = os.environ.get("PUMPSIM_NO_BUILD", "") in ("", "0")
        if not build:
            raise CodegenError(
                f"compiled kernel for {structure.variant} is missing or stale (key {key}); "
                "run `make codegen` or unset PUMPSIM_NO_BUILD")
        if log is None:
            def log(msg):
                if sys.stderr.isatty():
                    print(f"pumpsim: {msg}", file=sys.stderr, flush=True)
        folder = build_variant(structure, log=log)
        manifest = _check(folder, key)
        if manifest is None:
            raise CodegenError(f"build of {structure.variant} did not produce a valid library")
    lib = str(folder / manifest["library"])
    fns = {name: ca.external(name, lib) for name in manifest["functions"]}
    k = Kernels(structure, key, folder, manifest, fns)
    _LOADED[key] = k
    return k
