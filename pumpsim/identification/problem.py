"""The Problem interface every identification problem offers the optimiser and the result, what
single-measurement problems share (names checked against the registries, start values, bounds, the
runtime parameter vector with fitted values put in), and the constant-speed problem."""
from __future__ import annotations

import difflib
import math
import os

import casadi as ca
import numpy as np

from ..config import PumpConfig, as_array
from ..data import Dataset
from ..signals import noise_sigma
from ..errors import ConfigError
from ..kernels import fast_kernel, load_kernels, map_samples
from ..model_spec.parameters import (ANGLE_ACTING, COF_ALIASES, DERIVED, KERNEL_GRAPH_INPUTS,
                                     MEASUREMENT, alias_targets, derive, fit_bounds, layout)
from ..sensor import LAG_SUBSTEPS, first_order_lag, refine
from ..motion import ripple_motion
from .interval import smooth_interval_columns, stepped_samples, subpoint_offsets
from .reversals import reversal_keep
from .runs import DESIGN_RUNS, MODEL_RUNS
from .sampled import drive_kinematics, drive_motion, drive_note, pointwise_columns, simd_torque, simd_torque_designs
from .start import periodic_config_names, phase_and_speed_start

Z_SPECIAL = KERNEL_GRAPH_INPUTS  # theta0, speed, delay, torque_offset, ripple_cos, ripple_sin
_RIPPLE = np.array([Z_SPECIAL.index("ripple_cos"), Z_SPECIAL.index("ripple_sin")])


def base_name(name):
    """'theta0@1' (a per-measurement parameter of a joint fit) -> 'theta0'."""
    return name.split("@", 1)[0]


class Problem:
    """What the optimiser and the result use, the same for constant-speed, joint and transient
    problems: `names`, start `x0`, bounds `lower`/`upper`, measured `y`, `model(x)`,
    `model_and_jacobian(x, cols=None)` (derivatives), `symbolic_model(phi)` (IPOPT),
    `residual(x)`, `dt`, `time_axis()`, `speed_of(x)`, `angle(x)`, `start(x)` (a better start for
    periodic parameters), `parameter_vector(x)`, the kernels `kern` and the evaluation count `n_eval`.

    `_setup` is what every single-measurement problem shares: the config's parameter vector and
    kernels, the fit names checked against the registries (`SPECIAL`: the names beyond parameter
    paths and aliases), start values (`initial`, else `starts`, else the config) and bounds."""

    SPECIAL: tuple = ()
    KIND = ""  # how an error message names the problem
    RESIDUAL_UNIT = "N m"  # the measured channel's: the torque (a transient fit's: the speed)
    METHOD_TAG = ""  # appended to the result's method
    NOTE = ""  # appended to the result's message
    # None: every sample weighs in the cost; a number: the reversal-aware cost (reversals.py) with
    # this noise sigma in the step threshold (0: estimated from the residual at each x)
    reversal_sigma: float | None = None
    # True: the columns of the geometric defect parameters (interval_geometric) are the derivative
    # of the sample-interval average of the model (see ConstantSpeedProblem._interval_columns);
    # SMOOTH_COLUMNS: that derivative's smooth formula on every sample
    interval_geometry: bool | str = False

    def keep_at(self, x):
        """The samples the cost keeps at x (bool per sample), None: all; here the measured ones."""
        return self.measured

    def exact_at(self, x):
        """(model, Jacobian without interval columns) at x if the problem kept them, else None."""
        return None

    def _setup(self, cfg: PumpConfig, data: Dataset, names, starts: dict, initial=None):
        self.cfg, self.data = cfg, data
        self.measured = None if data.measured is None else np.asarray(data.measured, bool)  # Dataset.measured
        self.pv = cfg.parameters("constrained")
        self.kern = load_kernels(self.pv.structure)
        self.p0 = as_array(self.pv)
        self.names = list(names)
        if not self.names:
            raise ConfigError("params names no parameter to fit")
        self._index = {n: i for i, n in enumerate(self.pv.names)}
        for n in self.names:
            self._check_name(n)
        if len(set(self.names)) != len(self.names):
            raise ConfigError(f"params names a parameter twice: {','.join(self.names)}")
        v = self.pv.values
        # [housing static/dynamic, slot static/dynamic, slot/housing dynamic]: mu scales the
        # configured COFs by one factor (a rig's own [friction.slot] is a measured or chosen value,
        # kept in proportion); with a frictionless nominal housing the slot COF equals mu
        self._ratios = np.array([v[f"friction.{side}.static"] / max(v[f"friction.{side}.dynamic"], 1e-300)
                                 for side in ("housing", "slot")] + [slot_ratio(v)])
        self._follow = following(cfg)
        self.fixed = {"mu": v["friction.housing.dynamic"], "mu_slot": v["friction.slot.dynamic"], **starts}
        self.x0, self.lower, self.upper = start_and_bounds(self.names, self.pv, self.fixed, initial)
        self.t = data.time - data.time[0]
        self.n_eval = 0

    def _check_name(self, n):
        if n in self.SPECIAL or n in self._index or alias_targets(n):
            return
        close = difflib.get_close_matches(n, list(self.SPECIAL) + list(self._index), n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise ConfigError(f"params: unknown parameter '{n}'{self.KIND}{hint}")

    def _parameters(self, val, lib=np):
        """The runtime parameter vector with the fitted values `val` (name -> value) put in."""
        p0 = self.p0 if lib is np else ca.DM(self.p0)
        return parameter_map(self._index, p0, val, self.fixed["mu_slot"], self._ratios, self._follow)

    def residual(self, x):
        return self.y - self.model(x)

    @property
    def dt(self):
        return self.t[1] - self.t[0]

    def time_axis(self):
        return self.t + self.data.time[0]

    def start(self, x):
        return np.array(x, dtype=float)

    def moves_phase(self) -> bool:
        """Whether a fitted name has a non-convex cost (the phase, the speed, a harmonic's phase):
        its start is scanned (start.py) before the local fit."""
        return any(base_name(n) in ("theta0", "speed") for n in self.names) or bool(periodic_config_names(self))


class ConstantSpeedProblem(Problem):
    """Model torque tau(t; phi) at constant speed and its Jacobian d tau / d phi: the pointwise
    columns exact, from the SIMD library's Jacobian entries (sampled.py) where this machine has
    them, else CasADi forward AD through the compiled kernel on its map.

    Every fitted name acts on the model through z = (runtime parameter vector, theta0, speed,
    delay, torque_offset, ripple_cos, ripple_sin), and z is affine in the fitted values: z(x) =
    z(x0) + S (x - x0), S a constant seed matrix. The compiled graph is one sample's torque and its
    derivatives along the columns of S, mapped over the samples: it depends only on the variant and
    the number of directions, never on the names or the sample count, so building it is cheap and
    every fit, candidate and joint measurement shares it."""

    # the COF aliases and the measurement parameters of a constant-speed fit (registry)
    SPECIAL = COF_ALIASES + tuple(m.name for m in MEASUREMENT if not m.transient or m.in_kernel_graph)

    def __init__(self, cfg: PumpConfig, data: Dataset, names, initial=None, extra=None,
                 ripple_order: int = 1, speed_in_band: bool = False):
        starts = {"theta0": float(data.angle[0]) if data.angle is not None else cfg.angle,
                  "speed": data.mean_speed() if data.speed is not None else cfg.speed,
                  "torque_offset": 0.0, "delay": 0.0, "ripple_cos": 0.0, "ripple_sin": 0.0, "lag": 0.0,
                  **(extra or {})}
        self._setup(cfg, data, names, starts, initial)
        self.ripple_order = int(ripple_order)
        # a speed the user asks for is searched over the start band (start.py); only a workflow
        # that refines a known operating point (diagnosis) confines it to the tolerance band
        self.speed_band = speed_band(cfg, data) if speed_in_band and "speed" in self.names else None
        if self.speed_band is not None:
            i = self.names.index("speed")
            self.lower[i], self.upper[i] = self.speed_band
            self.x0[i] = min(max(self.x0[i], self.speed_band[0]), self.speed_band[1])
        self.y = data.torque
        # the drive's own time: tau = t at a constant speed; with a drifting measured speed the
        # angle and speed follow the column's trend (sampled.drive_kinematics)
        self.tau, *self._rates = drive_kinematics(data, self.t)
        if self.tau is not self.t:
            self.NOTE = self.NOTE + drive_note(data)
        self._seeds = self._seed_matrix()
        self._half_step = 0.5 * (self.t[1] - self.t[0]) if self.t.size > 1 else 0.0

    def _values(self, x):
        """Every special value at x: the fitted ones from x, the others fixed."""
        d = dict(self.fixed)
        d.update(zip(self.names, x))
        return d

    def z(self, x):
        """The kernel-graph input z at the fitted values x (the last one remembered: a step's trial
        point, then its Jacobian, ask for the same z; read-only, as it is shared)."""
        key = np.asarray(x, dtype=float).tobytes()
        last = self.__dict__.get("_z_last")
        if last is not None and last[0] == key:
            return last[1]
        z = self._z(x)
        z.flags.writeable = False
        self._z_last = (key, z)
        return z

    def _z(self, x):
        d = self._values(x)
        p = self._parameters(dict(zip(self.names, x)))
        return np.concatenate([np.asarray(p, dtype=float).ravel(), [d[s] for s in Z_SPECIAL]])

    def _seed_matrix(self):
        """S = dz/dx at the start: the map from fitted values to z is affine (a derived default that
        follows a fitted input, vane inertia from the mass, is linear in it), so each column is the
        central difference of the map by a unit step ('lag' acts after the kernel: a zero column)."""
        S = np.zeros((self.p0.size + len(Z_SPECIAL), len(self.names)))
        for j, nm in enumerate(self.names):
            at = [{n: v + (n == nm) * sgn for n, v in zip(self.names, self.x0)} for sgn in (0.5, -0.5)]
            hi, lo = (np.asarray(parameter_map(self._index, self.p0, a, 0.0, self._ratios, self._follow),
                                 dtype=float).ravel() for a in at)
            S[:self.p0.size, j] = hi - lo
            if nm in Z_SPECIAL:
                S[self.p0.size + Z_SPECIAL.index(nm), j] = 1.0
        return S

    def angle_and_jacobian(self, x, lib=np, columns=True):
        """Rotor angle per sample and its derivative by the fitted values (lib = ca for a symbolic
        x): the integral of omega = omega0 (1 + rc cos(k theta_n) - rs sin(k theta_n)) with the
        nominal angle theta_n = theta0 + omega0 (t - delay). columns=False: the angle alone (None)."""
        d = self._values(x)
        th0, w0, dl, rc, rs, k = (d["theta0"], d["speed"], d["delay"], d["ripple_cos"], d["ripple_sin"],
                                  self.ripple_order)
        t = self.tau if lib is np else ca.DM(self.tau)
        thn = th0 + w0 * (t - dl)
        if lib is np and rc == 0 and rs == 0:  # no ripple: ripple_motion's values, without its sines
            theta, g = thn + 0.0, 1.0
        else:
            theta, g, _ = ripple_motion(thn, th0, 1.0, rc, rs, k, lib)  # g = omega / omega0
        if lib is not np or not columns:
            return theta, None
        # each column computed only when fitted (at 10^6 samples each is 8 MB)
        cols = {"theta0": lambda: g - rc * math.cos(k * th0) + rs * math.sin(k * th0),
                "speed": lambda: (t - dl) * g, "delay": lambda: -w0 * g,
                "ripple_cos": lambda: (np.sin(k * thn) - math.sin(k * th0)) / k,
                "ripple_sin": lambda: (np.cos(k * thn) - math.cos(k * th0)) / k}
        J = np.zeros((t.size, len(self.names)))
        for j, nm in enumerate(self.names):
            if nm in cols:
                J[:, j] = cols[nm]()
        return theta, J

    def angle(self, x):
        return self.angle_and_jacobian(x, columns=False)[0]

    def _lag(self, x):
        return self._values(x)["lag"]

    @property
    def _simd(self):
        """The SIMD library or None (PUMPSIM_FIT_KERNEL=scalar: the CasADi map), looked up once per
        problem (the lookup checks the sources)."""
        if os.environ.get("PUMPSIM_FIT_KERNEL", "") == "scalar":
            return None
        if "_simd_lib" not in self.__dict__:
            self._simd_lib = fast_kernel(self.kern.structure)
        return self._simd_lib

    def _torque(self, theta, z, kin):
        """torque_at, the last few short runs of any problem remembered (runs.MODEL_RUNS): a fit asks
        for the same model again (a step's trial point, then its Jacobian; the mask and the model
        at one x), and every candidate of a screen for the current fit's."""
        fast, z = self._simd, np.asarray(z, dtype=float)
        lib = self.kern if fast is None else fast
        run = (lambda: (torque_at(lib, theta, z, self.ripple_order, *kin),)) if fast is None else (
            lambda: (simd_torque(fast, theta, z, self.ripple_order, *kin),))
        # without a ripple the SIMD path's drive is the same bits at any order (sampled._drive): the
        # screen's speed-ripple candidates share the current fit's runs
        order = self.ripple_order if fast is None or z[fast.n_params + _RIPPLE].any() else None
        return MODEL_RUNS.get(("torque", lib, order, z.tobytes()), (theta, *kin), run)[0]

    def _grid(self, T, *per_sample):
        """The sensor filters the continuous torque: with a lag (T > 0) the model is evaluated on
        LAG_SUBSTEPS points per sample interval (angles, times and their derivatives interpolated
        linearly: smooth on that scale) and `_sensed` filters there and keeps the samples."""
        m = LAG_SUBSTEPS if T > 0 and self.t.size > 1 else 1
        return m, [a if m == 1 else self._refined(a, m) for a in per_sample]

    def _refined(self, a, m):
        """refine(a, m), kept for the drive's own per-sample arrays (the same at every x)."""
        if not any(a is b for b in (self.tau, *self._rates)):
            return refine(a, m)
        memo = self.__dict__.setdefault("_refine_memo", {})
        key = (id(a), m)
        if key not in memo:
            memo[key] = refine(a, m)
        return memo[key]

    def _sensed(self, y, T, m):
        return y if T <= 0 else first_order_lag(y, self.dt / m, T)[::m]

    def model(self, x):
        self.n_eval += 1
        T = self._lag(x)
        m, (theta, *kin) = self._grid(T, self.angle(x), self.tau, *self._rates)
        return self._sensed(self._torque(theta, self.z(x), kin), T, m)

    def model_and_jacobian(self, x, cols=None):
        """Torque and its Jacobian (the columns `cols` only, default all). For the angle-acting
        parameters (theta0, speed, delay, ripple) the derivative is that of the sample-interval
        average of the model, [tau(theta + h) - tau(theta - h)] / (2 h) with 2 h = omega dt:
        Coulomb friction reversals change tau over ~1e-4 rad, far below a sample angle, so the
        pointwise d tau / d theta is a set of spikes that carries no phase information at the
        sampling scale."""
        self.n_eval += 1
        cols = list(range(len(self.names))) if cols is None else list(cols)
        names = [self.names[c] for c in cols]
        T = self._lag(x)
        theta, dtheta = self.angle_and_jacobian(x)
        m, (theta, dtheta, *kin) = self._grid(T, theta, dtheta, self.tau, *self._rates)
        z = self.z(x)
        # the geometric defects' columns: the interval averages' derivatives (_interval_columns)
        geo = [i for i, n in enumerate(names) if interval_geometric(n)] if self.interval_geometry and T == 0 else []
        J = np.zeros((theta.size, len(cols)))
        tq, J[:] = self._pointwise(theta, z, kin, cols)
        slope = ends = None
        if any(n in ANGLE_ACTING for n in names) or ("lag" in names and T == 0) or geo:
            h = abs(self.speed_of(x)) * self._half_step / m
            ends = self._torque(theta - h, z, kin), self._torque(theta + h, z, kin)  # the intervals' ends
            slope = (ends[1] - ends[0]) / (2 * h)
            for i, c in enumerate(cols):
                if self.names[c] in ANGLE_ACTING:
                    J[:, i] += slope * dtheta[:, c]
        if T == 0 and "lag" in names:  # at T = 0 the filter is y = tau - T dtau/dt to first order
            J[:, names.index("lag")] = -self.speed_of(x) * slope
        if geo and len(cols) == len(self.names):  # before the interval columns replace the exact ones
            self._exact = (np.array(x, dtype=float), tq.copy(), J.copy())
        self._interval_columns(x, J, geo, cols, tq, ends)
        if T > 0:
            y, J = self._sensed(tq, T, m), self._sensed(J, T, m)
            if "lag" in names:  # d y / d T by finite steps of the exact filter (1-D)
                dT = 1e-6 * T
                J[:, names.index("lag")] = (self._sensed(tq, T + dT, m) - self._sensed(tq, T - dT, m)) / (2 * dT)
            return y, J
        return tq, J

    def exact_at(self, x):
        """(torque, Jacobian with every column exact) at x -- what a problem without the interval
        columns returns there, to the bit -- if this problem's last full evaluation with interval
        columns was at x, else None: the exact polish of an interval fit starts where it ended."""
        got = self.__dict__.get("_exact")
        if got is None or not np.array_equal(got[0], np.asarray(x, dtype=float)):
            return None
        return got[1].copy(), got[2].copy()

    def _pointwise(self, theta, z, kin, cols):
        """The torque at theta and its derivatives along the seed columns `cols` with theta held:
        exact derivatives of the same model -- the SIMD library's Jacobian entries where this machine
        has them (sampled.pointwise_columns), else forward AD on the CasADi map (sample_torque)."""
        fast = self._simd if self._simd is not None and self._simd.has_jacobian else None
        if fast is not None:
            if not cols:
                return self._torque(theta, z, kin), np.zeros((theta.size, 0))
            seeds = self._seeds[:, cols]
            return MODEL_RUNS.get(("columns", fast, self.ripple_order, z.tobytes(), seeds.tobytes(), seeds.shape),
                                  (theta, *kin), lambda: pointwise_columns(fast, theta, z, self.ripple_order, kin, seeds))
        f = sample_torque(self.kern, max(1, len(cols)), theta.size)
        tq, J = f(theta, kin[0], z, self.ripple_order, kin[1], kin[2], self._seeds[:, cols or [0]])
        return np.asarray(tq).ravel(), np.asarray(J).reshape(theta.size, -1)[:, :len(cols)]

    def _interval_averages(self, xs, at):
        """The model torque at each of the points xs averaged over the sample intervals of the
        samples `at` (indices; INTERVAL_SUBPOINTS points at the interval's sub-sample angles,
        centred on the sample): a friction reversal inside the interval contributes its step times
        the fraction of the interval it covers. On the SIMD library all points' sub-sample runs go
        in one call; the CasADi map runs over every sample (its graphs are per length)."""
        offsets = subpoint_offsets(INTERVAL_SUBPOINTS)
        sub = at if self._simd is not None else slice(None)
        kin = tuple(np.asarray(a)[sub] for a in (self.tau, *self._rates))
        thetas, zs = [], []
        for x in xs:
            theta, z, h = self.angle(x)[sub], self.z(x), abs(self.speed_of(x)) * self.dt
            thetas += [theta + o * h for o in offsets]
            zs += [z] * offsets.size
        if self._simd is None:
            runs = [self._torque(th, z, kin)[at] for th, z in zip(thetas, zs)]
        else:
            thetas, zs = np.array(thetas), np.array(zs)
            runs = DESIGN_RUNS.get(
                ("designs", self._simd, self.ripple_order, zs.tobytes(), zs.shape), (thetas, *kin),
                lambda: (simd_torque_designs(self._simd, thetas, zs, self.ripple_order, *kin),))[0]
        return [np.mean(runs[i:i + offsets.size], axis=0) for i in range(0, len(runs), offsets.size)]

    def _interval_columns(self, x, J, which, cols, samples, ends):
        """Replace the columns `which` of J (by the fit names of `cols`; on entry the exact
        derivatives at the samples `samples`, the torque at the intervals' ends `ends`) with the
        derivatives of the sample-interval average. A geometric defect moves the Coulomb friction
        reversals: at a sample the point model then jumps by a whole step when a reversal crosses
        the sample and is flat in between, so its exact derivative (which sees only the smooth
        part) leaves a Gauss-Newton fit on a staircase whose valleys are ~1 um wide; the average's
        derivative carries the reversals' motion at the sampling scale, as the interval slope does
        for the angle-acting parameters. Where the torque is smooth on the sample scale that
        derivative follows from the exact ones (interval.smooth_interval_columns); at and next to
        a step it is the central difference of the average by INTERVAL_STEP of the housing's size
        (PUMPSIM_INTERVAL_COLUMNS=runs: on every sample, as the reference)."""
        if not which:
            return
        if self.interval_geometry == SMOOTH_COLUMNS:  # a quick look's columns: no sub-sample runs
            J[:, which] = smooth_interval_columns(J[:, which], INTERVAL_SUBPOINTS)
            return
        if os.environ.get("PUMPSIM_INTERVAL_COLUMNS", "") == "runs":  # the reference: runs on every sample
            at = np.arange(samples.size)
        else:
            at = np.nonzero(stepped_samples(samples, *ends, np.max(np.abs(samples)), J[:, which]))[0]
            J[:, which] = smooth_interval_columns(J[:, which], INTERVAL_SUBPOINTS)
            if at.size == 0:
                return
        v = self.pv.values
        step = INTERVAL_STEP * max(v["housing.a"], v["housing.b"])
        x = np.asarray(x, dtype=float)
        points = []
        for i in which:
            e = np.zeros_like(x)
            e[cols[i]] = step
            points += [x + e, x - e]
        avg = self._interval_averages(points, at)
        for j, i in enumerate(which):
            J[at, i] = (avg[2 * j] - avg[2 * j + 1]) / (2 * step)

    def symbolic_model(self, phi):
        """The (unfiltered) model torque as a CasADi expression of symbolic fitted values phi."""
        theta, _ = self.angle_and_jacobian([phi[i] for i in range(len(self.names))], lib=ca)
        z = ca.DM(self.z(self.x0)) + ca.mtimes(ca.DM(self._seeds), phi - ca.DM(self.x0))
        f = sample_torque(self.kern, 0, self.t.size)
        tau, g, gd = (ca.DM(a).T for a in (self.tau, *self._rates))
        return f(theta.T, tau, z, self.ripple_order, g, gd).T

    def speed_of(self, x):
        return self._values(x)["speed"]

    def keep_at(self, x):
        """False at the samples next to the model's torque steps at x (reversals.py): the model
        (unfiltered: a lag does not move a reversal) at the samples, at the interval midpoints and,
        for the intervals with a step, at the bisection points that locate it; and where not measured."""
        if self.reversal_sigma is None or self.t.size < 3:
            return self.measured
        self.n_eval += 1
        theta, z = self.angle(x), self.z(x)
        h = abs(self.speed_of(x)) * self._half_step
        kin = (self.tau, *self._rates)
        samples = self._torque(theta, z, kin)
        mids = self._torque(theta + h, z, (self.tau + (self.tau[1] - self.tau[0]) / 2, *self._rates))

        def evaluate(k, frac):  # intervals k at t_k + frac dt, padded to a power of two (map sizes)
            pad = lambda a: np.pad(a, (0, (1 << int(k.size - 1).bit_length()) - k.size), mode="edge")  # noqa: E731
            inner = [pad(a[k] + frac * (a[k + 1] - a[k])) for a in (theta, *kin)]
            return self._torque(inner[0], z, inner[1:])[:k.size]
        # sigma 0: from the residual at x itself, so the mask is a function of x alone
        sigma = self.reversal_sigma or noise_sigma(self.y - (samples if self._lag(x) <= 0 else self.model(x)))
        return reversal_keep(samples, mids, sigma, evaluate) & (True if self.measured is None else self.measured)

    def start(self, x):
        return phase_and_speed_start(self, x)

    def parameter_vector(self, x):
        return self.z(x)[:self.p0.size]


INTERVAL_SUBPOINTS = 8  # points per sample interval of the interval-average model
# interval_geometry's value for columns from the smooth formula on every sample, steps included: a
# direction for one cheap step that only ranks starts (the sub-sample runs are ~80 % of an interval
# Jacobian's cost)
SMOOTH_COLUMNS = "smooth"
INTERVAL_STEP = 5e-5  # its difference step, of the housing's larger semi-axis (~1 um on a 22 mm housing)


def interval_geometric(name) -> bool:
    """The housing's centre and harmonic amplitudes: defects that act through the friction
    reversals' instants (ConstantSpeedProblem._interval_columns)."""
    n = base_name(name)
    return n.startswith("housing.center.") or (n.startswith("housing.harmonics.") and n.endswith(".amplitude"))


_SAMPLE_FNS: dict = {}  # per (variant key, directions[, samples]): see sample_torque


def sample_torque(kern, directions: int, samples: int) -> ca.Function:
    """One sample's drive torque at angle theta and drive time tau given z (runtime parameters,
    theta0, speed, delay, torque_offset, ripple_cos, ripple_sin), the ripple order k and the drive
    time's rates g = dtau/dt, gd = d2tau/dt2 (1 and 0 at a constant speed; see sampled.drive_kinematics):
    the speed and acceleration come from the ripple at the nominal angle theta0 + speed (tau -
    delay), times g (chain rule) -- with, for directions m > 0, its derivatives along the m columns
    of a seed matrix S; mapped over `samples` samples. Inputs (theta, tau, z, k, g, gd[, S])."""
    key = (kern.key, directions)
    if key not in _SAMPLE_FNS:
        npar = len(layout(kern.structure))
        th, t, k, g, gd = (ca.MX.sym(s) for s in ("theta", "tau", "k", "g", "gd"))
        z = ca.MX.sym("z", npar + len(Z_SPECIAL))
        theta0, w0, delay, offset, rc, rs = (z[npar + i] for i in range(len(Z_SPECIAL)))
        _, w, wd = drive_motion(theta0 + w0 * (t - delay), theta0, w0, rc, rs, k, g, gd, ca)
        tq = kern["inverse_dynamics"](th, w, wd, z[:npar])[0] + offset
        if directions == 0:
            _SAMPLE_FNS[key] = ca.Function("torque", [th, t, z, k, g, gd], [tq])
        else:
            S = ca.MX.sym("S", z.size1(), directions)
            _SAMPLE_FNS[key] = ca.Function("torque_dir", [th, t, z, k, g, gd, S], [tq, ca.jtimes(tq, z, S)])
    mkey = key + (samples,)
    if mkey not in _SAMPLE_FNS:
        _SAMPLE_FNS[mkey] = map_samples(_SAMPLE_FNS[key], samples)
    return _SAMPLE_FNS[mkey]


def torque_at(kern, theta, z, k, tau, g, gd) -> np.ndarray:
    """`sample_torque(kern, 0, n)` evaluated at NumPy theta, tau, g, gd (n samples), z and ripple
    order k: through the SIMD inverse dynamics (sampled.simd_torque; the same model to ~1e-14 of the
    torque scale, ~10-25x the samples per second) where this machine has it, else the CasADi map."""
    fast = fast_kernel(kern.structure)
    if fast is None:
        return np.asarray(sample_torque(kern, 0, theta.size)(theta, tau, z, k, g, gd)).ravel()
    return simd_torque(fast, theta, z, k, tau, g, gd)


def start_and_bounds(names, pv, starts, initial=None):
    """Start values and bounds of the fit names (every problem): a start given by the caller, else
    the measurement's (theta0, speed, ...), else the config value (an alias: its first target's --
    mu is the housing's dynamic COF); bounds from the registries."""
    initial = initial or {}

    def start(n):
        if n in initial:
            return float(initial[n])
        if n in starts:
            return float(starts[n])
        return float(pv.values[n if n in pv.values else alias_targets(n)[0]])

    lower, upper = zip(*[fit_bounds(n, pv.structure) for n in names]) if names else ((), ())
    return np.array([start(n) for n in names], dtype=float), np.array(lower), np.array(upper)


SPEED_COLUMN_Z = 4.0  # half-width of a speed column's band, in standard errors of its mean


def speed_band(cfg, data):
    """(lowest, highest) speed a fit may give a measurement. Without a speed column: the configured
    speed +- operation.speed_tolerance (the operating point is known; a spectral peak elsewhere
    is a disturbance, not the shaft). With one: its mean (over whole revolutions) +- SPEED_COLUMN_Z
    standard errors of that mean, the column's noise taken as white (its robust sigma from third
    differences, which an exact column's own ripple hardly enters -- a 2.8 % order-3 ripple at
    20 kHz reads as 5e-3 rad/s where first differences read 0.7 --, / sqrt(n)): a
    0.3 % noisy column's mean over 1 s is known to ~3e-5, which over the record turns the angle by
    0.01 rad -- with a large shaft-synchronous effect the torque knows the speed far better. None
    with no speed set, with a column that has a significant slow trend (the model follows the
    trend), or an exact one (zero noise)."""
    if cfg.mode != "speed" or not cfg.speed:
        return None
    if data.speed is not None:
        if data.speed_trend() is not None:
            return None
        se = noise_sigma(data.speed, order=3) / math.sqrt(max(data.n, 1))
        mean = data.mean_speed()
        return (mean - SPEED_COLUMN_Z * se, mean + SPEED_COLUMN_Z * se) if se > 0 else None
    return cfg.speed * (1 - cfg.speed_tolerance), cfg.speed * (1 + cfg.speed_tolerance)


def half_band(cfg, data) -> float:
    """Half the width of the measurement's speed band (the nominal tolerance without one)."""
    band = speed_band(cfg, data)
    return 0.5 * (band[1] - band[0]) if band is not None else cfg.speed_tolerance * (cfg.speed or 0.0)


def following(cfg):
    """The derived defaults the config did not set: they follow their inputs when those are fitted."""
    return tuple(q for q in DERIVED if q.name not in cfg.given)


def slot_ratio(v) -> float:
    """The configured slot/housing dynamic COF ratio that ties the slot COF to mu (1 with a
    frictionless nominal housing: the slot COF then equals mu)."""
    mu_h, mu_s = v["friction.housing.dynamic"], v["friction.slot.dynamic"]
    return mu_s / mu_h if mu_h > 0 else 1.0


def parameter_map(index, p0, val, mu_slot_fixed, ratios, follow=()):
    """The runtime parameter vector with the fitted values `val` (name -> expression) put in:
    mu sets the housing COF (static scaled by the configured ratio) and, unless mu_slot is fitted,
    the slot COF in the configured slot/housing proportion (ratios[2]); an alias sets its targets
    (housing.radius: both semi-axes); any other name is a
    parameter path; a derived default in `follow` is recomputed from its fitted inputs."""
    numeric = isinstance(p0, np.ndarray) and all(isinstance(e, NUMBERS) for e in val.values())
    # numbers: one float array written in place (the same float operations, ~10x less Python
    # than a list of ~40 scalars checked one by one); expressions: a list for CasADi's vertcat
    p = np.array(p0, dtype=float).reshape(-1) if numeric else [p0[i] for i in range(p0.shape[0])]

    def setp(name, expr):
        p[index[name]] = expr

    mu_slot = mu_slot_fixed
    if "mu" in val:
        setp("friction.housing.dynamic", val["mu"])
        setp("friction.housing.static", val["mu"] * ratios[0])
        if "mu_slot" not in val:
            mu_slot = val["mu"] * ratios[2]  # tied to mu in the configured proportion
    if "mu_slot" in val:
        mu_slot = val["mu_slot"]
    if "mu" in val or "mu_slot" in val:
        setp("friction.slot.dynamic", mu_slot)
        setp("friction.slot.static", mu_slot * ratios[1])
    for nm, e in val.items():
        for target in alias_targets(nm) or ((nm,) if nm in index else ()):
            setp(target, e)
    for q in follow:
        if any(n in val for n in q.inputs):
            setp(q.name, derive(q.derived, {n: p[index[n]] for n in q.inputs}))
    if numeric:
        return p.reshape(-1, 1)
    if all(isinstance(e, NUMBERS) for e in p):
        return np.array(p, dtype=float).reshape(-1, 1)  # numbers: CasADi's vertcat costs ~0.5 ms a call
    return ca.vertcat(*p)


NUMBERS = (float, int, np.floating, np.integer)
