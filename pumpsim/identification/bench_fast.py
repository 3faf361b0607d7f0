"""A fast model of a bench log from the pump's cycle-averaged maps (pneumatics.pumpdown.pump_maps),
and the start it gives the full fit.

The fast model: the booster pressure p_b and the shaft speed omega, driven by the logged voltage V,
  I domega/dt = k i - friction tanh(omega / MOTOR_FRICTION_SPEED) - T(p_b)
  V_b / (R T) dp_b/dt = leak(p_b) - m_rev(p_b) omega / (2 pi)
with the current quasi-static, i = (V - k omega) / R (L / R is a fraction of a sample interval),
T the pump's mean load torque (gas and vane friction) and m_rev the mass it draws per revolution,
both from the maps, interpolated in log p_b. The motor and the booster are in the equations, not in
the maps: motor.* and booster.* change no map. The others (mu, the clearances, the valve) do: the maps
are made at the start values and at one step in each of them, and taken as linear in them.

Classical RK4 on the log's grid (substeps where the motor's mechanical time constant asks), the runs
of a Jacobian as one vectorised integration: ~0.1 s for a 5 s log at 1 kHz against ~3-8 s for one
run of the full model. It is not the full model (it ignores how the maps move with speed, the check
valve, the run-up's inductance and the ripple): its estimates are a start and its Jacobian a guide;
the full model decides the estimates and gives the covariance (pumpdown_fit.identify_bench).
"""
from __future__ import annotations

import math

import numpy as np

from ..pneumatics.pumpdown import orifice_factor
from ..tolerances import STEP_SE
from .bench_model import START_NAME

MAP_POINTS = 8  # booster pressures mapped, geometric between the log's extremes
MAP_STEP = 0.1  # a map parameter's step for the maps' sensitivity, of its scale
# the maps' integration: they agree with rtol 1e-6 ones to ~0.1 % (EVP example) at 0.4 of the cost,
# and the fast model is a guide, not the answer
MAP_RTOL, MAP_ATOL = 1e-4, 1e-5
STAGE_LIMIT = 0.25  # an RK4 step at most this share of the fastest time constant (motor, booster)
MOTOR_FRICTION_SPEED = 0.5  # rad/s, as the kernel's (codegen.pneumatic_model)


def maps_change(name) -> bool:
    """Whether a fitted parameter changes the pump's maps (the motor and booster ones do not)."""
    return not name.startswith(("motor.", "booster."))


def map_pressures(log_pressure, start) -> np.ndarray:
    hi = 1.02 * max(float(start), float(np.max(log_pressure)))
    lo = 0.85 * max(float(np.min(log_pressure)), 1.0)
    return np.geomspace(lo, hi, MAP_POINTS)


def leak_flows(v, p_b):
    """The booster leak's mass flow [kg/s] per kg/s of booster.leak at the booster pressures p_b
    (an array): the kernel's orifice law from the atmosphere, 1 at full vacuum."""
    g = v["gas.gamma"]
    choked = math.sqrt(g) * (2 / (g + 1)) ** ((g + 1) / (2 * (g - 1)))
    return orifice_factor(np.minimum(np.asarray(p_b, float) / v["gas.atmosphere"], 1.0), v) / choked


def _nodes(n, m) -> np.ndarray:
    """Every m-th of n sample indices, the last one included."""
    idx = np.arange(0, n, m)
    return idx if idx[-1] == n - 1 else np.append(idx, n - 1)


class FastBenchModel:
    """The fast model at a BenchModel's grid for the fitted names of a problem (parameter_vector:
    fitted values -> runtime vector); `channels_many(xs)` as BenchModel's, from the maps."""

    def __init__(self, cfg, bench, log_pressure, names, parameter_vector, x0, scale):
        from ..pneumatics.pumpdown import pump_maps

        self.bench, self.names, self.pv = bench, list(names), parameter_vector
        self.x_map = np.asarray(x0, float).copy()
        self.map_cols = [j for j, n in enumerate(self.names) if maps_change(n)]
        pressures = map_pressures(log_pressure, bench.start_pressure)
        base = pump_maps(cfg, pressures, MAP_RTOL, MAP_ATOL, p=bench.split(parameter_vector(self.x_map))[0])
        self.log_p = np.log(base.pressure)
        self.pumping_speed = float(np.max(base.pumping_speed))  # m^3/s: the booster's fastest time constant
        self.base = self._tables(base)
        self.slopes, self.map_seconds = [], base.wall_time
        for j in self.map_cols:
            h = MAP_STEP * scale(j, self.x_map)
            xj = self.x_map.copy()
            xj[j] += h
            m = pump_maps(cfg, pressures, MAP_RTOL, MAP_ATOL, p=bench.split(parameter_vector(xj))[0])
            self.map_seconds += m.wall_time
            self.slopes.append((self._tables(m) - self.base) / h)

    @staticmethod
    def _tables(m) -> np.ndarray:
        """[mass per revolution, load torque] at the mapped pressures."""
        return np.vstack([m.mass_flow * 2 * math.pi / m.speed, m.gas_torque + m.friction_torque])

    def _run_values(self, x):
        x = np.asarray(x, float)
        tab = self.base.copy()
        for j, s in zip(self.map_cols, self.slopes):
            tab = tab + s * (x[j] - self.x_map[j])
        p, start = self.bench.split(self.pv(x))
        return tab, dict(zip(self.bench.names, p), start=start)

    def channels_many(self, xs) -> list:
        runs = [self._run_values(x) for x in xs]
        P, W, I = self._integrate(runs)
        b = self.bench
        out = []
        from .bench_model import block_means

        for k in range(len(runs)):
            out.append({"booster_pressure": P[:, k], "current": block_means(I[:, k], b.edges),
                        "speed": block_means(W[:, k], b.edges)})
        return out

    def _integrate(self, runs):
        b = self.bench
        vs = [v for _, v in runs]
        col = lambda key: np.array([v[key] for v in vs])  # noqa: E731
        R, k, fr = col("motor.resistance"), col("motor.constant"), col("motor.friction")
        inertia = col("rotor.inertia") + col("motor.inertia")
        c_p = col("gas.gas_constant") * col("gas.temperature") / col("booster.volume")
        leak = col("booster.leak")
        tabs = np.stack([t for t, _ in runs])  # (runs, 2, points)
        lp_tab, last, rows = self.log_p, self.log_p.size - 2, np.arange(len(runs))

        def rates(p, w, volt):  # linear in log p_b between the mapped points, held beyond them
            lp = np.clip(np.log(np.maximum(p, 1.0)), lp_tab[0], lp_tab[-1])
            j = np.minimum(np.searchsorted(lp_tab, lp, side="right") - 1, last)
            f = (lp - lp_tab[j]) / (lp_tab[j + 1] - lp_tab[j])
            mrev, load = tabs[rows, :, j].T * (1 - f) + tabs[rows, :, j + 1].T * f
            i = (volt - k * w) / R
            torque = k * i - (fr + load) * np.tanh(w / MOTOR_FRICTION_SPEED)
            return c_p * (leak * leak_flows(vs[0], p) - mrev * w / (2 * math.pi)), torque / inertia

        # the motor's mechanical time constant and the booster's V_b / pumping speed
        tau = min(float(np.min(inertia * R / np.maximum(k, 1e-12) ** 2)),
                  float(np.min(col("booster.volume"))) / max(self.pumping_speed, 1e-300))
        # RK4 steps of whole sample intervals, each at most STAGE_LIMIT tau (substeps where one
        # interval is longer), the voltage its mean over the step; the states interpolated back
        nodes = _nodes(b.n, max(1, int(STAGE_LIMIT * tau / b.step)))
        p, w = col("start"), np.full(len(runs), b.omega0)
        Pn, Wn = [p], [w]
        for i0, i1 in zip(nodes[:-1], nodes[1:]):
            span = b.grid[i1] - b.grid[i0]
            volt = (b.volt_integral[i1] - b.volt_integral[i0]) / span
            n_sub = max(1, int(math.ceil(span / (STAGE_LIMIT * tau))))
            h = span / n_sub
            for _ in range(n_sub):
                k1 = rates(p, w, volt)
                k2 = rates(p + 0.5 * h * k1[0], w + 0.5 * h * k1[1], volt)
                k3 = rates(p + 0.5 * h * k2[0], w + 0.5 * h * k2[1], volt)
                k4 = rates(p + h * k3[0], w + h * k3[1], volt)
                p = p + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
                w = w + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            Pn.append(p)
            Wn.append(w)
        tn = b.grid[nodes]
        Pn, Wn = np.array(Pn), np.array(Wn)
        P = np.column_stack([np.interp(b.grid, tn, Pn[:, j]) for j in range(len(runs))])
        W = np.column_stack([np.interp(b.grid, tn, Wn[:, j]) for j in range(len(runs))])
        I = (b.volt[:, None] - k[None, :] * W) / R[None, :]
        return P, W, I


class FastProblem:
    """A bench-log problem's fit with the fast model in place of the full one (optimiser.gauss_newton
    takes it): the same names, bounds, measured values and noise scaling."""

    def __init__(self, prob, fast):
        self.prob, self.fast = prob, fast
        self.names, self.lower, self.upper, self.y = prob.names, prob.lower, prob.upper, prob.y

    def keep_at(self, x):
        return None

    def model(self, x):
        return self.prob.scaled(self.fast.channels_many([x])[0])

    def model_and_jacobian(self, x, cols=None):
        """The fast model at x and its forward differences in the columns cols (all: None), the
        runs as one vectorised integration."""
        x = np.asarray(x, float)
        xs, hs = self.prob.difference_points(x, range(len(self.names)) if cols is None else cols)
        ms = [self.prob.scaled(c) for c in self.fast.channels_many([x] + xs)]
        return ms[0], np.column_stack([(mj - ms[0]) / h for mj, h in zip(ms[1:], hs)])


FAST_ITERATIONS, FAST_TOL = 10, 1e-4  # the fast fit is a start: a few standard errors off is fine
FULL_STEPS = 5  # full-model steps with its Jacobian, at most (the common case takes 2)
# converged: every parameter's step below STEP_SE of its standard errors (tolerances.py, shared
# with optimiser.gauss_newton's iteration limit)
# a full-model step updates the Jacobian (Broyden) when its largest parameter change is at least this
# share of the difference step: the secant of two tight runs is then as accurate as a loose column
# (its runs' errors over a longer step); over a step of about a standard error it is their noise
# (measured on the 5 s twin log: a second update there shrank the standard errors by 20-30 %)
SECANT_SHARE = 0.25
# Jacobian columns taken from the fast model, not from runs of the full one: the fitted start
# pressure moves the booster's initial mass only, and what follows from it (the booster's pressure
# through the pump's mass per revolution, the current through its load torque) is what the maps
# describe. Measured on the 5 s twin log: the column 1.8 % off the full model's at rtol 1e-6, the
# Gauss-Newton fixed point moved by < 0.005 standard errors and the standard errors by < 1.2 %
# against that column; on 0.5 s logs of a 0.4 L booster 6.6 % off, < 0.02 standard errors, the
# others' standard errors within 0.1 %, its own 5.5 % low (docs, bench-log fit). A run of the full
# model less per Jacobian by differences.
FAST_COLUMNS = (START_NAME,)


def _step(J, r):
    """Gauss-Newton step (column-scaled least squares) and the standard errors from J."""
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    Js = J / scale
    d, *_ = np.linalg.lstsq(Js, r, rcond=None)
    cov = np.linalg.pinv(Js.T @ Js) * max(float(np.mean(r ** 2)), 1.0)
    return d / scale, np.sqrt(np.abs(np.diag(cov))) / scale


def _broyden(J, d, dm):
    """Broyden's rank-one update of J for the step d and the model's change dm, in parameters
    scaled by J's column norms (the parameters' sizes differ by orders of magnitude)."""
    s = np.linalg.norm(J, axis=0)
    s[s == 0] = 1.0
    ds = d * s
    return J + np.outer(dm - J @ d, ds / (ds @ ds)) * s


def fast_then_full(prob, fast, x0, max_iter=30, log=None, loose=None):
    """The fit from the maps' start: Gauss-Newton on the fast model from x0; there the full
    model's forward-difference Jacobian (its run at the fast fit and the steps' runs at once on the
    cores); then its Gauss-Newton steps until one is below STEP_SE standard errors or no longer
    lowers the residual, a step of at least SECANT_SHARE of a difference step correcting the
    Jacobian along itself (Broyden). The covariance comes from that Jacobian.
    loose: the same problem at a looser tolerance (tolerance continuation): the Jacobian's steps
    are its runs (a run at 1e-5 costs ~0.6 of one at 1e-6), the base, the steps, their residuals
    and the convergence test the tight problem's. Returns (FitOutcome, x of the fast fit)."""
    fp = FastProblem(prob, fast)
    x_fast = fast_fit(fp, x0, max_iter)
    history = []

    def accept(xn, mn, stage):
        history.append({"params": dict(zip(prob.names, map(float, xn))), "rms": _rms(prob.y - mn), "stage": stage})
        if log and len(history) > 1:
            log(history[-1])

    x = x_fast.copy()
    fast_cols = fast_columns(prob)
    full = [j for j in range(x.size) if j not in fast_cols]
    m, J_full = prob.model_and_jacobian(x, full) if loose is None else prob.model_and_loose_jacobian(x, loose, full)
    J = np.empty((m.size, x.size))
    J[:, full] = J_full
    if fast_cols:
        J[:, fast_cols] = fp.model_and_jacobian(x, fast_cols)[1]
    accept(x, m, "fast model")
    steps = (prob if loose is None else loose).step * np.array([prob.scale_of(j, x) for j in range(x.size)])
    return _chord_steps(prob, x, m, J, accept, history, SECANT_SHARE * steps), x_fast


def fast_columns(prob) -> list:
    """The indices of prob's Jacobian columns the fast model gives (FAST_COLUMNS; by differences
    only: a sensitivity costs no run of its own)."""
    return [j for j, n in enumerate(prob.names) if n in FAST_COLUMNS and prob.jacobian == "differences"]


def maps_jacobian_text(prob, loose, x) -> str:
    """How fast_then_full took the Jacobian at x (the fit's report says it)."""
    text = prob.jacobian_text(x) if loose is None else (
        f"{loose.jacobian_text(x)}, the steps' runs at rtol {loose.rtol:g} (a {100 * loose.step:g} % step) from the "
        f"base run and the residuals at {prob.rtol:g}")
    fast = [prob.names[j] for j in fast_columns(prob)]
    return text + (f"; the column of {', '.join(fast)} from the fast model (cycle-averaged maps)" if fast else "")


def fast_fit(fp, x0, max_iter) -> np.ndarray:
    """The fast model's Gauss-Newton fit from x0 (FAST_ITERATIONS, FAST_TOL)."""
    from .optimiser import gauss_newton

    return np.asarray(gauss_newton(fp, np.asarray(x0, float), max_iter=min(max_iter, FAST_ITERATIONS),
                                   tol=FAST_TOL).x, float)


# where a full-model step does not lower the residual, x is the full model's minimum only if the
# data cannot tell it from the one the step points to (optimiser.start_test)
NOT_FULL_MINIMUM = ("a full-model step did not lower the residual, yet the fit is NOT at the full model's minimum: "
                    "its Gauss-Newton step points {se} standard errors away (to {to}; F test p = {p:.2g}); the full "
                    "model's steps from the fast (cycle-averaged) model's fit stalled short of the full model's "
                    "minimum -- these estimates are not the full model's fit: do not use them; check the config "
                    "against the pump, or fit fewer parameters (--params)")


def _chord_steps(prob, x, m, J, accept, history, secant):
    """Gauss-Newton steps with the Jacobian J, until one is below STEP_SE standard errors or no
    longer lowers the residual, at most FULL_STEPS; J follows a step that moves some parameter by
    at least its `secant` (Broyden). A step that does not lower the residual ends the fit converged
    only when x passes start_test against J (x inside its own confidence region)."""
    from .optimiser import NO_DECREASE, FitOutcome

    rms = _rms(prob.y - m)
    converged, message = False, f"full-model steps did not settle within {FULL_STEPS}"
    for _ in range(FULL_STEPS + 1):
        dx, se = _step(J, prob.y - m)
        if np.all(np.abs(dx) <= STEP_SE * se):
            converged, message = True, f"full-model step below {STEP_SE:g} standard errors"
            break
        xn = np.clip(x + dx, prob.lower, prob.upper)
        mn = prob.model(xn)
        if _rms(prob.y - mn) >= rms:
            converged, message = _at_minimum(prob, x, dx, prob.y - m, J, NO_DECREASE)
            break
        if np.any(np.abs(xn - x) >= secant):
            J = _broyden(J, xn - x, mn - m)
        x, m, rms = xn, mn, _rms(prob.y - mn)
        accept(x, m, "full model, its Jacobian")
    return FitOutcome(x, prob.y - m, J, history, converged, message)


def _at_minimum(prob, x, dx, r, J, message) -> tuple:
    """(converged, message) where no step from x lowered the residual r (noise sigmas; dx the
    Gauss-Newton step from x with J): `message` when the data cannot tell x from the minimum the
    step points to, else not converged and NOT_FULL_MINIMUM."""
    from .optimiser import START_TEST_LEVEL, start_test

    se, p = start_test(x, dx, r, J, prob.lower, prob.upper, r.size)
    if p >= START_TEST_LEVEL:
        return True, message
    to = ", ".join(f"{n} = {v:.6g}" for n, v in zip(prob.names, np.clip(x + dx, prob.lower, prob.upper)))
    length = f"{se:.3g}" if np.isfinite(se) else "infinitely many (noise-free data)"
    return False, NOT_FULL_MINIMUM.format(se=length, p=p, to=to)


def _rms(r) -> float:
    return float(np.sqrt(np.mean(r ** 2)))
