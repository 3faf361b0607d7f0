"""Model 1 with gas (spec §2 and §8): the vanes free in their slots, integrated with the gas cells
by CVODES (the pneumatic integrator, pumpsim.pneumatics.run) on the compiled right-hand side
and its exact Jacobian; lift-off reported per vane.

A vane is on the housing while its penetration is > 0 (the penalty force pushes), lifted
otherwise (report Table 1; on the slot bottom when s < 0 as well). Lift-off intervals are read
from the output grid: a sign change of the penetration between two samples is placed by linear
interpolation (to a fraction of the sample interval, not located by root finding).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..contact import TOUCHING
from ..errors import ConfigError
from ..model_spec.parameters import pneumatic_layout
from . import run
from .kernel import kernels, parameter_vector, structure_of

QUAD_NAMES = run.QUAD_NAMES + ("contact_work", "load_work")
INITIAL_STATES = ("housing", "rotor", "bottom")
# state scale of s_i [m] and of sdot_i per rad/s of rotor speed: the absolute tolerance is
# atol x scale, and a penalty contact's penetration is ~N/k ~ 1e-7..1e-5 m
VANE_POSITION_SCALE = 1e-3  # x vane.length


def model_parts(cfg, **overrides):
    """(kernels, parameter vector) of the gas-coupled Model 1 for cfg."""
    if cfg.pneumatic is None:
        raise ConfigError(f"{cfg.path or cfg.name}: the contact model with gas needs the gas tables "
                          "[ports] and [booster] (spec §8)")
    if not cfg.contact_given:
        raise ConfigError("the contact model needs [contact.housing] with a stiffness in the config")
    return kernels(cfg, "contact"), parameter_vector(cfg, "contact", **overrides)


def vane_slices(N):
    """Indices of s_i and sdot_i in the state (codegen.pneumatic_contact_model.state_names)."""
    return slice(6 + 2 * N, 6 + 3 * N), slice(6 + 3 * N, 6 + 4 * N)


def initial_state(cfg, kern, p, initial="housing", theta0=None, omega0=None):
    """Gas at rest pressure (as the Model 2 pump-down) and the vanes at their Model 2 positions:
    with Model 2's sliding speed (housing), carried by the rotor (rotor) or on the slot bottom
    (bottom; the cells then start at the Model 2 cells' gas masses)."""
    if initial not in INITIAL_STATES:
        raise ConfigError(f"initial vane state must be one of {', '.join(INITIAL_STATES)}, got '{initial}'")
    N = cfg.vanes
    xg = run.initial_state(cfg, kern, p, theta0, omega0)
    s, sd, _ = (np.asarray(v).ravel() for v in kern["constrained_state"](xg[0], xg[1], p))
    if initial != "housing":
        sd = np.zeros(N)
    if initial == "bottom":
        s = np.zeros(N)
    return np.concatenate([xg[:-2], s, sd, xg[-2:]])


def state_scale(x0, p, cfg, kern):
    sc = run.state_scale(x0, p, kern.structure)
    v = dict(zip([q.name for q in pneumatic_layout(kern.structure)], p))
    i_s, i_sd = vane_slices(cfg.vanes)
    size = VANE_POSITION_SCALE * v["vane.length"]
    sc[i_s] = size
    sc[i_sd] = size * max(abs(cfg.speed or 0.0), 100.0)
    return sc


def integrate(cfg, duration, rate, until=None, rtol=1e-7, atol=1e-6, initial="housing",
              progress=None, x0=None, p=None, max_steps=2_000_000):
    """run.integrate on the Model 1 variant; the PumpdownRun carries lift-off intervals."""
    kern, p0 = model_parts(cfg)
    p = p0 if p is None else np.asarray(p, float)
    x0 = initial_state(cfg, kern, p, initial) if x0 is None else np.asarray(x0, float)
    r = run.integrate(cfg, duration, rate, p=p, x0=x0, until=until, rtol=rtol, atol=atol,
                      progress=progress, max_steps=max_steps, kern=kern,
                      scale=state_scale(x0, p, cfg, kern))
    r.lift_off = lift_off_intervals(r.time, r.states[:, 0], r.outputs["penetration"])
    return r


@dataclass
class LiftOff:
    vane: int
    start: float  # s (None: lifted from the start)
    end: float | None  # s (None: still lifted at the end)
    angle_start: float  # rotor angle [rad], unwrapped
    angle_end: float | None
    max_gap: float  # m, largest -penetration sampled in the interval

    def as_dict(self) -> dict:
        deg = (lambda a: None if a is None else float(math.degrees(a) % 360.0))
        return {"vane": self.vane, "start": self.start, "end": self.end,
                "angle_start_deg": deg(self.angle_start), "angle_end_deg": deg(self.angle_end),
                "max_gap": self.max_gap}


def lift_off_intervals(t, theta, penetration) -> list[LiftOff]:
    """Per vane, the intervals without housing contact (penetration < 0)."""
    pen = np.asarray(penetration, float)
    pen = pen[:, None] if pen.ndim == 1 else pen
    out = []
    for i in range(pen.shape[1]):
        d = pen[:, i]
        off = d < -TOUCHING  # a vane started on the housing has |penetration| ~ 1e-18 m: touching
        if not off.any():
            continue
        edges = np.flatnonzero(np.diff(off.astype(int)))  # sample k: off changes between k, k+1

        def crossing(k):
            f = d[k] / (d[k] - d[k + 1]) if d[k] != d[k + 1] else 0.0
            return t[k] + f * (t[k + 1] - t[k]), theta[k] + f * (theta[k + 1] - theta[k])

        starts = ([(t[0], theta[0])] if off[0] else []) + [crossing(k) for k in edges if not off[k]]
        ends = [crossing(k) for k in edges if off[k]] + ([(None, None)] if off[-1] else [])
        for (t0, a0), (t1, a1) in zip(starts, ends):
            sel = (t >= t0) & (t <= (t1 if t1 is not None else t[-1]))
            gap = float(np.max(-d[sel])) if sel.any() else 0.0
            out.append(LiftOff(i, float(t0), None if t1 is None else float(t1), float(a0),
                               None if a1 is None else float(a1), max(gap, 0.0)))
    return out


def lift_off_text(intervals, N, t_end) -> list[str]:
    """One line per vane: how often and how long it left the housing, and where the first time."""
    lines = []
    for i in range(N):
        mine = [iv for iv in intervals if iv.vane == i]
        if not mine:
            lines.append(f"vane {i}: on the housing throughout")
            continue
        total = sum((iv.end if iv.end is not None else t_end) - iv.start for iv in mine)
        first = mine[0].as_dict()
        where = (f"{first['angle_start_deg']:.1f}..{first['angle_end_deg']:.1f} deg"
                 if first["angle_end_deg"] is not None else f"from {first['angle_start_deg']:.1f} deg")
        lines.append(f"vane {i}: lifts off {len(mine)} time(s), {total * 1e3:.3f} ms in all "
                     f"(largest gap {max(iv.max_gap for iv in mine) * 1e6:.2f} um); first at "
                     f"t = {mine[0].start:.6g} s, rotor angle {where}")
    return lines


def structure(cfg):
    return structure_of(cfg, "contact")
