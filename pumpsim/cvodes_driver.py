"""CVODES driven directly over the compiled kernels, without CasADi's integrator layer.

CasADi's CVODES plugin re-initialises the solver on every call (each output chunk starts again at
order 1 with a tiny step), evaluates the Jacobian at nearly every linear-solver set-up and adds its
own per-step work. This driver is a small C library over the system's SUNDIALS: CVODES' own dense
linear solver (so the Jacobian is reused as CVODES decides), a vector absolute tolerance, and one
solver memory that carries on from one output chunk to the next when the caller continues from
where the last call ended (`resume`). The right-hand side and its Jacobian are the kernels' own
compiled functions, called through their C entry points.

A fresh machine needs a C compiler (as for the kernels) and the SUNDIALS 6 or 7 headers and
libraries (Debian/Ubuntu 24.04: `apt-get install libsundials-dev`; conda: `sundials`; Homebrew:
`sundials`). The library is built once into the kernel folder; where it cannot be built or
loaded, `available()` says why and the callers use CasADi's CVODES plugin instead (same
equations, same tolerances). PUMPSIM_CVODES=casadi forces that path.
"""
from __future__ import annotations

import ctypes
import hashlib
import logging
import os
import subprocess
from pathlib import Path

import numpy as np

from .cvodes_source import SOURCE
from .errors import SolverError

ENV = "PUMPSIM_CVODES"
TIMING_ENV = "PUMPSIM_CVODES_TIMING"  # "1": the driver times its kernel calls (Driver.times)
LIBS = ["-lsundials_cvodes", "-lsundials_nvecserial", "-lsundials_sunmatrixdense",
        "-lsundials_sunlinsoldense", "-lm"]
# -O3: the driver's vector operations, LU and table interpolation are short loops over contiguous
# arrays that -O2 leaves mostly scalar; without -ffast-math no sum is reordered (the same results)
CFLAGS = ["-O3"]
STAT_NAMES = ("nsteps", "nfevals", "njevals", "nlinsetups", "netfails", "nniters", "nncfails", "nsens_fevals", "njumps")
_LIB: dict = {}


def _build() -> ctypes.CDLL:
    from .model_spec import manifest as mf

    tag = hashlib.sha1((SOURCE + " ".join(CFLAGS + LIBS)).encode()).hexdigest()[:16]
    folder = mf.generated_dir() / f"cvodes-driver-{tag}"
    lib = folder / "pumpsim_cvodes.so"
    if not lib.exists():
        folder.mkdir(parents=True, exist_ok=True)
        src = folder / f"pumpsim_cvodes.{os.getpid()}.c"  # per process: builds may run side by side
        src.write_text(SOURCE)
        tmp = folder / f".{os.getpid()}.so"
        cc = os.environ.get("CC", "cc")
        try:
            out = subprocess.run([cc, *CFLAGS, "-fPIC", "-shared", str(src), "-o", str(tmp), *LIBS],
                                 capture_output=True, text=True)
        finally:
            src.unlink()
        if out.returncode:
            raise OSError(f"{cc} could not build the CVODES driver (SUNDIALS headers or libraries missing?): "
                          + (out.stderr.strip().splitlines() or ["no message"])[-1])
        os.replace(tmp, lib)
        logging.getLogger("pumpsim").debug("built the direct CVODES driver in %s", folder)  # ~1 s: no notice
    dll = ctypes.CDLL(str(lib))
    p = ctypes.c_void_p
    dll.drv_new.restype = p
    dll.drv_new.argtypes = [ctypes.c_int, ctypes.c_double, p, ctypes.c_int, ctypes.c_long, ctypes.c_double,
                            p, p, p, p, p, ctypes.c_int, ctypes.c_int, p, p, p, p, p, p, ctypes.c_int,
                            ctypes.c_longlong, p, p, ctypes.c_int]
    dll.drv_run.argtypes = [p, ctypes.c_double, p, ctypes.c_int, ctypes.c_int, p, p, p, p, p, p, p, p, p]
    dll.drv_drive.argtypes = [p, p, ctypes.c_int, ctypes.c_double, ctypes.c_int, p, ctypes.c_int, p]
    dll.drv_drive_offset.argtypes = [p, ctypes.c_double]
    dll.drv_switches.argtypes = [p, ctypes.c_int, p, p, ctypes.c_double]
    dll.drv_timing.argtypes = [p, ctypes.c_int, p]
    dll.drv_table.argtypes = [p, ctypes.c_int, p, p, p, ctypes.c_int, p, p]
    dll.drv_sens.argtypes = [p, ctypes.c_int, ctypes.c_int, p, p, p, ctypes.c_int, ctypes.c_double, p, p]
    dll.drv_roots.argtypes = [p, p, p, p, p, p, ctypes.c_int, p, p, ctypes.c_int, p, ctypes.c_int, p,
                              ctypes.c_double]
    dll.drv_message.restype = ctypes.c_char_p
    dll.drv_message.argtypes = [p]
    dll.drv_free.argtypes = [p]
    dll.drv_tune.argtypes = [p, ctypes.c_int, ctypes.c_long, ctypes.c_double]
    dll.drv_block_solver.argtypes = [p, ctypes.c_int]
    dll.drv_step_bounds.argtypes = [p, ctypes.c_double, ctypes.c_double]
    dll.drv_profile.argtypes = [p, ctypes.c_double, p, ctypes.c_double, ctypes.c_long, p, p]
    dll.drv_rows.argtypes = [p, p, p, p, p, ctypes.c_int, ctypes.c_long, p, ctypes.c_long, ctypes.c_int, p, p]
    return dll


def library():
    """The driver library, or None (available() says why)."""
    if os.environ.get(ENV, "").lower() == "casadi":
        return None
    if "lib" not in _LIB:
        try:
            _LIB["lib"], _LIB["why"] = _build(), ""
        except (OSError, subprocess.SubprocessError) as e:
            _LIB["lib"], _LIB["why"] = None, str(e)
            logging.getLogger("pumpsim").debug("CVODES through CasADi's plugin: %s", e)
    return _LIB["lib"]


def available() -> tuple[bool, str]:
    """(usable, why not); checked at every solver set-up, so PUMPSIM_CVODES=casadi applies to
    the next run."""
    if library() is None:
        return False, _LIB.get("why") or f"{ENV}=casadi"
    return True, ""


def _ptr(a) -> int:
    return a.ctypes.data


class KernelCall:
    """One compiled kernel function `name` of the library at `so`: its work buffers, its inputs
    (fixed arrays, the state's slot filled per call) and outputs."""

    def __init__(self, so, name, inputs, state_slot):
        self.dll = ctypes.CDLL(str(so))
        self.fn = getattr(self.dll, name)
        sz = [ctypes.c_longlong() for _ in range(4)]
        getattr(self.dll, name + "_work")(*[ctypes.byref(s) for s in sz])
        n_arg, n_res, n_iw, n_w = (max(int(s.value), 1) for s in sz)
        self.keep = [np.ascontiguousarray(v, dtype=float) for v in inputs]
        self.arg = np.zeros(n_arg, dtype=np.uintp)
        for i, v in enumerate(self.keep):
            if i != state_slot:
                self.arg[i] = _ptr(v)
        self.res = np.zeros(n_res, dtype=np.uintp)
        self.iw = np.zeros(n_iw, dtype=np.int64)
        self.w = np.zeros(n_w)
        self.slot = state_slot

    def __call__(self, x, outs):
        """Evaluate at state x into the arrays outs (None: output not wanted); returns outs."""
        x = np.ascontiguousarray(x, dtype=float)
        self.arg[self.slot] = _ptr(x)
        for k, o in enumerate(outs):
            self.res[k] = 0 if o is None else _ptr(o)
        if self.fn(ctypes.c_void_p(_ptr(self.arg)), ctypes.c_void_p(_ptr(self.res)),
                   ctypes.c_void_p(_ptr(self.iw)), ctypes.c_void_p(_ptr(self.w)), 0):
            raise SolverError("a compiled kernel failed to evaluate")
        return outs

    def address(self) -> int:
        return ctypes.cast(self.fn, ctypes.c_void_p).value

    def rows(self, X, sizes, wanted=None) -> list:
        """The kernel at every row of X (n, nx) in one C loop (the driver library's): output k as
        an (n, sizes[k]) array, None where `wanted` leaves it out; the outputs dense."""
        X = np.ascontiguousarray(X, dtype=float)
        outs = [np.empty((X.shape[0], s)) if wanted is None or wanted[k] else None for k, s in enumerate(sizes)]
        ptrs = np.array([0 if o is None else _ptr(o) for o in outs], dtype=np.uintp)
        size = np.asarray(sizes, dtype=np.int64)
        lib = library()
        if lib is None:
            raise OSError(available()[1])
        if lib.drv_rows(self.address(), _ptr(self.arg), _ptr(self.res), _ptr(self.iw), _ptr(self.w), self.slot,
                        X.shape[0], _ptr(X), X.shape[1], len(sizes), _ptr(ptrs), _ptr(size)):
            raise SolverError("a compiled kernel failed to evaluate")
        return outs


def kernel_library(kern) -> Path:
    """The compiled library of a loaded variant (kern: kernels.*'s loaded kernels)."""
    return next(Path(kern.folder).glob("*.so"))


def rhs_and_jacobian(kern, name, inputs, state_slot=0) -> tuple[KernelCall, KernelCall]:
    """KernelCall of the compiled ODE `name` and of its Jacobian `name`_jac, both reading `inputs`."""
    so = kernel_library(kern)
    return KernelCall(so, name, inputs, state_slot), KernelCall(so, name + "_jac", inputs, state_slot)


class Driver:
    """CVODES (BDF, dense direct solver, CVODES' Jacobian reuse) on y' = f(y) of a kernel.

    rhs, jac: KernelCall of the right-hand side and its Jacobian; out_offsets: where each rhs
    output starts in y' (-1: not wanted); jac_blocks: per Jacobian output, (sparsity, row offset)
    or None (not wanted); atol: per component; jac_every: steps between Jacobian updates at
    most (CVODES' default 51); lin_size: the Jacobian's rows from lin_size on are zero (states
    that do not feed back, such as quadratures riding along): the Newton systems are then solved
    on the leading block only, by the driver's own LU, with the same results as SUNDIALS' dense
    solver (None) and faster; lin_size = n: the whole system by that LU. keep_step: (lo, hi),
    the ratios of the next step to the last that CVODES leaves the step at after a success
    (None: its default (0, 1.5), which never shrinks a step before it fails). sundials_vectors:
    SUNDIALS' own serial vector operations instead of the driver's (the same results; a check)."""

    def __init__(self, n, rhs, out_offsets, jac, jac_blocks, rtol, atol, max_order=5, max_steps=500000,
                 max_step=None, jac_every=None, lin_size=None, keep_step=None, sundials_vectors=False):
        self.lib = library()
        if self.lib is None:
            raise OSError(available()[1])
        self.n = n
        self.rhs, self.jac = rhs, jac
        self.off = np.asarray(out_offsets, dtype=np.int64)
        bufs, pos = [], []
        for k, block in enumerate(jac_blocks):
            if block is None:
                continue
            sp, r0 = block
            rows, cols = sp.get_triplet()
            buf = np.zeros(len(rows))
            jac.res[k] = _ptr(buf)
            bufs.append(buf)
            pos.append(np.asarray(cols, dtype=np.int64) * n + np.asarray(rows, dtype=np.int64) + r0)
        self.jbuf = np.concatenate(bufs) if len(bufs) > 1 else bufs[0]
        if len(bufs) > 1:  # one buffer: the outputs write into consecutive parts of it
            start = 0
            for k, block in enumerate(jac_blocks):
                if block is not None:
                    jac.res[k] = _ptr(self.jbuf) + 8 * start
                    start += block[0].nnz()
        self.jpos = np.concatenate(pos)
        self.atol = np.ascontiguousarray(atol, dtype=float)
        self.rtol = float(rtol)
        self.stats_now = np.zeros(len(STAT_NAMES), dtype=np.int64)
        self.handle = self.lib.drv_new(
            n, float(rtol), _ptr(self.atol), int(max_order), int(max_steps), float(max_step or 0.0),
            rhs.address(), _ptr(rhs.arg), _ptr(rhs.res), _ptr(rhs.iw), _ptr(rhs.w), rhs.slot, self.off.size,
            _ptr(self.off), jac.address(), _ptr(jac.arg), _ptr(jac.res), _ptr(jac.iw), _ptr(jac.w), jac.slot,
            self.jpos.size, _ptr(self.jpos), _ptr(self.jbuf), int(not sundials_vectors))
        if not self.handle:
            raise OSError("SUNDIALS could not set up CVODES")
        if lin_size is not None and lin_size <= n and self.lib.drv_block_solver(self.handle, int(lin_size)):
            raise OSError("SUNDIALS could not set up the leading-block linear solver")
        if jac_every:
            self.lib.drv_tune(self.handle, 0, int(jac_every), 0.0)
        if keep_step is not None:
            lo, hi = (float(v) for v in keep_step)
            if not 0.0 <= lo < 1.0 < hi:  # CVODES would put its default in silently
                raise ValueError(f"keep_step = {keep_step}: needs 0 <= lo < 1 < hi")
            self.lib.drv_step_bounds(self.handle, lo, hi)
        self._times = np.zeros(3)
        self.timed = os.environ.get(TIMING_ENV, "") == "1"
        self.lib.drv_timing(self.handle, int(self.timed), _ptr(self._times))
        self.last = None  # (t, y) where the solver memory stands
        self.drive_offset = 0.0  # set_drive, shift_drive
        self.n_roots, self.root = 0, None
        self.n_sens, self.sensitivities = 0, None

    def set_drive(self, pbuf, slot, step, values, stops=()):
        """A time-dependent input: before every kernel call pbuf[slot] (pbuf: the kernels' parameter
        array) becomes the linear interpolation at t of `values` on the grid 0, step, 2 step, ...
        (linear beyond its ends); stops: grid indices where the solver's steps end instead of
        stepping across them (where the input's slope jumps)."""
        self._drive = (pbuf, np.ascontiguousarray(values, dtype=float), np.unique(np.asarray(stops, dtype=float)))
        if self._drive[1].size < 2:
            raise ValueError("set_drive: at least 2 values")
        k = self._drive[2]
        self.lib.drv_drive(self.handle, _ptr(pbuf), int(slot), float(step), self._drive[1].size, _ptr(self._drive[1]),
                           k.size, _ptr(k) if k.size else None)
        self.drive_offset = 0.0

    def shift_drive(self, offset):
        """The drive's time is the solver's t + offset from now on (runs on a clock of their own)."""
        if offset != self.drive_offset:
            self.lib.drv_drive_offset(self.handle, float(offset))
            self.drive_offset = float(offset)
            self.last = None

    def set_table(self, nodes, values, slopes, gbuf, dgbuf):
        """Kernel inputs that depend on y[0] (an angle) only, from a table over one turn: nodes
        (0 .. 2 pi, increasing), values and slopes (d/dangle) per node (nodes, m); before every
        right-hand side the periodic cubic Hermite interpolant at y[0] mod 2 pi goes into gbuf,
        before every Jacobian also its derivative into dgbuf (both the kernels' own input arrays)."""
        self._table = tuple(np.ascontiguousarray(a, dtype=float) for a in (nodes, values, slopes))
        t, v, dv = self._table
        if v.shape != dv.shape or v.shape[0] != t.size or gbuf.size != v.shape[1] or dgbuf.size != v.shape[1]:
            raise ValueError("set_table: nodes, values, slopes and buffers disagree in size")
        self.lib.drv_table(self.handle, t.size, _ptr(t), _ptr(v), _ptr(dv), v.shape[1], _ptr(gbuf), _ptr(dgbuf))

    def set_sensitivities(self, directions, steps, scales, error_control=False):
        """Forward sensitivities of y along parameter directions (rows of `directions`, in the
        drive's parameter buffer, set_drive): s' = J s + df/dp d with J the Jacobian kernel's and
        df/dp d a forward difference of the right-hand side over `steps`; absolute tolerances
        atol / scales; error_control: the sensitivities in the error test (the staggered corrector
        either way). Before any run; `run` then also fills self.sensitivities (m, ns, n)."""
        D = np.ascontiguousarray(directions, dtype=float)
        rows, cols = self.jpos % self.n, self.jpos // self.n
        self._sens = (D, np.ascontiguousarray(steps, dtype=float), np.ascontiguousarray(scales, dtype=float),
                      np.ascontiguousarray(rows, dtype=np.int64), np.ascontiguousarray(cols, dtype=np.int64))
        self.n_sens = D.shape[0]
        if self.lib.drv_sens(self.handle, self.n_sens, D.shape[1], _ptr(D), _ptr(self._sens[1]), _ptr(self._sens[2]),
                             int(bool(error_control)), float(self.rtol), _ptr(self._sens[3]), _ptr(self._sens[4])):
            raise OSError("CVODES could not set up its forward sensitivities")

    def set_switches(self, angles, widths, max_width):
        """Switches of the right-hand side where y[0] (an angle) crosses `angles` (mod 2 pi): the
        sensitivities jump there by (f after - f before) s[0] / |y[1]|, f taken at the edges of
        the switch's band (half-width widths / |y[1]|, ignored beyond max_width), and their
        right-hand side is taken at the band's edge inside it. After set_sensitivities."""
        order = np.argsort(np.mod(angles, 2 * np.pi))
        self._switches = (np.ascontiguousarray(np.mod(angles, 2 * np.pi)[order], dtype=float),
                          np.ascontiguousarray(np.asarray(widths, float)[order]))
        if self.lib.drv_switches(self.handle, len(order), _ptr(self._switches[0]), _ptr(self._switches[1]),
                                 float(max_width)):
            raise OSError("CVODES could not set up its root finding")

    def set_roots(self, call, slots, offsets, output, n_out, state_idx, touch):
        """Switching functions located by CVODES: the kernel call's output `output` (its first
        n_out values; the state's pieces y[offsets[i]:] at its input slots[i]), then the states
        y[state_idx]; a value below `touch` in size counts as zero."""
        self._g = (call, np.asarray(slots, dtype=np.int64), np.asarray(offsets, dtype=np.int64),
                   np.zeros(max(n_out, 1)), np.asarray(state_idx, dtype=np.int64))
        call.res[:] = 0
        call.res[output] = _ptr(self._g[3])
        self.n_roots = n_out + len(state_idx)
        self._found = np.zeros(self.n_roots, dtype=np.int32)
        if self.lib.drv_roots(self.handle, call.address(), _ptr(call.arg), _ptr(call.res), _ptr(call.iw),
                              _ptr(call.w), len(slots), _ptr(self._g[1]), _ptr(self._g[2]), n_out, _ptr(self._g[3]),
                              len(state_idx), _ptr(self._g[4]), float(touch)):
            raise OSError("CVODES could not set up its root finding")

    def run(self, t0, y0, touts, s0=None):
        """y at each of touts (increasing, > t0) from y0 at t0 -> (m, n). The solver carries on
        without a restart when (t0, y0) is where the last call ended. With switching functions
        it stops at the first root: fewer rows, and self.root = (time, state, indices). With
        sensitivities: s0 (ns, n) their start, self.sensitivities (m, ns, n) at touts."""
        touts = np.ascontiguousarray(touts, dtype=float)
        y0 = np.ascontiguousarray(y0, dtype=float)
        resume = (self.last is not None and self.last[0] == t0 and np.array_equal(self.last[1], y0)
                  and s0 is None)
        Y = np.empty((touts.size, self.n))
        S0 = np.ascontiguousarray(np.zeros((self.n_sens, self.n)) if s0 is None else s0, dtype=float)
        SY = np.empty((touts.size, self.n_sens, self.n))
        done, t_root, y_root = ctypes.c_int(), ctypes.c_double(), np.empty(self.n)
        found = self._found if self.n_roots else np.zeros(1, dtype=np.int32)
        flag = self.lib.drv_run(self.handle, float(t0), _ptr(y0), int(resume), touts.size, _ptr(touts), _ptr(Y),
                                _ptr(self.stats_now), ctypes.byref(done), ctypes.byref(t_root), _ptr(y_root),
                                _ptr(found), _ptr(S0), _ptr(SY))
        if flag < 0:
            self.last = None
            msg = self.lib.drv_message(self.handle).decode(errors="replace")
            raise SolverError(f"CVODES failed (flag {flag}): {msg or 'no message'}")
        Y = Y[:done.value]
        self.sensitivities = SY[:done.value] if self.n_sens else None
        self.root = None
        if flag == 2:  # CV_ROOT_RETURN
            self.root = (t_root.value, y_root, np.nonzero(found)[0])
            self.last = (t_root.value, y_root.copy())
        else:
            self.last = (float(touts[-1]), Y[-1].copy())
        return Y

    def profile(self, t0, y0, t_end, max_steps=200_000) -> dict:
        """What limits the steps from y0 at t0 to t_end, step by step (a restart; the next run
        restarts too): time, step, order, angle (y[0]), the error-test and Newton failures
        before each accepted step, and `weighted_error` (steps, n): each component's local error
        estimate times its error weight (the error test passes when their rms is <= 1)."""
        y0 = np.ascontiguousarray(y0, dtype=float)
        rec, k = np.zeros((max_steps, 6 + self.n)), ctypes.c_long()
        flag = self.lib.drv_profile(self.handle, float(t0), _ptr(y0), float(t_end), int(max_steps), _ptr(rec),
                                    ctypes.byref(k))
        self.last = None
        if flag < 0:
            msg = self.lib.drv_message(self.handle).decode(errors="replace")
            raise SolverError(f"CVODES failed (flag {flag}): {msg or 'no message'}")
        r = rec[:k.value]
        return {"time": r[:, 0], "step": r[:, 1], "order": r[:, 2].astype(int), "angle": r[:, 3],
                "error_test_failures": r[:, 4].astype(int), "newton_failures": r[:, 5].astype(int),
                "weighted_error": r[:, 6:]}

    def times(self) -> dict:
        """Wall seconds inside the right-hand side, the Jacobian and the runs so far (timed: with
        PUMPSIM_CVODES_TIMING=1 when the driver was made; zeros otherwise): the monotonic clock
        around each call (~25 ns), so their shares of the run's wall are shares of its CPU too."""
        self.lib.drv_timing(self.handle, int(self.timed), _ptr(self._times))
        return dict(zip(("rhs_wall", "jac_wall", "run_wall"), self._times.tolist()))

    @property
    def stats(self) -> dict:
        return dict(zip(STAT_NAMES, (int(v) for v in self.stats_now)))

    def __del__(self):
        if getattr(self, "handle", None) and self.lib is not None:
            self.lib.drv_free(self.handle)
            self.handle = None
