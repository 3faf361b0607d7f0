"""The pump-down model over a bench log by the direct CVODES driver (cvodes_driver), with forward
sensitivities along the fitted parameters' directions (pumpdown_fit's module doc: what they are
worth against forward differences).

A run is one CVODES call over the log's grid on the right-hand side and its compiled Jacobian,
with the cell geometry from a table over one turn (pneumatics.geometry_table: the tabulated
kernels, half the cost of pump_rhs's) and the logged voltage interpolated in C before every kernel
call, the steps ending on the samples where it steps (pneumatics.drive: the same voltage as the CasADi path's).
With sensitivities, CVODES integrates s_j = dx/dtheta_j beside the states:
s_j' = J s_j + df/dp d_j, J the Jacobian kernel's and df/dp d_j a forward difference of the
right-hand side in the runtime parameter vector along d_j (the fitted parameter's direction there;
the kernel has no derivative in p). The sensitivities are left out of the error test (staggered
corrector): the steps are the states' own, and the sensitivities are those of that discrete
solution, consistent with the run they belong to, so a Jacobian no longer carries the
differences between two runs' step sequences. Where the right-hand side switches (a vane's
reversal in its slot) they jump (reversal_switches).
"""
from __future__ import annotations

import threading

import numpy as np

from .. import cvodes_driver
from ..errors import SolverError

P_STEP = 1e-7  # the right-hand side's difference step in p, of the fitted parameter's scale
MAX_ORDER = 3  # as bench_model's
MAX_STEPS = 20_000_000
# A vane reversing in its slot flips its Coulomb friction within |sdot| < friction.slot.v_static
# (~1e-4 rad of rotor angle at speed; the tip's normal force and the rotor's acceleration jump with
# it): a switch of the right-hand side. The sensitivities take it as a jump at the reversal angle
# (cvodes_driver.Driver.set_switches) over a band of BAND x the angle where |sdot| reaches
# v_dynamic (measured: 1 is best; 0.5 or 3 leave 7-47 % column errors, docs/explanation/bench-log.md);
# bands wider than MAX_BAND rad (the pump barely turning) are left to the steps.
BAND, MAX_BAND = 1.0, 0.05
ANGLE_GRID = 2048  # angles searched for reversals per revolution
SAME_ANGLE = 1e-6  # rad: reversals closer than this are one switch (the bisection's ds is a difference)
# the start state's and the compared channels' parameter derivatives: central differences of
# algebraic maps (no integration), at this share of the parameter's scale
MAP_STEP = 1e-5


def usable() -> bool:
    return cvodes_driver.available()[0]


class DirectRuns:
    """Runs of the pump-down model driven by `drive` (pneumatics.drive.VoltageDrive) on a uniform
    grid by the direct driver: `runs(x0s, ps)` -> [states (n, nx)]; `run(x0, p, directions, steps,
    scales, s0)` -> (states, sensitivities (n, k, nx))."""

    def __init__(self, kern, grid, drive, scale, rtol, atol):
        from ..kernels.pneumatic import parameter_index
        from ..pneumatics import geometry_table

        self.kern, self.grid, self.drive = kern, np.asarray(grid, float), drive
        self.S, self.rtol, self.atol = np.asarray(scale, float), rtol, atol
        self.table = geometry_table.enabled()  # the tabulated geometry (PUMPSIM_GEOMETRY=exact: not)
        self.geometry = None  # "table" or "exact": the last run's
        self.iv = parameter_index(kern.structure, "motor.voltage")
        self.nx = kern["pump_rhs"].size1_in(0)
        self.stats = {"runs": 0, "nsteps": 0, "nfevals": 0, "njevals": 0, "netfails": 0, "nsens_fevals": 0, "njumps": 0}
        self._lock = threading.Lock()
        self.switches = None  # reversal_switches, at the first sensitivity run (geometry: no fitted parameter moves it)

    def _driver(self, p, table=True):
        from ..pneumatics import geometry_table

        pbuf = np.array(p, dtype=float)  # the one buffer both kernels read
        rhs, jac, fj, attach = geometry_table.driver_calls(self.kern, pbuf, pbuf, self.nx, table and self.table)
        d = cvodes_driver.Driver(self.nx, rhs, [0, -1], jac, [(fj.sparsity_out(0), 0), None], self.rtol,
                                 self.atol * self.S, max_order=MAX_ORDER, max_steps=MAX_STEPS, lin_size=self.nx)
        self.geometry = attach(d)
        d.set_drive(pbuf, self.iv, self.drive.step, self.drive.values, self.drive.stops)
        return d

    def run(self, x0, p, directions, steps, scales, s0):
        """(states, sensitivities) of one run with sensitivities along the runtime parameter
        directions (k, n_p), the right-hand side's difference steps, the parameters' scales (the
        sensitivities' absolute tolerances atol / scale) and their start s0 (k, nx). The table
        serves unless a direction moves the geometry (the right-hand side's difference along it
        would miss the geometry's change)."""
        from ..pneumatics import geometry_table

        changes = np.asarray(directions, float) * np.asarray(steps, float)[:, None]
        d = self._driver(p, not geometry_table.moves_geometry(self.kern, p, changes))
        d.set_sensitivities(directions, steps, scales, error_control=False)
        if self.switches is None:
            self.switches = reversal_switches(self.kern, p)
        d.set_switches(*self.switches, MAX_BAND)
        X = self._one(d, x0, s0)
        return X, np.concatenate([np.asarray(s0, float)[None], d.sensitivities])

    def runs(self, x0s, ps) -> list:
        """[states] for each (x0, p): several at once in threads (the driver's C call releases
        the interpreter), each on its own solver memory."""
        from concurrent.futures import ThreadPoolExecutor

        from ..kernels.scalar import default_threads

        if len(ps) == 1:
            return [self._one(self._driver(ps[0]), x0s[0])]
        with ThreadPoolExecutor(max_workers=min(len(ps), default_threads())) as pool:
            return list(pool.map(lambda a: self._one(self._driver(a[1]), a[0]), zip(x0s, ps)))

    def _one(self, d, x0, s0=None):
        try:
            Y = d.run(0.0, np.asarray(x0, float), self.grid[1:], s0)
        except SolverError as e:
            raise SolverError(f"the pump-down model's integration over the log failed: {e}") from None
        st = d.stats
        with self._lock:
            for k in self.stats:
                self.stats[k] += 1 if k == "runs" else st[k]
        return np.vstack([x0, Y])


def reversal_switches(kern, p):
    """(angles, band coefficients): the rotor angles in [0, 2 pi) where a vane reverses in its
    slot (ds/dtheta = 0; vanes reversing together count once) and, for each, BAND v_dynamic /
    |d2s/dtheta2| (the band's half-width times the speed)."""
    from ..kernels.pneumatic import parameter_index

    geo = kern["cell_geometry"]
    s_of = lambda th: np.asarray(geo(th, p)[5]).ravel()  # noqa: E731 (each vane's extension)
    ds = lambda th: (s_of(th + 1e-7) - s_of(th - 1e-7)) / 2e-7  # noqa: E731
    # a grid off the symmetric angles (where the reversals tend to lie exactly), one revolution
    grid = (np.arange(ANGLE_GRID + 1) + 0.371) * (2 * np.pi / ANGLE_GRID)
    D = np.array([ds(t) for t in grid])
    angles, widths = [], []
    v_d = p[parameter_index(kern.structure, "friction.slot.v_dynamic")]
    for i in range(D.shape[1]):
        for k in np.nonzero(np.sign(D[:-1, i]) * np.sign(D[1:, i]) < 0)[0]:
            a, b = grid[k], grid[k + 1]
            for _ in range(40):  # bisection to ~1e-14 rad
                m = 0.5 * (a + b)
                a, b = (m, b) if np.sign(ds(m)[i]) == np.sign(D[k, i]) else (a, m)
            th = 0.5 * (a + b) % (2 * np.pi)
            h = 1e-4
            curv = abs((s_of(th + h)[i] - 2 * s_of(th)[i] + s_of(th - h)[i]) / h ** 2)
            w = BAND * v_d / max(curv, 1e-300)
            same = [n for n, t in enumerate(angles) if abs((th - t + np.pi) % (2 * np.pi) - np.pi) < SAME_ANGLE]
            if same:  # vanes reversing together: one switch, the widest band
                widths[same[0]] = max(widths[same[0]], w)
            else:
                angles.append(th)
                widths.append(w)
    return np.array(angles), np.array(widths)


def parameter_directions(parameter_vector, x, scales, iv, cols):
    """The runtime parameter vector's derivative by the fitted parameters `cols` at x (k, n_p), a
    central difference of the map (linear in most parameters; the voltage slot, the log's, zeroed)."""
    x = np.asarray(x, float)
    out = []
    for j in cols:
        h = MAP_STEP * scales[j]
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        out.append((parameter_vector(xp) - parameter_vector(xm)) / (2 * h))
    D = np.array(out)
    D[:, iv] = 0.0
    return D


def channel_derivatives(compared, X, SX, p, D, scales):
    """{channel: (m, k)} derivatives of compared(X, p) (the compared channels from the states and
    the runtime parameter vector) along the states' sensitivities SX (n, k, nx) and the parameter
    directions D (k, n_p): compared is affine in X, so its X part is exact (the change of a
    parameter's scale along s_j, less the affine part), its p part a central difference."""
    zero = compared(np.zeros_like(X), p)
    base = compared(X, p)
    cols = {c: [] for c in base}
    for j, s in enumerate(scales):
        lin = compared(s * SX[:, j, :], p)
        h = MAP_STEP * s
        up, down = compared(X, p + h * D[j]), compared(X, p - h * D[j])
        for c in cols:
            cols[c].append((lin[c] - zero[c]) / s + (up[c] - down[c]) / (2 * h))
    return base, {c: np.column_stack(v) for c, v in cols.items()}
