"""Vane friction from the current's vane-passing ripple of a fast bench log (spec §10).

A bench log's block means (pumpdown_fit) see the pump's mean torque, where vane friction (mu) and
the motor's friction torque add: the mean current cannot tell them apart. The torque's ripple at
the vane-passing orders (N, 2N, ... of the shaft's rotation) can: the motor's friction is a
constant torque, while the vanes' friction follows their normal forces around the revolution.

The shaft's load torque is reconstructed from the motor equations
    V = R i + L di/dt + k omega,    (I_rotor + I_motor) omegadot = k i - tau_f - tau_pump,
at each vane-passing order h as a harmonic: the channels' harmonics come from a least-squares
regression on cos/sin(h theta) plus a slow quadratic trend over a window, and at the order's
frequency Omega_h = h omega the derivatives are exact factors, so the winding's L/R filter and the
inertia are undone without numerical differentiation:
    omega_h = (V_h - (R + j Omega_h L) i_h) / k   (or the speed column's harmonic),
    tau_h   = k i_h - (I_rotor + I_motor) j Omega_h omega_h.
The shaft angle theta comes from the speed column, else the back-EMF integrated (the L di/dt term
integrates to L (i - i0): no derivative either); its scale is first refined so that the current's
order-N line is sharpest (a 0.3 % error in R would turn the order-N phase by radians over a window),
then fitted as a nuisance near it, its uncertainty in mu's interval.

The window is fitted in SUB_WINDOWS consecutive parts, each order's harmonic in each part. A wrong
scale turns each order's phase in proportion to the angle, so from one part to the next; over a single
part the lines' own drift (their phase turns as the booster empties) converts it into an amplitude
change as well, which is what mu changes: with one harmonic per order over the whole window the scale
and mu were confounded (the tests' 2 kHz twin, orders 4 and 8: mu's standard error 2.4 % of mu with
the scale known, 12 % with it fitted). The parts' phase progression fixes the scale instead (1.0 %).

Assumption on the gas: the window is the log's end (late in the pump-down, the booster pressure
varying least), and the gas torque is NOT assumed away: the reference ripple is the pump-down
model's own load torque (gas, vane friction and inertia) over the same window, at the bench fit's
values. So mu is fitted in the harmonic domain, tau_h(measured) = exp(j h phi) tau_h(model; mu),
with the phase phi free (a bench log has no angle reference). The model's harmonics are linear in
mu to well below the estimates' errors over the bracket used (re-linearised when the estimate
leaves it); the interval is inflated by the misfit (chi2 / dof) when that exceeds the noise.
What the ripple says of motor.friction: the mean current needs tau_pump(mu) + friction, so with
the ripple's mu the friction is the bench fit's plus the model's mean torque per unit mu times
(the fit's mu - the ripple's).

Resolution: an order is usable below NYQUIST_SHARE of the Nyquist frequency, and the ripple is
resolved when at least MIN_ORDERS vane-passing orders are (the threshold rate of `threshold_rate`;
docs/explanation/bench-log.md has the twin experiments over sample rates). Below it, and when the
95 % interval reaches mu = 0, there is no number, and the note says why.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import block_diag

from ..tolerances import BENCH_FIT_ATOL, BENCH_FIT_RTOL

NYQUIST_SHARE = 0.8  # an order is usable below this share of the Nyquist frequency
MIN_ORDERS = 2  # vane-passing orders a ripple estimate needs (one complex harmonic fixes the phase only)
MAX_ORDERS = 4  # vane-passing orders used at most (the higher ones are small against the noise)
WINDOW_REVOLUTIONS = 100  # the window: the log's last this many revolutions ...
WINDOW_SHARE = 0.5  # ... at most this share of the log (the start is the run-up)
MIN_REVOLUTIONS = 10  # a window shorter than this does not separate the orders from the trend
SUB_WINDOWS = 2  # the window's parts, each with its own harmonics (module doc: the angle's scale)
MODEL_SAMPLES_PER_REVOLUTION = 128  # the model's reference ripple is sampled this finely
MOTOR_FRICTION_SPEED = 0.5  # rad/s, the compiled model's tanh of the motor friction (spec §8)
SCALE_SPAN = 0.03  # the back-EMF angle's scale is searched within +-3 % ...
SCALE_PHASE = 0.05  # ... on steps turning order N by this many radians over the window
# the sharpest line is off by ~0.1 % (its phase drifts with the pressure): the fit takes the scale
# within +-SCALE_LOCAL of it that the model's ripple matches best
SCALE_LOCAL = 0.004
MU_BRACKET = 0.1  # the model's ripple is linearised between mu and mu (1 + this)
RELINEARISE = 2  # re-linearisations when the estimate leaves the bracket
Z95 = 1.959964


def usable_orders(vanes, speed, rate) -> list[int]:
    """The vane-passing orders (multiples of `vanes`) whose frequency at `speed` [rad/s] lies below
    NYQUIST_SHARE of the Nyquist frequency of `rate` [Hz], at most MAX_ORDERS of them."""
    f_rev = speed / (2 * np.pi)
    limit = NYQUIST_SHARE * 0.5 * rate
    return [vanes * m for m in range(1, MAX_ORDERS + 1) if vanes * m * f_rev < limit]


def threshold_rate(vanes, speed) -> float:
    """The lowest sample rate [Hz] at which MIN_ORDERS vane-passing orders are usable at `speed`."""
    return MIN_ORDERS * vanes * speed / (2 * np.pi) / (NYQUIST_SHARE * 0.5)


def motor_values(cfg, values=None) -> dict:
    """The motor's constants (config, overridden by fitted `values`), the shaft's total inertia."""
    v = {**cfg.pneumatic.values, **(values or {})}
    keys = ("motor.constant", "motor.resistance", "motor.inductance", "motor.friction")
    out = {k.split(".")[1]: float(v[k]) for k in keys}
    out["inertia"] = float(v["motor.inertia"]) + float(cfg.values["rotor.inertia"])
    return out


def shaft_torque(log, motor) -> np.ndarray:
    """The pump's load torque per sample, k i - tau_f - I omegadot, omega from the speed column or the
    back-EMF; derivatives by second-order differences (a noise-free or finely sampled log: the fit
    uses the harmonic form, `torque_harmonics`)."""
    t, i = log.time, log.current
    omega = log.speed if log.speed is not None else \
        (log.voltage - motor["resistance"] * i - motor["inductance"] * np.gradient(i, t)) / motor["constant"]
    tau_f = motor["friction"] * np.tanh(omega / MOTOR_FRICTION_SPEED)
    return motor["constant"] * i - tau_f - motor["inertia"] * np.gradient(omega, t)


def shaft_angle(log, motor, sl) -> np.ndarray:
    """The shaft angle over the window's samples `sl` (from its start): the speed column or the
    back-EMF integrated, L di/dt integrating to L (i - i0)."""
    t, i = log.time[sl], log.current[sl]
    if log.speed is not None:
        w = log.speed[sl]
        return np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))])
    e = log.voltage[sl] - motor["resistance"] * i
    th = np.concatenate([[0.0], np.cumsum(0.5 * (e[1:] + e[:-1]) * np.diff(t))])
    return (th - motor["inductance"] * (i - i[0])) / motor["constant"]


def refine_angle(theta, current, vanes) -> tuple:
    """The angle scaled so that the current's order-`vanes` line is sharpest (scale within
    +-SCALE_SPAN); returns (theta, scale)."""
    span = max(float(theta[-1] - theta[0]), 1e-300)
    step = SCALE_PHASE / (vanes * span)
    scales = 1.0 + np.arange(-SCALE_SPAN, SCALE_SPAN + step, step)
    y = current - current.mean()
    power = [abs(np.dot(y, np.exp(-1j * vanes * s * theta))) for s in scales]
    k = int(np.argmax(power))
    if 0 < k < len(scales) - 1:  # the peak between grid points (parabola through three)
        a, b, c = power[k - 1], power[k], power[k + 1]
        d = 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) != 0 else 0.0
        s = scales[k] + d * step
    else:
        s = scales[k]
    return theta * s, float(s)


def harmonics(y, t, theta, orders) -> tuple:
    """Least-squares harmonics of y (samples, or samples x channels) at `orders` of theta with a
    quadratic trend: complex C_h (y ~ sum Re(C_h exp(j h theta))), per channel, and the covariance
    of (Re C_h, Im C_h) stacked, from the fit's residual variance (a list for several channels)."""
    Y = np.asarray(y, float).reshape(len(t), -1)
    u = (t - t.mean()) / max(np.ptp(t), 1e-300)
    cols = [np.ones_like(u), u, u * u]
    for h in orders:
        cols += [np.cos(h * theta), -np.sin(h * theta)]
    A = np.column_stack(cols)
    G = np.linalg.inv(A.T @ A)  # well conditioned: a window holds many periods of every order
    coef = G @ (A.T @ Y)
    R = Y - A @ coef
    s2 = np.sum(R * R, axis=0) / max(len(t) - A.shape[1], 1)
    c = (coef[3::2] + 1j * coef[4::2]).T
    covs = [v * G[3:, 3:] for v in s2]
    return (c[0], covs[0]) if np.ndim(y) == 1 else (c, covs)


def as_real(z) -> np.ndarray:
    """Complex harmonics as the stacked (Re, Im) pairs of `harmonics`' covariance."""
    return np.column_stack([np.real(z), np.imag(z)]).ravel()


def complex_factor(c) -> np.ndarray:
    """The real 2x2 matrix of multiplying a (Re, Im) pair by the complex c."""
    return np.array([[c.real, -c.imag], [c.imag, c.real]])


def torque_harmonics(log, motor, sl, theta, orders) -> tuple:
    """The load torque's harmonics at `orders` over the window `sl` (module doc) and their
    covariance (the channels' noises independent)."""
    t = log.time[sl]
    speed = float((theta[-1] - theta[0]) / (t[-1] - t[0]))
    k, I, R, L = motor["constant"], motor["inertia"], motor["resistance"], motor["inductance"]
    Om = np.array(orders, float) * speed
    other = log.speed if log.speed is not None else log.voltage
    (ci, cx), (Ci, Cx) = harmonics(np.column_stack([log.current[sl], other[sl]]), t, theta, orders)
    if log.speed is not None:
        a_i, a_x = np.full(len(orders), k + 0j), -1j * I * Om
    else:
        a_i = k + 1j * I * Om * (R + 1j * Om * L) / k
        a_x = -1j * I * Om / k
    tau = a_i * ci + a_x * cx
    Mi, Mx = (block_diag(*[complex_factor(c) for c in a]) for a in (a_i, a_x))
    return tau, Mi @ Ci @ Mi.T + Mx @ Cx @ Mx.T


def window_parts(sl, parts=SUB_WINDOWS) -> list:
    """The window's samples `sl` in `parts` consecutive slices of (nearly) equal length."""
    edges = np.linspace(sl.start, sl.stop, parts + 1).round().astype(int)
    return [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def parts_harmonics(log, motor, sl, theta, orders, parts=SUB_WINDOWS) -> tuple:
    """torque_harmonics over each part of the window `sl` (theta over the whole window, from its
    start), stacked part after part: the harmonics and their block-diagonal covariance."""
    taus, covs = [], []
    for part in window_parts(sl, parts):
        tau, cov = torque_harmonics(log, motor, part, theta[part.start - sl.start:part.stop - sl.start], orders)
        taus.append(tau)
        covs.append(cov)
    return np.concatenate(taus), block_diag(*covs)


@dataclass
class RippleFit:
    """The ripple's estimate of mu (or why there is none) and what it says of motor.friction."""

    resolved: bool
    reason: str  # why not resolved, or ""
    sample_rate: float
    threshold: float  # Hz, the lowest rate resolving MIN_ORDERS orders at the window's speed
    orders: list = field(default_factory=list)
    window: tuple = ()  # (start, end) s
    speed: float = 0.0
    pressure: tuple = ()  # booster pressure at the window's ends, Pa
    mu: float | None = None
    stderr: float | None = None
    phase: float | None = None  # rad, the log's angle against the model's
    scale: float = 1.0  # the back-EMF angle's refinement
    chi2: float | None = None  # weighted residual sum of squares, with `dof`
    dof: int = 0
    mu_mean: float | None = None  # the mu the bench fit explained the mean current with (fitted or held)
    friction: float | None = None  # motor.friction the two mus imply, N m
    friction_stderr: float | None = None
    measured: list = field(default_factory=list)  # torque harmonics, (Re, Im) N m per order, part after part
    model: list = field(default_factory=list)

    @property
    def interval(self):
        return (self.mu - Z95 * self.stderr, self.mu + Z95 * self.stderr) if self.mu is not None else None

    def notes(self) -> list[str]:
        if not self.resolved:
            return [f"vane-passing ripple not used: {self.reason}"]
        lo, hi = self.interval
        out = [f"vane-passing ripple (orders {', '.join(map(str, self.orders))}, {self.window[0]:.3g}-"
               f"{self.window[1]:.3g} s at {self.speed:.4g} rad/s): mu {self.mu:.4g} ± {self.stderr:.2g} "
               f"(95%: {lo:.4g} .. {hi:.4g})"]
        if self.mu_mean is not None and self.friction is not None:
            out.append(f"the mean current was explained with mu {self.mu_mean:.4g}; vane friction from the ripple "
                       f"leaves motor.friction {self.friction:.3g} ± {self.friction_stderr:.2g} N m (the mean "
                       "current's torque not explained by the vanes)")
        return out

    def to_json(self) -> dict:
        d = {k: getattr(self, k) for k in ("resolved", "reason", "sample_rate", "threshold", "orders", "speed",
                                           "mu", "stderr", "phase", "scale", "chi2", "dof", "mu_mean",
                                           "friction", "friction_stderr", "measured", "model")}
        d.update(window=list(self.window), pressure=list(self.pressure),
                 lower95=self.interval[0] if self.resolved else None,
                 upper95=self.interval[1] if self.resolved else None,
                 units={"mu": "-", "threshold": "Hz", "speed": "rad/s", "friction": "N m", "measured": "N m"})
        return d


def ripple_window(log, motor, vanes) -> tuple:
    """The window's samples: the log's last WINDOW_REVOLUTIONS revolutions at its final speed, at
    most WINDOW_SHARE of it; and that speed (back-EMF or speed column over the last tenth)."""
    tail = slice(int(0.9 * log.n), None)
    speed = float(np.mean(log.speed[tail])) if log.speed is not None else float(
        (np.mean(log.voltage[tail]) - motor["resistance"] * np.mean(log.current[tail])) / motor["constant"])
    duration = float(log.time[-1] - log.time[0])
    span = min(WINDOW_REVOLUTIONS * 2 * np.pi / max(speed, 1e-9), WINDOW_SHARE * duration)
    start = int(np.searchsorted(log.time, log.time[-1] - span))
    return slice(start, log.n), speed


def model_runs(cfg, log, ps, t_end, rate, kern, rtol=BENCH_FIT_RTOL, atol=BENCH_FIT_ATOL) -> list:
    """[(grid times from the log's start, states)] of the pump-down model driven by the log's
    voltage up to t_end on a uniform grid at `rate`, one per parameter vector (batched)."""
    from ..kernels.pneumatic import parameter_index
    from ..pneumatics import run
    from .bench_model import BenchModel, grid_runs

    bm = BenchModel(cfg, log.time, log.voltage, log.start_pressure(),
                    float(log.speed[0]) if log.speed is not None else 0.0, rtol, atol, kern)
    n = int(np.floor(t_end * rate + 1e-9)) + 1
    grid = np.arange(n) / rate
    x0s = [bm.start_state(p) for p in ps]
    if any(p[parameter_index(kern.structure, "valve.reed")] > 0.5 for p in ps):  # valve events
        return [(grid, run.integrate(cfg, grid[-1] * (1 + 1e-12), rate, p=p, x0=x0, rtol=rtol, atol=atol,
                                     kern=kern, drive=bm.drive).states[:n]) for p, x0 in zip(ps, x0s)]
    runs = grid_runs(kern, grid, bm.drive, run.state_scale(x0s[0], ps[0], kern.structure), rtol, atol)
    return [(grid, X) for X in runs.runs(x0s, ps)]


def model_harmonics(kern, p, grid, X, windows, orders) -> tuple:
    """The model's load torque (torque output less the rotor's inertia term) over the windows
    [(start, end)] [s from the log's start], the parts of one: its harmonics at `orders` of the
    model's angle in each, stacked, and its mean over them all."""
    from ..kernels.pneumatic import parameter_index
    from ..pneumatics import run

    sel = (grid >= windows[0][0]) & (grid <= windows[-1][1])
    o = run.evaluate_outputs(kern, X[sel], p, ["torque", "omegadot"])
    tau = o["torque"] - p[parameter_index(kern.structure, "rotor.inertia")] * o["omegadot"]
    t, theta = grid[sel], X[sel, 0]
    cs = [harmonics(tau[(t >= a) & (t <= b)], t[(t >= a) & (t <= b)], theta[(t >= a) & (t <= b)], orders)[0]
          for a, b in windows]
    return np.concatenate(cs), float(np.mean(tau))


def scaled_fit(log, motor, sl, theta, orders, mu_a, a, d, scales) -> tuple:
    """The fit (fit_phase_and_mu) at the angle scale of `scales` whose weighted misfit is least;
    returns (scale, torque harmonics, their covariance, the fit)."""
    best = None
    for s in scales:
        tau, cov = parts_harmonics(log, motor, sl, theta * s, orders)
        est = fit_phase_and_mu(tau, cov, orders, mu_a, a, d)
        if best is None or est["chi2"] < best[3]["chi2"]:
            best = (s, tau, cov, est)
    if len(scales) > 1:  # the scale's own uncertainty in mu's interval: its column in the Jacobian
        s, tau, cov, _ = best
        h = scales[1] - scales[0]
        up, down = (parts_harmonics(log, motor, sl, theta * (s + e), orders)[0] for e in (h, -h))
        best = (s, tau, cov, fit_phase_and_mu(tau, cov, orders, mu_a, a, d, (up - down) / (2 * h)))
    return best


def fit_phase_and_mu(tau, cov, orders, mu_a, a, d, nuisance=None) -> dict:
    """mu and phase phi of tau_h = exp(j h phi) (a_h + (mu - mu_a) d_h), weighted by the inverse of
    the harmonics' covariance: phi on a grid (mu in closed form), then Gauss-Newton in both. tau, a
    and d hold the orders once per part of the window (parts_harmonics), or once.
    nuisance: d tau / d(a parameter fitted elsewhere), a column of the Jacobian for the interval."""
    h = np.resize(np.asarray(orders, float), len(tau))
    W = np.linalg.pinv(cov)

    def parts(phi):
        e = np.exp(1j * h * phi)
        return as_real(tau - e * a), as_real(e * d)

    def best_delta(phi):
        y, g = parts(phi)
        delta = float(g @ W @ y) / max(float(g @ W @ g), 1e-300)
        r = y - delta * g
        return float(r @ W @ r), delta

    phis = np.linspace(0.0, 2 * np.pi / orders[0], 180, endpoint=False)
    phi = phis[int(np.argmin([best_delta(f)[0] for f in phis]))]
    delta = best_delta(phi)[1]
    for _ in range(20):
        e = np.exp(1j * h * phi)
        m = a + delta * d
        r = as_real(tau - e * m)
        J = np.column_stack([-as_real(e * d), -as_real(1j * h * e * m)])
        A = J.T @ W @ J
        step = np.linalg.solve(A, -J.T @ W @ r)
        delta, phi = delta + step[0], phi + step[1]
        if abs(step[0]) < 1e-10 * max(abs(mu_a), 1e-3) and abs(step[1]) < 1e-10:
            break
    e = np.exp(1j * h * phi)
    r = as_real(tau - e * (a + delta * d))
    if nuisance is not None:
        J = np.column_stack([J, as_real(nuisance)])
        A = J.T @ W @ J
    chi2, dof = float(r @ W @ r), 2 * len(h) - J.shape[1]
    inflate = max(1.0, chi2 / dof) if dof > 0 else 1.0  # a model misfit widens the interval
    se = float(np.sqrt(np.linalg.inv(A)[0, 0] * inflate))
    return {"mu": mu_a + delta, "stderr": se, "phase": float(np.mod(phi, 2 * np.pi / orders[0])),
            "chi2": chi2, "dof": dof}


def unresolved_reason(vanes, speed, rate, orders, threshold, span) -> str:
    """Why this log's ripple gives no estimate, or "" when it does (span: the window, s)."""
    f_pass = vanes * speed / (2 * np.pi)
    if not np.isfinite(speed) or speed <= 0:
        return "the pump does not turn at the log's end (back-EMF or speed column)"
    if len(orders) < MIN_ORDERS:
        return (f"the log's {rate:.4g} Hz resolves {len(orders)} vane-passing order(s) at its final speed "
                f"{speed:.4g} rad/s (vanes pass at {f_pass:.4g} Hz); a ripple estimate needs {MIN_ORDERS} orders "
                f"below {NYQUIST_SHARE:g} of the Nyquist frequency, a log of at least {threshold:.4g} Hz")
    if speed * span < MIN_REVOLUTIONS * 2 * np.pi:
        return (f"the log's second half holds {speed * span / (2 * np.pi):.3g} revolutions; the ripple needs "
                f"{MIN_REVOLUTIONS} (a longer log)")
    return ""


def measured_angle(log, motor, sl, vanes) -> tuple:
    """The log's shaft angle over the window, its refined scale and the scales the fit searches
    (the back-EMF angle's scale is a nuisance of the fit, near the sharpest line)."""
    theta = shaft_angle(log, motor, sl)
    if log.speed is not None:
        return theta, 1.0, [1.0]
    theta, s0 = refine_angle(theta, log.current[sl], vanes)
    step = SCALE_PHASE / (vanes * float(theta[-1] - theta[0]))
    return theta, s0, 1.0 + np.arange(-SCALE_LOCAL, SCALE_LOCAL + step / 2, step)


def linearised_fit(reference, mu0, fit) -> tuple:
    """The model's ripple linear in mu between two runs (reference(mu) -> (harmonics, mean
    torque)), re-linearised when fit(mu_a, a, d) -> (scale, tau, cov, est) leaves the bracket.
    Returns (the pair of mus, their references, (scale, tau, est))."""
    ref = {}
    pair = [mu0, mu0 * (1 + MU_BRACKET)]
    for attempt in range(RELINEARISE + 1):
        for m in pair:
            if m not in ref:
                ref[m] = reference(m)
        (a, _), (b, _) = ref[pair[0]], ref[pair[1]]
        scale, tau, _, est = fit(pair[0], a, (b - a) / (pair[1] - pair[0]))
        lo, hi = min(pair), max(pair)
        if lo - MU_BRACKET * lo <= est["mu"] <= hi + MU_BRACKET * hi or est["mu"] <= 0 or attempt == RELINEARISE:
            break
        far = max(pair, key=lambda m: abs(m - est["mu"]))
        pair = [est["mu"], pair[1 - pair.index(far)]]
    return pair, ref[pair[0]], ref[pair[1]], (scale, tau, est)


def ripple_mu(cfg, log, vector, values, mu_stderr=None, kern=None) -> RippleFit:
    """mu from a bench log's vane-passing ripple (module doc). vector(values) -> the runtime
    parameter vector; values: the bench fit's values by name, 'mu' among them (the mu the mean
    current was explained with); mu_stderr: its standard error when the bench fit fitted it."""
    from ..kernels.pneumatic import kernels

    kern = kernels(cfg) if kern is None else kern
    motor, vanes = motor_values(cfg, values), cfg.vanes
    sl, speed = ripple_window(log, motor, vanes)
    rate = 1.0 / log.step
    orders = usable_orders(vanes, speed, rate) if speed > 0 else []
    t0 = log.time[0]
    window = (float(log.time[sl.start] - t0), float(log.time[-1] - t0))
    out = RippleFit(resolved=False, reason="", sample_rate=rate, threshold=threshold_rate(vanes, max(speed, 0.0)),
                    orders=orders, window=window, speed=speed,
                    pressure=(float(log.booster_pressure[sl.start]), float(log.booster_pressure[-1])))
    out.reason = unresolved_reason(vanes, speed, rate, orders, out.threshold, window[1] - window[0])
    if out.reason:
        return out
    theta, s0, scales = measured_angle(log, motor, sl, vanes)
    mu_used = float(values["mu"])
    model_rate = max(MODEL_SAMPLES_PER_REVOLUTION * speed / (2 * np.pi), rate)

    parts = [(float(log.time[q.start] - t0), float(log.time[q.stop - 1] - t0)) for q in window_parts(sl)]

    def reference(m):
        p = vector({**values, "mu": m})
        (grid, X), = model_runs(cfg, log, [p], window[1], model_rate, kern)
        return model_harmonics(kern, p, grid, X, parts, orders)

    pair, (a, mean_a), (b, mean_b), (scale, tau, est) = linearised_fit(
        reference, mu_used, lambda mu_a, a, d: scaled_fit(log, motor, sl, theta, orders, mu_a, a, d, scales))
    out.scale = float(s0 * scale)
    if est["mu"] - Z95 * est["stderr"] <= 0:
        out.reason = (f"the ripple over {window[0]:.3g}-{window[1]:.3g} s does not determine mu: its 95 % interval "
                      f"reaches 0 (± {Z95 * est['stderr']:.2g}; the channels' noise against a ripple of "
                      f"{np.abs(tau[0]):.2g} N m at order {orders[0]}: a longer or quieter log)")
        return out
    out.resolved = True
    out.mu, out.stderr, out.phase, out.chi2, out.dof = (est[k] for k in ("mu", "stderr", "phase", "chi2", "dof"))
    slope = (mean_b - mean_a) / (pair[1] - pair[0])  # the pump's mean torque per unit mu
    out.measured, out.model = as_real(tau).tolist(), as_real(a + (out.mu - pair[0]) * (b - a) / (pair[1] - pair[0]))
    out.model = out.model.tolist()
    out.mu_mean = mu_used
    out.friction = motor["friction"] + slope * (mu_used - out.mu)
    out.friction_stderr = abs(slope) * float(np.hypot(out.stderr, mu_stderr or 0.0))
    return out


def bench_ripple(cfg, log, vector, values, mu_estimate=None, kern=None) -> RippleFit:
    """ripple_mu at the end of a bench-log fit: `values` the fit's, `mu_estimate` its Estimate of mu
    (when it fitted mu). A failed run of the reference model is a note, not a failed identification."""
    from ..errors import SolverError

    se = mu_estimate.stderr if mu_estimate is not None and mu_estimate.identifiable else None
    try:
        return ripple_mu(cfg, log, vector, values, se, kern)
    except SolverError as e:
        return RippleFit(resolved=False, reason=f"the model's reference ripple could not be computed ({e})",
                         sample_rate=1.0 / log.step, threshold=float("nan"))
