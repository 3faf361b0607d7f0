"""Model 1 with gas (spec §2 and §8): the vanes free in their slots, integrated with the gas cells
by CVODES (the pneumatic integrator, pumpsim.pneumatics.run) on the compiled right-hand side
and its exact Jacobian; lift-off reported per vane.

A vane is on the housing while its penetration is > 0 (the penalty force pushes), lifted
otherwise (report Table 1; on the slot bottom when s < 0 as well). Lift-off intervals are read
from the output grid: a sign change of the penetration between two samples is placed by linear
interpolation (to a fraction of the sample interval, not located by root finding, which cost ~0.3 s
per crossing); a bounce shorter than the output interval is missed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..contact import TOUCHING
from ..errors import ConfigError
from ..result import contact_warnings
from ..tolerances import ATOL, CONTACT_GAS_ATOL, CONTACT_GAS_RTOL, RTOL
from ..model_spec.parameters import pneumatic_layout
from . import run
from ..kernels.pneumatic import kernels, parameter_vector, structure_of
from .simulate import CELL_COLUMNS, GasSolution, cell_outputs, gas_run_times

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
    # the plenum energies and the reed stay last (codegen.pneumatic_contact_model.state_names)
    return np.concatenate([xg[:-4], s, sd, xg[-4:]])


def state_scale(x0, p, cfg, kern):
    sc = run.state_scale(x0, p, kern.structure)
    v = dict(zip([q.name for q in pneumatic_layout(kern.structure)], p))
    i_s, i_sd = vane_slices(cfg.vanes)
    size = VANE_POSITION_SCALE * v["vane.length"]
    sc[i_s] = size
    sc[i_sd] = size * max(abs(cfg.speed or 0.0), 100.0)
    return sc


def integrate(cfg, duration, rate, until=None, rtol=CONTACT_GAS_RTOL, atol=CONTACT_GAS_ATOL,
              initial="housing", progress=None, x0=None, p=None, max_steps=2_000_000):
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
            f = min(max(d[k] / (d[k] - d[k + 1]), 0.0), 1.0) if d[k] != d[k + 1] else 0.0
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


# -- simulate --model contact on a config with the gas tables ------------------------------------
VANE_COLUMNS = ("s", "sdot", "normal", "slot1", "slot2", "penetration")


class GasContactSolution(GasSolution):
    """Spec §7 columns of Model 1 (penetration_i included) and the spec §8 ones: booster
    pressure, current, per cell pressure_i, volume_i, temperature_i; lift-off per vane."""

    lift_off: list = []  # LiftOff intervals; budgets also hold the kinetic energy change

    def work_line(self) -> str:
        q = self.budgets
        return (f"work: shaft {q['shaft_work']:.4g} J = gas {q['gas_work']:.4g} J + friction "
                f"{q['friction_work']:.4g} J + contacts {q['contact_work']:.3g} J + kinetic "
                f"{q['kinetic']:.3g} J (gas forces on the vanes: {-q['load_work']:.4g} J)")

    def summary_extra(self) -> list:
        return lift_off_text(self.lift_off, self.n_vanes, self.time[-1])


def simulate(cfg, duration=None, rate=10000.0, method="cvodes", rtol=RTOL, atol=ATOL, initial=None,
             progress=None, max_steps=2_000_000):
    """Model 1 with the gas (spec §2, §8) at constant speed (operation.mode speed) or driven by the
    motor (mode motor), from the booster's start pressure; duration default: two revolutions (speed
    drive) or 0.1 s (motor). atol as for the mechanical models: of vane positions [m]; every other
    state gets the same share of its nominal size (state_scale)."""
    t = gas_run_times(cfg, duration, rate, method)
    atol_rel = atol / (VANE_POSITION_SCALE * cfg.values["vane.length"])
    r = integrate(cfg, t[-1], rate, rtol=rtol, atol=min(atol_rel, 0.1), initial=initial or "housing",
                  progress=progress, max_steps=max_steps)
    return _solution(cfg, r)


def _solution(cfg, r):
    N = cfg.vanes
    o = {k: (v.T if np.ndim(v) == 2 else (v[None, :] if k in VANE_COLUMNS + CELL_COLUMNS and N == 1
                                           else v)) for k, v in r.outputs.items()}
    i_s, i_sd = vane_slices(N)
    vanes = {"s": r.states[:, i_s].T, "sdot": r.states[:, i_sd].T}
    vanes.update({k: o[k] for k in ("normal", "slot1", "slot2", "penetration")})
    o.update(cell_outputs(r.outputs, r.states, N))
    events = []
    for iv in r.lift_off:
        d = iv.as_dict()
        events.append({"time": iv.start, "kind": "lift_off", "vane": iv.vane,
                       "message": f"vane {iv.vane} leaves the housing at {d['angle_start_deg']:.2f} deg"})
        if iv.end is not None:
            events.append({"time": iv.end, "kind": "housing_contact", "vane": iv.vane,
                           "message": f"vane {iv.vane} back on the housing at {d['angle_end_deg']:.2f} deg"})
    events.sort(key=lambda e: e["time"])
    q = dict(zip(QUAD_NAMES, r.quad[-1]))
    ke = o["kinetic_energy"]
    w = r.states[:, 1]
    q["kinetic"] = float(ke[-1] - ke[0] + 0.5 * cfg.values["rotor.inertia"] * (w[-1] ** 2 - w[0] ** 2))
    stats = dict(r.stats)
    warnings = []
    contact_warnings(o, r.time, warnings)
    res = GasContactSolution("contact", cfg.mode, r.time, r.states[:, 0], w, o["torque"], vanes,
              dict(zip([qq.name for qq in pneumatic_layout(structure(cfg))], r.p)), stats, events,
              warnings, extra=o, config_name=cfg.name)
    res.lift_off = r.lift_off
    res.budgets = {k: float(v) for k, v in q.items()}
    return res
