"""Inverse dynamics of many samples per call, in SIMD lanes, on NumPy buffers.

`load_fast_kernel(structure)` loads (or builds) the SIMD library of codegen.simd beside the scalar
one; calling it evaluates the constrained model's inverse dynamics for arrays theta, omega, omegadot
with one parameter vector for all samples, one per block of consecutive samples (many designs, e.g.
one revolution each) or one per sample. No CasADi objects are involved: ctypes hands the library
pointers to float64 arrays and it writes into one preallocated (1 + 17 N, n) array (pass `out=` to
reuse it: fresh pages cost ~0.2 us per sample). `outputs=` names the outputs wanted: the call then
runs the smallest entry point that computes them (model_spec.simd.SUBSETS: the torque alone, one
row; the simulation's reported columns) and the buffer has only that entry's rows. ctypes
releases the GIL during the call, so `threads > 1` splits the samples over threads.
`jacobian(theta, omega, omegadot, p, seeds)` gives the torque and its exact derivatives along
directions in (theta, omega, omegadot, p) in the same sample-parallel form (`has_jacobian`: the
library has these entries).

Never stale: the scalar library's contract (pumpsim.model_spec.manifest: key over C source and
options, library hash, this tree's source fingerprint) plus this CPU's instruction-set flags and C
library (pumpsim.model_spec.simd); a missing or mismatched library is built through
kernels.cache.build_library (codegen's one entry point; PUMPSIM_NO_BUILD=1: refused). On a
machine where no SIMD library can be built (gcc leaves the loops scalar, no vector math) `load_fast_kernel` returns
the same interface over the scalar CasADi kernel (`.simd` False; fallback=False raises instead).

`fast_kernel(structure)` is the SIMD library where this machine has one (else None), and
`sampled_inverse_dynamics` evaluates through the fastest kernel available.
"""
from __future__ import annotations

import ctypes
import os
from concurrent.futures import ThreadPoolExecutor

import casadi as ca
import numpy as np

from ..errors import CodegenError, ConfigError
from ..model_spec.outputs import VANE_OUTPUTS
from ..model_spec.parameters import Structure, layout
from ..model_spec.simd import SUBSETS, find_simd
from .cache import build_library, building_allowed, log_build, memo_key
from .scalar import default_threads, evaluate, inverse_dynamics, load_kernels

_LOADED: dict = {}
_c_long, _ptr = ctypes.c_long, ctypes.c_void_p


def _address(a: np.ndarray) -> int:
    """Address of a C-contiguous array's first element (cheaper than a.ctypes.data)."""
    return a.__array_interface__["data"][0]


class FastInverseDynamics:
    """Inverse dynamics over samples in SIMD lanes (see the module docstring)."""

    simd = True

    def __init__(self, structure: Structure, folder, manifest: dict):
        self.structure, self.folder, self.manifest = structure, folder, manifest
        self.key = manifest["key"]
        self.vanes, self.n_params = manifest["vanes"], manifest["n_params"]
        self.outputs = tuple(manifest["outputs"])  # torque, then the per-vane outputs
        self._set_layouts(manifest["subsets"])
        lib = ctypes.CDLL(str(folder / manifest["library"]))
        self._entries = {}
        for key in self.layouts:
            fns = [getattr(lib, f"pumpsim_simd{'' if key is None else '_' + key}_{kind}")
                   for kind in ("blocks", "samples")]
            for fn in fns:
                fn.argtypes = [_c_long, _ptr, _ptr, _ptr, _ptr, _c_long, _ptr, _c_long]
                fn.restype = ctypes.c_int
            self._entries[key] = fns
        self._jac = None
        if "jacobian" in manifest:  # the torque's derivatives along directions (seeds)
            self._jac = [getattr(lib, f"pumpsim_simd_jac_{kind}") for kind in ("blocks", "samples")]
            for fn in self._jac:
                fn.argtypes = [_c_long, _ptr, _ptr, _ptr, _ptr, _c_long, _c_long, _ptr, _ptr, _c_long]
                fn.restype = ctypes.c_int
        self._reduce = None
        if "reductions" in manifest:  # a design study's per-design numbers (codegen/simd_reduce.py)
            self._reduce = lib.pumpsim_simd_reduce_designs
            self._reduce.argtypes = [_c_long, _c_long, _ptr, _ptr, _ptr, _c_long, _ptr, _ptr, _ptr, _c_long]
            self._reduce.restype = ctypes.c_int
        self._lib = lib

    @property
    def has_jacobian(self) -> bool:
        return self._jac is not None

    def jacobian(self, theta, omega, omegadot, p, seeds, block: int | None = None, out=None,
                 threads: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """The torque and its derivatives along directions: seeds (nd, 3 + n_p), each row a direction
        in (theta, omega, omegadot, p), the same for every sample; p as for a call. Exact (CasADi's
        reverse-mode gradient of the same expressions, contracted with the seeds in the library).
        Returns (torque (n,), derivatives (nd, n)), views into `out` (1 + nd, n): see jacobian_array."""
        if self._jac is None:
            raise CodegenError(f"the SIMD library of {self.structure.variant} has no Jacobian entries")
        theta, omega, omegadot, p, n = self._arguments(theta, omega, omegadot, p)
        seeds = np.ascontiguousarray(np.atleast_2d(np.asarray(seeds, dtype=float)))
        if seeds.ndim != 2 or seeds.shape[1] != 3 + self.n_params:
            raise ConfigError(f"seeds must have 3 + {self.n_params} entries per direction (theta, omega, "
                              f"omegadot, p), got shape {seeds.shape}")
        nd = seeds.shape[0]
        out = self._checked_out(out, 1 + nd, n, "jacobian_array(n, directions)")
        self._run(self._jac, n, theta, omega, omegadot, p, block, out, threads, (nd, _address(seeds)))
        return out[0], out[1:]

    @staticmethod
    def jacobian_array(n: int, directions: int) -> np.ndarray:
        """An output buffer for `jacobian` (n samples, that many directions), to reuse across calls."""
        return np.empty((1 + directions, n))

    @property
    def has_reductions(self) -> bool:
        return self._reduce is not None

    def reduce_designs(self, theta, omega, p, consts, tolerances, alike: int = 1) -> np.ndarray:
        """A design study's numbers per design, each design's outputs reduced in cache
        (codegen/simd_reduce.py): p (designs, n_p), omega (designs,) their speeds (omegadot 0), theta
        (n,) the rotor angles they share. Returns (designs, columns + vanes x alike) in
        manifest["reductions"]["columns"]'s order, then the per-vane friction powers. consts
        (designs, 4): c_visc, L, l_m, bearing torque; tolerances: (position, paradox); alike > 1
        (1-vane library): the vane stands for that many."""
        if self._reduce is None:
            raise CodegenError(f"the SIMD library of {self.structure.variant} has no reduction entry")
        theta, p, omega, consts, tol = (np.ascontiguousarray(x, dtype=float)
                                        for x in (theta, np.atleast_2d(p), np.atleast_1d(omega), consts, tolerances))
        D = p.shape[0]
        if omega.shape == (1,):
            omega = np.full(D, omega[0])
        got = [x.shape for x in (theta, p, omega, consts, tol)]
        if got[1:] != [(D, self.n_params), (D,), (D, 4), (2,)] or theta.ndim != 1 or not theta.size:
            raise ConfigError(f"theta must be (n,), p (designs, {self.n_params}), omega (designs,), consts "
                              f"(designs, 4) and tolerances (2,), got shapes {', '.join(map(str, got))}")
        res = np.empty((D, len(self.manifest["reductions"]["columns"]) + self.vanes * alike))
        code = self._reduce(D, theta.size, *(_address(x) for x in (theta, omega, p)), alike,
                            *(_address(x) for x in (consts, tol, res)), res.shape[1])
        if code:
            raise CodegenError(f"the SIMD reduction of {self.structure.variant} refused its arguments"
                               + (" (out of memory)" if code == 2 else ""))
        return res

    def _set_layouts(self, subsets: dict):
        """The vane outputs of each entry point: None the full one, then the reduced SUBSETS."""
        self.layouts = {None: self.outputs[1:], **{k: tuple(v) for k, v in subsets.items()}}
        self.rows = self.rows_of(None)

    def rows_of(self, key) -> int:
        return 1 + len(self.layouts[key]) * self.vanes

    def entry_for(self, outputs) -> str | None:
        """The entry point with the fewest rows that computes every name in `outputs` (None: all)."""
        if outputs is None:
            return None
        if isinstance(outputs, str):
            outputs = (outputs,)
        want = set(outputs) - {"torque"}
        unknown = sorted(want - set(self.outputs))
        if unknown:
            raise ConfigError(f"no inverse-dynamics output {', '.join(map(repr, unknown))}; available: "
                              f"{', '.join(self.outputs)}")
        return min((k for k, names in self.layouts.items() if want <= set(names)), key=self.rows_of)

    # -- arguments ---------------------------------------------------------------------------------
    def _samples_array(self, name, a, n):
        a = np.asarray(a, dtype=float)
        if a.ndim == 0:
            return np.full(n, a)
        if a.ndim > 1 or a.size != n:
            raise ConfigError(f"{name} must be a scalar or have {n} samples, got shape {a.shape}")
        return np.ascontiguousarray(a)

    def output_array(self, n: int, outputs=None) -> np.ndarray:
        """An output buffer for n samples (and the `outputs` of the call), to pass as `out=` to
        repeated calls. `out` may also be a column range of a wider array (rows contiguous, any
        row stride)."""
        return np.empty((self.rows_of(self.entry_for(outputs)), n))

    def _out_array(self, out, key, n):
        return self._checked_out(out, self.rows_of(key), n, "output_array")

    @staticmethod
    def _checked_out(out, rows, n, maker):
        if out is None:
            return np.empty((rows, n))
        if (out.shape != (rows, n) or out.dtype != np.float64 or out.strides[1] != 8
                or out.strides[0] < 8 * n or out.strides[0] % 8):
            raise ConfigError(f"out must be a float64 array of shape {(rows, n)} with contiguous "
                              f"rows (see {maker})")
        return out

    def _arguments(self, theta, omega, omegadot, p):
        theta = np.atleast_1d(np.asarray(theta, dtype=float))
        if theta.ndim != 1:
            raise ConfigError(f"theta must be one-dimensional, got shape {theta.shape}")
        n = theta.size
        theta = np.ascontiguousarray(theta)
        omega = self._samples_array("omega", omega, n)
        omegadot = self._samples_array("omegadot", omegadot, n)
        p = np.asarray(p, dtype=float)
        if p.shape[-1:] != (self.n_params,) or p.ndim > 2:
            raise ConfigError(f"p must have {self.n_params} parameters per row ({self.structure.variant}), "
                              f"got shape {p.shape}")
        return theta, omega, omegadot, p, n

    def _layout(self, p, n, block):
        """(per_sample, shared, p as the library reads it, block, unit): p one vector for all samples
        (shared), one per block of `block` samples, or one per sample (stored by parameter); `unit`
        the samples a thread takes whole -- blocks, or chunks of one design: the library restarts its
        chunks at each block, so any split gives the same bits as one call."""
        if p.ndim == 2 and block is None:
            if p.shape[0] != n:
                raise ConfigError(f"p has {p.shape[0]} rows for {n} samples; give block= for one "
                                  "row per block of samples")
            return True, False, np.ascontiguousarray(p.T), None, self.manifest.get("chunk", 512)
        block = n if p.ndim == 1 else int(block)
        rows = 1 if p.ndim == 1 else p.shape[0]
        if block < 1 or rows != max(1, -(-n // block)):
            raise ConfigError(f"p has {rows} rows; {n} samples in blocks of {block} need "
                              f"{max(1, -(-n // block))}")
        shared = p.ndim == 1
        return False, shared, np.ascontiguousarray(p), block, self.manifest.get("chunk", 512) if shared else block

    def _run(self, fns, n, theta, omega, omegadot, p, block, out, threads, extra=()):
        """Call the (blocks, samples) entry pair `fns` over n samples, split over `threads`; `extra`
        are the arguments after p's and before out's."""
        per_sample, shared, p, block, unit = self._layout(p, n, block)
        blocks_fn, samples_fn = fns
        ld = out.strides[0] // 8
        units = -(-n // unit) if n else 0
        cuts = [min(n, unit * (units * t // max(1, threads))) for t in range(max(1, threads) + 1)]
        a_th, a_om, a_od, a_out, a_p = (_address(x) for x in (theta, omega, omegadot, out, p))

        def run(lo, hi):  # byte offsets into the C-contiguous float64 buffers
            if hi <= lo:
                return 0
            args = (hi - lo, a_th + 8 * lo, a_om + 8 * lo, a_od + 8 * lo)
            if per_sample:
                return samples_fn(*args, a_p + 8 * lo, n, *extra, a_out + 8 * lo, ld)
            if shared:
                return blocks_fn(*args, a_p, hi - lo, *extra, a_out + 8 * lo, ld)
            return blocks_fn(*args, a_p + 8 * self.n_params * (lo // block), block, *extra, a_out + 8 * lo, ld)

        if threads > 1 and n > 1:
            with ThreadPoolExecutor(threads) as ex:
                codes = list(ex.map(run, cuts[:-1], cuts[1:]))
        else:
            codes = [run(0, n)]
        if any(codes):
            raise CodegenError(f"SIMD inverse dynamics of {self.structure.variant} refused its arguments"
                               + (" (out of memory)" if 2 in codes else ""))

    def __call__(self, theta, omega, omegadot, p, block: int | None = None, out=None,
                 threads: int = 1, outputs=None) -> dict:
        """Evaluate n samples (n = len(theta)). p: (n_p,) for all samples; (n_blocks, n_p) with
        `block` samples per row (the last block may be shorter); or (n, n_p) without `block`, one
        vector per sample. outputs: the names wanted (default all; see entry_for). Returns
        {"torque": (n,), vane output: (N, n)} for those names -- views into `out`."""
        theta, omega, omegadot, p, n = self._arguments(theta, omega, omegadot, p)
        key = self.entry_for(outputs)
        out = self._out_array(out, key, n)
        self._run(self._entries[key], n, theta, omega, omegadot, p, block, out, threads)
        return self.split(out, key, outputs)

    def split(self, out: np.ndarray, key=None, outputs=None) -> dict:
        """{name: view of out} for an entry point's buffer: all its outputs, or `outputs`."""
        N = self.vanes
        res = {"torque": out[0]}
        for j, name in enumerate(self.layouts[key]):
            res[name] = out[1 + j * N:1 + (j + 1) * N]
        if outputs is None:
            return res
        return {k: res[k] for k in ((outputs,) if isinstance(outputs, str) else outputs)}


class ScalarInverseDynamics(FastInverseDynamics):
    """The same interface over the scalar CasADi kernel (machines without a SIMD library)."""

    simd = False

    def __init__(self, structure: Structure, reason: str):
        self.structure, self.reason = structure, reason
        self.kern = load_kernels(structure)
        self.key, self.folder, self.manifest = self.kern.key, self.kern.folder, self.kern.manifest
        self.vanes, self.n_params = structure.vanes, len(layout(structure))
        self.outputs = ("torque", *VANE_OUTPUTS)
        self._set_layouts(SUBSETS)
        self._jac = None  # derivatives: the CasADi map's (identification's fallback path)
        self._reduce = None

    def __call__(self, theta, omega, omegadot, p, block=None, out=None, threads=1, outputs=None):
        theta, omega, omegadot, p, n = self._arguments(theta, omega, omegadot, p)
        key = self.entry_for(outputs)
        out = self._out_array(out, key, n)
        names = self.layouts[key]
        if p.ndim == 1:
            block, p = n, p[None, :]
        elif block is None:
            block = 1
        if p.shape[0] != max(1, -(-n // block)):
            raise ConfigError(f"p has {p.shape[0]} rows for {n} samples in blocks of {block}")
        N = self.vanes
        for b, pb in enumerate(p):
            lo, hi = b * block, min(n, (b + 1) * block)
            r = evaluate(self.kern, "inverse_dynamics", [theta[lo:hi], omega[lo:hi], omegadot[lo:hi]],
                         pb, hi - lo, ("torque", *names))
            out[0, lo:hi] = r["torque"]
            for j, name in enumerate(names):
                out[1 + j * N:1 + (j + 1) * N, lo:hi] = r[name]
        return self.split(out, key, outputs)


def load_fast_kernel(structure: Structure, build: bool | None = None, fallback: bool = True, log=None):
    """The SIMD inverse dynamics of `structure` (constrained model), built if missing or stale
    (unless build=False or PUMPSIM_NO_BUILD=1: then refused). If no SIMD library can be built on
    this machine (gcc leaves the loops scalar, no vector math, no compiler), the scalar kernel
    behind the same interface (`.simd` False, `.reason` says why, logged); fallback=False raises."""
    if structure.model != "constrained":
        raise ConfigError("the fast inverse dynamics exist for the constrained model only")
    memo = memo_key(structure)
    if memo in _LOADED:
        return _LOADED[memo]
    fingerprint, folder_name = memo[1], memo[2]
    folder, manifest = find_simd(structure, ca.__version__, fingerprint)
    if manifest is None:
        if not building_allowed(build):
            raise CodegenError(
                f"SIMD kernel for {structure.variant} is missing or stale for this source and CPU "
                f"(source {fingerprint}, in {folder_name}); build it with `pumpsim kernels build CONFIG` "
                "or unset PUMPSIM_NO_BUILD")
        log = log or log_build
        try:
            build_library(structure, log, simd=True,
                          ready=lambda: find_simd(structure, ca.__version__, fingerprint)[0])
        except CodegenError as exc:
            if not fallback:
                raise
            log(f"no SIMD library for {structure.variant}, using the scalar kernel: {exc}")
            _LOADED[memo] = ScalarInverseDynamics(structure, str(exc))
            return _LOADED[memo]
        folder, manifest = find_simd(structure, ca.__version__, fingerprint)
        if manifest is None:
            raise CodegenError(f"SIMD build of {structure.variant} did not produce a valid library")
    _LOADED[memo] = FastInverseDynamics(structure, folder, manifest)
    return _LOADED[memo]


FAST_THREADED = 20000  # samples from which a SIMD call is split over threads (below: ~1 ms, not worth it)
_FAST: dict = {}


def fast_kernel(structure: Structure):
    """The SIMD inverse dynamics of a constrained variant (load_fast_kernel, built beside the
    scalar library when missing), or None where it cannot be built or PUMPSIM_FIT_KERNEL=scalar:
    then callers use the CasADi map. Looked up once per variant and process."""
    if os.environ.get("PUMPSIM_FIT_KERNEL", "") == "scalar" or structure.model != "constrained":
        return None
    memo = memo_key(structure)
    if memo not in _FAST:
        try:
            fk = load_fast_kernel(structure, fallback=True)
        except CodegenError:  # e.g. PUMPSIM_NO_BUILD with no SIMD library: the scalar kernel runs
            fk = None
        _FAST[memo] = fk if fk is not None and fk.simd else None
    return _FAST[memo]


def sampled_inverse_dynamics(kern, p, theta, omega, omegadot, outputs=None) -> dict:
    """inverse_dynamics through the fastest kernel this machine has: for a constrained variant the
    SIMD library (FastInverseDynamics; the entry point that computes only `outputs`, written into
    one buffer, split over threads from FAST_THREADED samples), else the CasADi map. The same
    names and shapes; the same numbers to ~1e-14 of each output's scale."""
    fast = fast_kernel(kern.structure)
    if fast is None:
        return inverse_dynamics(kern, p, theta, omega, omegadot, outputs)
    threads = default_threads() if np.size(theta) >= FAST_THREADED else 1
    return fast(theta, omega, omegadot, p, outputs=outputs, threads=threads)
