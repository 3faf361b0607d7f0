"""Load compiled kernels, never stale ones.

The runtime finds a variant's library by the contract's rules (`model_spec.manifest`): a
manifest of the same variant, schema and CasADi version whose key matches its recorded contents,
whose library has the recorded hash and which lists this tree's source fingerprint. No compiler
and no SymPy is involved in that check. A missing or stale variant is built through one entry
point, `pumpsim.codegen.build.build_library`, imported only then (set PUMPSIM_NO_BUILD=1 to
refuse instead). Loaded kernels are cached in memory per variant and source.

`python -m pumpsim.kernels [CONFIG ...] [--model contact]` loads (building when needed) the
variants of configuration files; `make codegen` runs it on the bundled examples.
"""
from __future__ import annotations

import argparse
import os
import sys
from dataclasses import dataclass, field

import casadi as ca

from .errors import CodegenError
from .model_spec import manifest as mf
from .model_spec.parameters import MODELS, Structure

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


def _log_if_terminal(msg):
    if sys.stderr.isatty():
        print(f"pumpsim: {msg}", file=sys.stderr, flush=True)


def building_allowed(build: bool | None) -> bool:
    """build if given, else True unless PUMPSIM_NO_BUILD is set (to anything but 0)."""
    return os.environ.get("PUMPSIM_NO_BUILD", "") in ("", "0") if build is None else build


def build_library(structure: Structure, log=None, simd: bool = False):
    """The one way the runtime builds a library -- the variant's, or with simd=True its SIMD
    inverse dynamics -- through codegen's one entry point, imported here and nowhere else."""
    from .codegen.build import build_library as build

    return build(structure, simd=simd, log=log or _log_if_terminal)


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
                "run `make codegen` or unset PUMPSIM_NO_BUILD")
        folder = build_library(structure, log)
        manifest = mf.trusted_manifest(folder, structure.variant, ca.__version__, fingerprint)
        if manifest is None:
            raise CodegenError(f"build of {structure.variant} did not produce a valid library")
    lib = str(folder / manifest["library"])
    fns = {name: ca.external(name, lib) for name in manifest["functions"]}
    k = Kernels(structure, manifest["key"], folder, manifest, fns)
    _LOADED[memo] = k
    return k


def main(argv=None) -> int:
    from .config import load_config

    ap = argparse.ArgumentParser(description="Load (and build when missing or stale) the compiled "
                                             "kernels of configuration files.")
    ap.add_argument("configs", nargs="+", help="TOML configs whose variants to load")
    ap.add_argument("--model", choices=MODELS, action="append")
    args = ap.parse_args(argv)
    seen = set()
    for path in args.configs:
        cfg = load_config(path, check_geometry=False)
        for model in args.model or ["constrained"]:
            st = cfg.structure_for(model)
            if st not in seen:
                seen.add(st)
                k = load_kernels(st, log=lambda m: print(m, flush=True))
                print(f"{st.variant}: {k.folder}")
        if cfg.pneumatic is not None:  # spec §8 configs also get their gas-cell variant
            from .pneumatics.kernel import structure_of

            models = ["constrained"] + (["contact"] if cfg.contact_given else [])  # Model 1 with gas too
            for st in (structure_of(cfg, m) for m in models):
                if st not in seen:
                    seen.add(st)
                    print(f"{st.variant}: {load_kernels(st, log=lambda m: print(m, flush=True)).folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
