"""The cell geometry over one revolution as a table, for the direct CVODES driver.

With Model 2 mechanics the cells' volumes, port overlaps, wall areas, exposed flanks and the vane
positions depend on the rotor angle and the parameters only, and they are about half of the
right-hand side's operations and more of its Jacobian's. A run evaluates them once per
revolution's table (the compiled `geometry_table` kernel: values and exact d/dtheta at each node)
and the driver interpolates them (periodic cubic Hermite) before each call of `pump_rhs_tab` and
`pump_rhs_tab_jac`, which take them as an input. The nodes are refined until the interpolant at
every interval's midpoint is within TABLE_TOL of the exact geometry (relative to each quantity's
largest size over the turn); the kinks (a vane's tip crossing a port edge, a flank drawn into the
rotor near top dead centre) are resolved by that refinement down to MIN_INTERVAL.
"""
from __future__ import annotations

import logging
import os
import threading
from dataclasses import dataclass

import numpy as np

from .. import cvodes_driver
from ..errors import CodegenError, SolverError

TWO_PI = 2 * np.pi
ENV = "PUMPSIM_GEOMETRY"  # "exact": the right-hand side computes the geometry at every call
TABLE_TOL = 1e-9  # relative to each quantity's largest size over the turn
START_NODES = 1024
MIN_INTERVAL = 1e-9  # rad: a kink is resolved to this
MAX_ROUNDS = 40
MAX_NODES = 100_000
NOISE = 1e-12
CACHED = 8  # tables kept (per kernel and parameters; ~1 MB each): a fit's nearby parameters rebuild
PROBE_ANGLES = 64  # angles over a turn at which moves_geometry compares the geometry
_CACHE: dict = {}
_CACHE_LOCK = threading.Lock()


@dataclass
class GeometryTable:
    nodes: np.ndarray  # (n,) 0 .. 2 pi
    values: np.ndarray  # (n, m): the kernel's geometry input (alpha as alpha - theta: periodic)
    slopes: np.ndarray  # (n, m) d/dtheta
    scale: np.ndarray  # (m,) each quantity's size: the tolerance's reference
    max_error: float  # largest relative midpoint error of the last refinement round

    def __call__(self, theta):
        """(values, slopes) at the angles theta (n,) -> (n, m) each, as the driver's C does."""
        a = np.mod(np.asarray(theta, float), TWO_PI)
        k = np.clip(np.searchsorted(self.nodes, a, side="right") - 1, 0, self.nodes.size - 2)
        return hermite(self.nodes[k], self.nodes[k + 1], self.values[k], self.values[k + 1],
                       self.slopes[k], self.slopes[k + 1], a)


def hermite(t0, t1, y0, y1, m0, m1, a):
    """Cubic Hermite on [t0, t1] at a (rows): value and derivative."""
    h = (t1 - t0)[:, None]
    u = (a - t0)[:, None] / h
    v = 1 - u
    g = (1 + 2 * u) * v * v * y0 + u * v * v * h * m0 + u * u * (3 - 2 * u) * y1 - u * u * v * h * m1
    dg = 6 * u * (u - 1) / h * (y0 - y1) + v * (1 - 3 * u) * m0 + u * (3 * u - 2) * m1
    return g, dg


def enabled() -> bool:
    return os.environ.get(ENV, "").lower() != "exact"


def available(kern) -> bool:
    """The variant exports the tabulated right-hand side (Model 2 with gas)."""
    return "geometry_table" in kern.functions


def exact(kern, p, theta):
    """The compiled geometry and its theta-derivative at the angles theta -> (n, m) each."""
    call = cvodes_driver.KernelCall(cvodes_driver.kernel_library(kern), "geometry_table",
                                    [np.zeros(1), p], 0)
    f = kern["geometry_table"]
    m = f.size1_out(0)
    if f.nnz_out(0) != m or f.nnz_out(1) != m:
        raise CodegenError(f"kernel {kern.key}: geometry_table's outputs are not dense; rebuild the kernel")
    g, dg = call.rows(np.asarray(theta, float).reshape(-1, 1), [m, m])
    return g, dg


def build(kern, p, tol=TABLE_TOL) -> GeometryTable:
    """The table of kernel `kern`'s geometry at parameters p (cached per kernel and p)."""
    p = np.ascontiguousarray(p, dtype=float)
    key = (kern.key, p.tobytes(), tol)
    with _CACHE_LOCK:
        if key in _CACHE:
            if isinstance(_CACHE[key], SolverError):  # tried before: it does not converge
                raise _CACHE[key]
            return _CACHE[key]
    t = np.linspace(0.0, TWO_PI, START_NODES + 1)
    g, dg = exact(kern, p, t)
    # a quantity that is zero up to rounding (a load coefficient of a vane the slot gas cannot
    # tilt) is held to the largest quantity's 1e-12 instead: relative to its own size it is noise
    size = np.abs(g).max(axis=0)
    scale = np.maximum(size, NOISE * size.max())
    err = 0.0
    check = np.ones(t.size - 1, dtype=bool)  # intervals whose midpoint is not yet checked
    for _ in range(MAX_ROUNDS):
        k = np.nonzero(check & (np.diff(t) > MIN_INTERVAL))[0]
        if k.size == 0:
            break
        mid = 0.5 * (t[k] + t[k + 1])
        gm, dgm = exact(kern, p, mid)
        gi, _ = hermite(t[k], t[k + 1], g[k], g[k + 1], dg[k], dg[k + 1], mid)
        e = np.max(np.abs(gi - gm) / scale, axis=1)
        err = float(e.max())
        bad = e > tol
        if t.size + bad.sum() > MAX_NODES:
            _keep(key, SolverError(f"the geometry table does not converge ({t.size} nodes; largest midpoint "
                                   f"error {err:.1e}): set {ENV}=exact"))
            raise _CACHE[key]
        # the failing intervals are split at their midpoints; the halves are checked next round
        t = np.insert(t, k[bad] + 1, mid[bad])
        g = np.insert(g, k[bad] + 1, gm[bad], axis=0)
        dg = np.insert(dg, k[bad] + 1, dgm[bad], axis=0)
        check = np.zeros(t.size - 1, dtype=bool)
        at = k[bad] + np.arange(bad.sum())  # the split intervals' first halves, in the new t
        check[at], check[at + 1] = True, True
    table = GeometryTable(t, g, dg, scale, err)
    _keep(key, table)
    return table


def _keep(key, value) -> None:
    """Cache a table (or the error of one that does not converge) under key."""
    with _CACHE_LOCK:  # runs in threads build their tables side by side
        while len(_CACHE) >= CACHED:
            del _CACHE[next(iter(_CACHE))]
        _CACHE[key] = value


def kernel_calls(kern, p, pbuf, nx):
    """(rhs, jac, table, gbuf, dgbuf): KernelCalls of pump_rhs_tab and pump_rhs_tab_jac reading
    the parameter buffer pbuf and the geometry buffers the driver fills from the table."""
    table = build(kern, p)
    m = table.values.shape[1]
    gbuf, dgbuf = np.zeros(m), np.zeros(m)
    so = cvodes_driver.kernel_library(kern)
    rhs = cvodes_driver.KernelCall(so, "pump_rhs_tab", [np.zeros(nx), gbuf, pbuf], 0)
    jac = cvodes_driver.KernelCall(so, "pump_rhs_tab_jac", [np.zeros(nx), gbuf, dgbuf, pbuf], 0)
    return rhs, jac, table, gbuf, dgbuf


def driver_calls(kern, p, pbuf, nx, use_table=True):
    """The direct driver's kernel calls reading the parameter buffer pbuf: (rhs, jac, the Jacobian's
    Function, attach). The tabulated kernels with the table at p where use_table and the variant
    has them, else pump_rhs and pump_rhs_jac; attach(driver) hands a driver the table and returns
    the geometry's name ("table" or "exact")."""
    if use_table and available(kern):
        try:
            rhs, jac, table, gbuf, dgbuf = kernel_calls(kern, p, pbuf, nx)
        except SolverError as e:  # a geometry the table cannot resolve: the exact one, as fast as before
            logging.getLogger("pumpsim").debug("geometry table: %s; the exact geometry at every call instead", e)
        else:
            def attach(d):
                d.set_table(table.nodes, table.values, table.slopes, gbuf, dgbuf)
                return "table"

            return rhs, jac, kern["pump_rhs_tab_jac"], attach
    rhs, jac = cvodes_driver.rhs_and_jacobian(kern, "pump_rhs", [np.zeros(nx), pbuf])
    return rhs, jac, kern["pump_rhs_jac"], lambda d: "exact"


def moves_geometry(kern, p, changes) -> bool:
    """Whether any change of p (rows of `changes`) changes the geometry at PROBE_ANGLES angles over
    a turn: a table at p does not follow such a change (a parameter the geometry does not read
    leaves it bit for bit)."""
    theta = (np.arange(PROBE_ANGLES) + 0.37) * (TWO_PI / PROBE_ANGLES)
    p = np.asarray(p, float)
    g0, _ = exact(kern, p, theta)
    return any(not np.array_equal(exact(kern, p + dp, theta)[0], g0) for dp in np.atleast_2d(changes))
