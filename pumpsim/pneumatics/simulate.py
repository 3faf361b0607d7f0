"""`pumpsim simulate` (Model 2, the tips on the housing) on a config with the spec §8 gas tables:
the gas cells, ports, valves, leaks and booster integrated with the mechanics by the pneumatic
integrator (run.integrate), at constant speed (operation.mode speed) or driven by the motor (mode
motor). Without this, simulate would hand back the purely mechanical torque of a pump whose config
says it moves gas.

The spec §7 columns come from the gas-coupled kernel (torque with the gas torque, housing and slot
reactions with the pressure loads on the vanes), except sdot_i: the pneumatic kernel does not
export it, and on Model 2 it is geometry, ds_i/dtheta x omega, so the mechanical kernel of the
same config gives it exactly at the integrated (theta, omega).
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from ..result import Solution, contact_warnings
from ..tolerances import ATOL, RTOL
from ..model_spec.parameters import pneumatic_layout
from . import run
from ..kernels.pneumatic import kernels, parameter_vector

CELL_COLUMNS = ("pressure", "volume", "temperature")


def gas_columns(n_vanes) -> list:
    """Spec §8 columns written after the spec §7 ones: booster pressure, motor current and per
    cell pressure_i, volume_i, temperature_i."""
    return ["booster_pressure", "current"] + [f"{c}_{i}" for i in range(n_vanes) for c in CELL_COLUMNS]


def cell_outputs(outputs, states, N) -> dict:
    """The gas columns' arrays from a pneumatic run's outputs (cells as (N, n)) and states."""
    o = {"booster_pressure": outputs["booster_pressure"], "current": states[:, 2]}
    for c in CELL_COLUMNS:
        o[c] = np.asarray(outputs[c]).reshape(len(states), N).T
    return o


class GasSolution(Solution):
    """Spec §7 columns of Model 2 and the spec §8 ones (gas_columns); `budgets` holds the energies
    [J] over the run (run.QUAD_NAMES)."""

    budgets: dict = {}

    def column_names(self) -> list:
        return super().column_names() + gas_columns(self.n_vanes)

    def work_line(self) -> str:
        q = self.budgets
        return (f"work: shaft {q['shaft_work']:.4g} J = gas {q['gas_work']:.4g} J + friction "
                f"{q['friction_work']:.4g} J + valve damping {q['valve_damping_work']:.3g} J "
                "(+ kinetic energy change)")

    def summary_extra(self) -> list:
        """Lines after the work line (Model 1: the lift-off per vane)."""
        return []

    def summary(self, warnings: bool = True) -> str:
        lines = super().summary(warnings).split("\n")
        work = [self.work_line()] if self.budgets else []
        return "\n".join(lines[:4] + work + self.summary_extra() + lines[4:])


def check_drive(cfg) -> None:
    """The gas model is driven at constant speed or by the motor; a given torque is refused."""
    if cfg.mode == "torque":
        raise ConfigError(f"{cfg.path or cfg.name}: operation.mode = \"torque\": the gas model runs at "
                          "constant speed (operation.mode = \"speed\") or with the motor (\"motor\"), "
                          "not with a given torque")


def gas_run_times(cfg, duration, rate, method):
    """The output times of a gas-model simulate (both models), after checking its options: cvodes
    only, a speed or motor drive; duration default two revolutions (speed) or 0.1 s (motor)."""
    from ..motion import sample_times

    if method != "cvodes":
        raise ConfigError(f"method {method}: the gas model integrates with cvodes only")
    check_drive(cfg)
    if duration is None:
        duration = 2 * 2 * math.pi / cfg.speed if cfg.mode == "speed" and cfg.speed > 0 else 0.1
    return sample_times(duration, rate)


def simulate(cfg, duration=None, rate=10000.0, method="cvodes", rtol=RTOL, atol=ATOL, progress=None,
             max_steps=2_000_000) -> GasSolution:
    """Model 2 with the gas from the booster's start pressure (spec §8). duration default: two
    revolutions (speed drive) or 0.1 s (motor); atol of the rotor angle [rad] (every other state
    gets the same share of its nominal size, run.state_scale)."""
    t = gas_run_times(cfg, duration, rate, method)
    kern = kernels(cfg)
    r = run.integrate(cfg, t[-1], rate, p=parameter_vector(cfg), rtol=rtol, atol=atol, progress=progress,
                      max_steps=max_steps, kern=kern)
    return _solution(cfg, r, kern)


def _solution(cfg, r, kern) -> GasSolution:
    from ..config import as_array
    from ..kernels import load_kernels, sampled_inverse_dynamics

    N = cfg.vanes
    o, X = r.outputs, r.states
    theta, omega, omegadot = X[:, 0], X[:, 1], np.asarray(o["omegadot"]).ravel()
    per_vane = {k: np.asarray(o[k]).reshape(len(X), N).T for k in ("s", "normal", "slot1", "slot2", "n_consistent")}
    pv = cfg.parameters("constrained")
    mech = sampled_inverse_dynamics(load_kernels(pv.structure), as_array(pv), theta, omega, omegadot, ("sdot",))
    vanes = {"s": per_vane["s"], "sdot": np.asarray(mech["sdot"]).reshape(N, -1),
             "normal": per_vane["normal"], "slot1": per_vane["slot1"], "slot2": per_vane["slot2"]}
    extra = dict(o)
    extra.update(cell_outputs(o, X, N))
    warnings = []  # Model 2 assumes every tip on the housing: a negative reaction is reported
    contact_warnings(per_vane, r.time, warnings, lift_off=True)
    res = GasSolution("constrained", cfg.mode, r.time, theta, omega, np.asarray(o["torque"]).ravel(),
                      vanes, dict(zip([q.name for q in pneumatic_layout(kern.structure)], r.p)),
                      dict(r.stats), list(r.events), warnings, extra=extra, config_name=cfg.name)
    res.budgets = {k: float(v) for k, v in zip(run.QUAD_NAMES, r.quad[-1])}
    return res
