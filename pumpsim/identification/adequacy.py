"""How well a fitted model describes the measurement, in the terms test engineers use, and where
it does not: the fit percentage (MATLAB's `compare`), the systematic residual against a noise
floor estimated from the record itself, and the misfit at the model's own shaft orders, over
the rotor angle and over time.

Three outcomes:
- adequate: the residual is noise (no systematic part above the noise floor's uncertainty);
- systematic: the model leaves a systematic residual (an effect it lacks: an eccentric rotor, a
  speed ripple, a sensor lag...) but describes what it does model -- the estimates are meaningful,
  their intervals optimistic;
- inadequate: the model's own shaft orders are not in the data as fitted (a wrong vane count or
  housing, a wrong speed, a local minimum): the estimates describe a different pump.

The last test assumes that the configured pump's torque is dominated by the orders it predicts:
a model without shaft orders (a concentric rig at constant speed) gives it nothing to check, and
only the fit percentage and the systematic share are reported.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ..distributions import chi2_sf, norm_sf
from ..signals import high_frequency_noise, order_spectrum, synchronous_average

MODEL_ORDER_POWER = 0.99  # the model's own orders: those carrying this share of its shaft-order power
MAX_ORDER = 64
# the model's own orders may keep this much of the fitted model's amplitude there as misfit, and
# the systematic residual may be this share of the torque's RMS: set on a grid of 6 rigs x (the
# right config with each library effect at SNR 5 and 20 | every other rig's config | a held wrong
# speed): right configs reach 0.34 (a 2-sample sensor lag at order 5 of a 607 rad/s rig) and 0.30,
# wrong pumps 0.48 and above, or a share above 0.5 (the table: docs, bench/adequacy_grid.py)
ORDER_MISFIT_MAX = 0.4
SHARE_MAX = 0.5
ORDER_MISFIT_ALPHA = 1e-3  # the misfit at the model's orders must also be significant against the noise
SYSTEMATIC_ALPHA = 1e-3  # the residual's variance above its high-frequency noise floor (one-sided test)
TIME_SEGMENTS = 4
VERDICTS = ("adequate", "systematic", "inadequate")  # in order of concern


@dataclass
class Adequacy:
    verdict: str  # adequate | systematic | inadequate
    fit_percent: float  # 100 (1 - |y - y_fit| / |y - mean y|)
    noise_sigma: float  # white-noise floor from the residual's high-frequency band [N m]
    systematic_rms: float  # sqrt(residual variance - noise variance), 0 when within the noise [N m]
    systematic_to_noise: float
    systematic_share: float  # systematic RMS / RMS of the fitted torque
    model_orders: list = field(default_factory=list)  # the model's own shaft orders
    order_misfit: float | None = None  # residual amplitude at those orders / the model's there
    order_misfit_p: float | None = None
    worst_orders: list = field(default_factory=list)  # [{"order", "amplitude"}] of the residual
    angle_of_largest: float | None = None  # rotor angle [rad] of the largest synchronous-average residual
    largest_synchronous: float | None = None  # its value [N m]
    segment_rms: list = field(default_factory=list)  # residual RMS per time segment [N m]
    reason: str = ""

    def to_json(self) -> dict:
        return asdict(self)

    def problem(self) -> str | None:
        return self.reason if self.verdict == "inadequate" else None

    def orders_missed(self) -> bool:
        """The model's own shaft orders (the vane passing and its harmonics) stay in the residual:
        a config that is not this pump, not an effect it lacks (ORDER_MISFIT_MAX)."""
        return (self.order_misfit is not None and self.order_misfit > ORDER_MISFIT_MAX
                and self.order_misfit_p < ORDER_MISFIT_ALPHA)

    def warning(self) -> str | None:
        if self.verdict != "systematic":
            return None
        return (f"the model leaves a systematic residual of {self.systematic_rms:.3g} N m RMS "
                f"({self.systematic_to_noise:.1f} x the noise, {100 * self.systematic_share:.2g} % of the "
                f"torque): an effect it lacks; the estimates hold, their intervals are optimistic")

    def summary(self) -> str:
        fit = (f"fit {self.fit_percent:.1f} % (NRMSE)" if self.model_orders
               else "fit % not meaningful (the model's torque has no shaft orders)")
        lines = [f"model adequacy: {self.verdict}; {fit}, noise floor "
                 f"{self.noise_sigma:.3g} N m, systematic residual {self.systematic_rms:.3g} N m "
                 f"({self.systematic_to_noise:.1f} x noise, {100 * self.systematic_share:.2g} % of the torque)"]
        if self.order_misfit is not None:
            lines.append(f"  at the model's own orders {_orders_text(self.model_orders)}: misfit "
                         f"{100 * self.order_misfit:.3g} % of the model's amplitude there")
        if self.verdict != "adequate" and self.worst_orders:
            lines.append("  the misfit lies at shaft orders " + ", ".join(
                f"{o['order']:.2f}" for o in self.worst_orders[:4])
                + (f"; largest at rotor angle {math.degrees(self.angle_of_largest):.0f} deg"
                   if self.angle_of_largest is not None else "")
                + "; RMS per quarter of the record " + ", ".join(f"{s:.3g}" for s in self.segment_rms))
        if self.reason:
            lines.append(f"  {self.reason}")
        return "\n".join(lines)


def _orders_text(orders) -> str:
    return ", ".join(str(k) for k in orders[:6]) + (" ..." if len(orders) > 6 else "")


def order_columns(angle, orders) -> np.ndarray:
    """cos(k angle), sin(k angle) for every order k (2 columns each)."""
    kth = np.outer(np.asarray(angle, dtype=float), np.asarray(orders, dtype=float))
    return np.column_stack([np.cos(kth), np.sin(kth)])


ORDER_CHUNK = 1 << 12  # samples per block of order columns (4096 x 128 columns: 4 MB)


def order_normal_equations(angle, orders, V) -> tuple:
    """G = X^T X and X^T V for the order columns X = order_columns(angle, orders), summed over
    blocks of samples: X itself would be n x 2 len(orders) (1 GB at 10^6 samples and 64 orders)."""
    angle, V = np.asarray(angle, dtype=float), np.asarray(V, dtype=float).reshape(len(angle), -1)
    m = 2 * len(orders)
    G, B = np.zeros((m, m)), np.zeros((m, V.shape[1]))
    for lo in range(0, angle.size, ORDER_CHUNK):
        X = order_columns(angle[lo:lo + ORDER_CHUNK], orders)
        G += X.T @ X
        B += X.T @ V[lo:lo + ORDER_CHUNK]
    return G, B


def normal_solve(G, b) -> np.ndarray:
    """The least-squares coefficients from the normal equations (minimum norm when the columns are
    dependent: a record shorter than the orders' periods)."""
    return np.linalg.lstsq(G, b, rcond=1e-12)[0]


def model_orders(fitted, angle, dt, speed, others=()) -> tuple:
    """The orders carrying MODEL_ORDER_POWER of the fitted torque's shaft-order power (below the
    Nyquist order) and the normal equations of their least-squares columns X: (orders, X^T X,
    X^T [fitted - its mean, *others]); ((), None, None) when the model has no shaft orders."""
    kmax = int(min(MAX_ORDER, 0.9 * math.pi / max(abs(speed) * dt, 1e-300)))
    if kmax < 1 or fitted.size < 4 * kmax + 8:
        return (), None, None
    ks = np.arange(1, kmax + 1)
    G, B = order_normal_equations(angle, ks, np.column_stack([fitted - fitted.mean(), *others]))
    coef = normal_solve(G, B[:, 0])
    power = coef[:kmax] ** 2 + coef[kmax:] ** 2
    total = float(power.sum())
    if total <= 1e-24 * max(float(np.mean(fitted**2)), 1e-300) or total <= 0:
        return (), None, None
    order = np.argsort(power)[::-1]
    keep = np.sort(order[:int(np.searchsorted(np.cumsum(power[order]), MODEL_ORDER_POWER * total)) + 1])
    cols = np.concatenate([keep, keep + kmax])
    return tuple(int(k) for k in ks[keep]), G[np.ix_(cols, cols)], B[cols]


def assess(measured, fitted, angle, dt, speed, fitted_parameters: int = 0) -> Adequacy:
    """The adequacy of a fit (see the module docstring)."""
    y, f = np.asarray(measured, dtype=float), np.asarray(fitted, dtype=float)
    r = y - f
    spread = float(np.linalg.norm(y - y.mean()))
    fit_percent = 100.0 * (1.0 - float(np.linalg.norm(r)) / spread) if spread > 0 else 0.0
    hf = high_frequency_noise(r)
    sigma = float(hf["sigma"])
    # a residual can be white about a mean the fit could not remove (a parameter on its bound, a
    # sign or offset the model lacks): that mean against the white noise's standard error counts too
    mean_z = abs(float(r.mean())) * math.sqrt(r.size) / sigma if sigma > 0 else 0.0
    systematic_p = min(float(hf["p_value"]), 2.0 * float(norm_sf(mean_z)))
    var = float(np.mean((r - r.mean()) ** 2)) + float(r.mean()) ** 2
    sys_rms = math.sqrt(max(var - sigma**2, 0.0))  # reported even when the test below does not reject
    f_rms = math.sqrt(float(np.mean(f**2)))
    out = Adequacy(verdict="adequate", fit_percent=fit_percent, noise_sigma=sigma, systematic_rms=sys_rms,
                   systematic_to_noise=sys_rms / sigma if sigma > 0 else (math.inf if sys_rms > 0 else 0.0),
                   systematic_share=sys_rms / f_rms if f_rms > 0 else 0.0)
    if angle is not None:
        ks, G, B = model_orders(f, angle, dt, speed, others=(r - r.mean(),))
        if ks:
            cm, cr = normal_solve(G, B[:, 0]), normal_solve(G, B[:, 1])
            pm, pr = float(cm @ G @ cm), float(cr @ G @ cr)  # |X c|^2
            dof = G.shape[0]
            F = (pr / dof) / max(sigma**2, 1e-300)
            out.model_orders, out.order_misfit = list(ks), math.sqrt(pr / pm) if pm > 0 else None
            out.order_misfit_p = float(chi2_sf(F * dof, dof))
        sa = synchronous_average(r - r.mean(), angle, bins=72)
        avg = sa["average"]
        if np.any(np.isfinite(avg)):
            j = int(np.nanargmax(np.abs(avg)))
            out.angle_of_largest, out.largest_synchronous = float(sa["angle"][j]), float(avg[j])
        out.worst_orders = _residual_orders(r, dt, speed)
    out.segment_rms = [float(np.sqrt(np.mean(s**2))) for s in np.array_split(r, TIME_SEGMENTS) if s.size]
    what = ("a config that is not this pump (vane count, housing, slot tilt), a wrong speed, or a local "
            "minimum; check the config and the speed, or fit the speed")
    if out.orders_missed():
        out.verdict = "inadequate"
        out.reason = (f"the model cannot describe this measurement: {100 * out.order_misfit:.0f} % of its own "
                      f"shaft orders ({_orders_text(out.model_orders)}) stays in the residual -- {what}")
    elif out.systematic_share > SHARE_MAX and systematic_p < SYSTEMATIC_ALPHA:
        out.verdict = "inadequate"
        out.reason = (f"the model cannot describe this measurement: its systematic residual is "
                      f"{100 * out.systematic_share:.0f} % of the torque -- {what}")
    elif systematic_p < SYSTEMATIC_ALPHA:
        out.verdict = "systematic"
    return out


def _residual_orders(r, dt, speed, peaks=4) -> list:
    return [{"order": p["order"], "amplitude": p["amplitude"]}
            for p in order_spectrum(r, dt, speed, peaks=peaks)["peaks"]]
