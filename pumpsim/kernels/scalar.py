"""The scalar kernels: a variant's compiled CasADi functions, loaded never stale, and their
evaluation over many samples (CasADi's map, one sample per call, split over threads for large
batches). Loaded kernels are kept in memory per variant, model source and kernel folder."""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..errors import CodegenError
from ..model_spec import manifest as mf
from ..model_spec import outputs as kernel_outputs
from ..model_spec.parameters import Structure
from .cache import build_library, building_allowed, memo_key

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


def load_kernels(structure: Structure, build: bool | None = None, log=None) -> Kernels:
    """The compiled functions of `structure`'s variant, built when missing or stale (unless
    build=False or PUMPSIM_NO_BUILD=1: then CodegenError); loaded once per variant and process."""
    memo = memo_key(structure)
    if memo in _LOADED:
        return _LOADED[memo]
    fingerprint = memo[1]
    folder, manifest = mf.find_variant(structure, ca.__version__, fingerprint)
    if manifest is None:
        if not building_allowed(build):
            raise CodegenError(
                f"compiled kernel for {structure.variant} is missing or stale (source "
                f"{fingerprint}, CasADi {ca.__version__}, in {mf.generated_dir()}); "
                "build it with `pumpsim kernels build CONFIG` or unset PUMPSIM_NO_BUILD")
        folder = build_library(structure, log,
                               ready=lambda: mf.find_variant(structure, ca.__version__, fingerprint)[0])
        manifest = mf.trusted_manifest(folder, structure.variant, ca.__version__, fingerprint)
        if manifest is None:
            raise CodegenError(f"build of {structure.variant} did not produce a valid library")
    lib = str(folder / manifest["library"])
    fns = {name: ca.external(name, lib) for name in manifest["functions"]}
    k = Kernels(structure, manifest["key"], folder, manifest, fns)
    _LOADED[memo] = k
    return k


CHUNK = 20000  # samples per kernel call


def _per_vane(arr, n_vanes):
    """Mapped kernel output (1, n_vanes * n) -> (n_vanes, n)."""
    return np.asarray(arr).reshape(n_vanes, -1, order="F")


def _shaped(name, arr, n_vanes):
    """A mapped output in the shape the contract declares for it."""
    kind = kernel_outputs.shape(name)
    if kind == "sample":
        return arr.ravel()
    if kind == "vane":
        return _per_vane(arr, n_vanes)
    raise ValueError(f"kernel output '{name}' ({kind}) is not a per-sample or per-vane output")


def evaluate(kern, name, samples, p, n, outputs=None):
    """Evaluate a compiled function over n samples: `samples` are scalars or length-n arrays (one
    per leading input), `p` the parameter vector shared by all samples (the last input).
    `outputs`: the names to return (default all; converting is a good part of a short call)."""
    outs = None
    names = kern[name].name_out()
    keep = [i for i, nm in enumerate(names) if outputs is None or nm in outputs]
    pcol = np.asarray(p, dtype=float).reshape(-1, 1)
    for lo in range(0, n, CHUNK):
        hi = min(n, lo + CHUNK)
        call = []
        for a in samples:
            a = np.asarray(a, dtype=float)
            # 1-D: one value per sample; 2-D (k, n): a k-vector per sample; 0-D: shared
            call.append(a[lo:hi][None, :] if a.ndim == 1 else (a[:, lo:hi] if a.ndim == 2 else a))
        res = kern.mapped(name, hi - lo)(*call, pcol)
        res = res if isinstance(res, (list, tuple)) else [res]
        res = [np.asarray(res[i]) for i in keep]
        outs = res if outs is None else [np.concatenate([o, r], axis=1) for o, r in zip(outs, res)]
    N = kern.structure.vanes
    return {names[i]: _shaped(names[i], o, N) for i, o in zip(keep, outs)}


def inverse_dynamics(kern, p, theta, omega, omegadot, outputs=None):
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    n = theta.size
    omega = np.broadcast_to(np.asarray(omega, dtype=float), (n,)).copy()
    omegadot = np.broadcast_to(np.asarray(omegadot, dtype=float), (n,)).copy()
    return evaluate(kern, "inverse_dynamics", [theta, omega, omegadot], p, n, outputs)
