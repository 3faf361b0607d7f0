"""Booster pump-down (spec §8): the full model through every revolution, and a fast path from
cycle-averaged maps.

Full path: CVODES on the compiled right-hand side (all cells, valves, motor) from the booster's
start pressure until the target (or a duration).

Fast path: at a grid of booster pressures the full model runs with the booster held at that
pressure (a booster volume of MAP_BOOSTER_VOLUME m^3 and no booster leak) until the motor and the
cells are in periodic steady state; over whole revolutions it averages the mass flow drawn from the
booster, the current, the shaft torque and the speed. The booster then follows
dV_b/(R T) dp_b/dt = leak(p_b) - mdot(p_b), with mdot and the current interpolated in log p_b
(monotone cubic). Assumptions: the booster changes slowly against a revolution and the motor's
run-up is taken from the first map run (from rest at the start pressure, MAP_SETTLE s), so the
inrush peak and the run-up's charge are in the fast path too.
"""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, SolverError
from ..tolerances import (CONTACT_PUMPDOWN_ATOL, CONTACT_PUMPDOWN_RTOL, LIFT_OFF_ROUNDING_REL, PUMPDOWN_ATOL,
                          PUMPDOWN_RTOL)
from . import run
from ..kernels.pneumatic import kernels, parameter_index, parameter_vector, structure_of

DEFAULT_DURATION = 120.0  # s: the longest pump-down when no --duration is given
MAP_BOOSTER_VOLUME = 1.0e3  # m^3: the booster pressure does not move during a map run
MAP_SETTLE = 0.15  # s of motor run-up before the first map point (later points start settled)
MAP_RESETTLE = 0.04  # s between map points (cells and manifold refill; the speed moves little)
MAP_REVOLUTIONS = 4  # whole revolutions averaged per map point
MAP_RATE = 20000.0  # Hz: output grid on which whole revolutions are interpolated


@dataclass
class PumpdownResult:
    name: str
    time: np.ndarray
    columns: dict  # spec §8 CSV columns
    summary: dict  # spec §8 JSON fields
    run: object = None
    warnings: list = field(default_factory=list)

    def to_csv(self, path) -> None:
        from ..io import atomic_path

        names = list(self.columns)
        data = np.column_stack([self.columns[n] for n in names])
        with atomic_path(path) as tmp:
            np.savetxt(tmp, data, delimiter=",", header=",".join(names), comments="", fmt="%.10g")

    def text(self) -> str:
        s = self.summary
        t = s["time_to_target"]
        lines = [f"pump-down of {self.name}: booster {s['start_pressure'] / 1e3:.1f} kPa -> "
                 f"{s['final_pressure'] / 1e3:.2f} kPa"
                 + (f", target {s['target_pressure'] / 1e3:.1f} kPa reached at {t:.3f} s" if t is not None
                    else " (target not reached)"),
                 (f"  current: peak {s['peak_current']:.1f} A, mean {s['mean_current']:.2f} A; "
                  f"energy {s['energy']:.1f} J; mean speed {s['mean_speed_rpm']:.0f} rpm" if s["energy"] is not None
                  else f"  no motor (the shaft turns at the set speed): mean speed {s['mean_speed_rpm']:.0f} rpm"),
                 f"  shaft work {s['shaft_work']:.1f} J = "
                 + " + ".join(f"{name} {v:.4g} J" for name, v in work_split(s))]
        lines += [f"  {line}" for line in s.get("lift_off_text", [])]
        st = s["solver"]
        lines.append(f"  CVODES: {st['nsteps']} steps, {st['nfevals']} rhs, {st['njevals']} Jacobians, "
                     f"{st['netfails']} error-test failures, {st.get('events', 0)} valve events, "
                     f"{st['wall_time']:.2f} s wall")
        return "\n".join(lines)


LOW_SPEED_RPM = 500.0  # below it a lift-off is the run-up's, before the vanes are pressed out

# the summary's figures of the motor and its supply: null (JSON) without a motor
MOTOR_FIGURES = ("energy", "peak_current", "mean_current", "copper_loss", "motor_friction_work")


def work_split(s) -> list[tuple[str, float]]:
    """The shaft work's parts [J] from a pump-down summary, summing to shaft_work: gas, friction,
    valve damping (reed) and contact work (Model 1) where present, and the kinetic energy left in
    rotor and vanes (the rest)."""
    parts = [("gas", s["gas_work"]), ("friction", s["friction_work"])]
    parts += [(name, s[k]) for k, name in (("valve_damping_work", "valve damping"), ("contact_work", "contacts"))
              if s.get(k)]
    return parts + [("kinetic", s["shaft_work"] - sum(v for _, v in parts))]


def _target(cfg, until):
    target = until if until is not None else cfg.pneumatic.booster_target
    if target is not None and not 0 < target < cfg.pneumatic.booster_start:
        raise ConfigError(f"until must be in (0, booster.pressure ({cfg.pneumatic.booster_start:g} Pa)), "
                          f"got {target:g}")
    return target


def default_tolerances(model="constrained") -> tuple[float, float]:
    """(rtol, atol) of a pump-down when none are given (pumpsim.tolerances: why)."""
    if model == "contact":
        return CONTACT_PUMPDOWN_RTOL, CONTACT_PUMPDOWN_ATOL
    return PUMPDOWN_RTOL, PUMPDOWN_ATOL


def pumpdown(cfg, until=None, duration=None, rate=2000.0, rtol=None, atol=None, progress=None,
             model="constrained") -> PumpdownResult:
    """Full-model pump-down from booster.pressure to `until` (default booster.target), at most
    `duration` seconds (default 120 s); model "contact": Model 1 (vanes free in their slots,
    lift-off reported) instead of Model 2. rtol/atol: default_tolerances(model) when None."""
    if model not in ("constrained", "contact"):
        raise ConfigError(f"model must be 'constrained' or 'contact', got '{model}'")
    rtol0, atol0 = default_tolerances(model)
    rtol, atol = (rtol0 if rtol is None else rtol), (atol0 if atol is None else atol)
    if cfg.pneumatic is None:
        raise ConfigError(f"{cfg.path or cfg.name}: pumpdown needs the gas tables [ports] and [booster] "
                          "(spec §8)")
    from .simulate import check_drive

    check_drive(cfg)
    target = _target(cfg, until)
    if target is None and duration is None:
        raise ConfigError("give until (a pressure in Pa), duration (s) or booster.target in the config")
    from ..motion import sample_times

    sample_times(DEFAULT_DURATION if duration is None else duration, rate)  # finite, > 0, sample limit
    for name, val in (("rtol", rtol), ("atol", atol)):
        if not 0 < val < 1:
            raise ConfigError(f"--{name} must be in (0, 1), got {val:g}")
    duration = DEFAULT_DURATION if duration is None else duration
    if model == "contact":
        from . import contact

        r = contact.integrate(cfg, duration, rate, until=target, rtol=rtol, atol=atol, progress=progress)
    else:
        r = run.integrate(cfg, duration, rate, until=target, rtol=rtol, atol=atol, progress=progress)
    r.stats.update(rtol=rtol, atol=atol)
    return _result(cfg, r, target)


def _result(cfg, r, target) -> PumpdownResult:
    o, X, t = r.outputs, r.states, r.time
    N = cfg.vanes
    cols = {"time": t, "angle": X[:, 0], "speed": X[:, 1], "torque": o["torque"],
            "booster_pressure": o["booster_pressure"], "current": X[:, 2]}
    for i in range(N):
        cols[f"pressure_{i}"] = o["pressure"][:, i]
        cols[f"volume_{i}"] = o["volume"][:, i]
        cols[f"temperature_{i}"] = o["temperature"][:, i]
    q = dict(zip(run.QUAD_NAMES, r.quad[-1]))
    t_end = float(t[-1])
    volt = cfg.pneumatic.values["motor.voltage"] if cfg.pneumatic.motor else None
    mean_i = q["electrical_energy"] / (volt * t_end) if volt else float(np.mean(X[:, 2]))
    summary = {
        "time_to_target": r.time_to_target, "final_pressure": float(o["booster_pressure"][-1]),
        "energy": q["electrical_energy"], "peak_current": float(r.peak_current),
        "mean_current": mean_i, "start_pressure": float(o["booster_pressure"][0]),
        "target_pressure": target, "duration": t_end,
        "mean_speed_rpm": float((X[-1, 0] - X[0, 0]) / t_end * 30 / math.pi),
        "shaft_work": q["shaft_work"], "gas_work": q["gas_work"], "friction_work": q["friction_work"],
        "copper_loss": q["copper_loss"], "motor_friction_work": q["motor_friction_work"],
        "valve_damping_work": q["valve_damping_work"],
        "solver": {k: (float(v) if isinstance(v, float) else v) for k, v in r.stats.items()},
    }
    if not cfg.pneumatic.motor:  # the shaft is driven at its speed: no supply, no current
        summary.update(dict.fromkeys(MOTOR_FIGURES))
    warnings = []
    if getattr(r, "lift_off", None) is not None:  # Model 1: the vanes' columns and their lift-off
        _contact_result(cfg, r, cols, summary)
    normal = o["normal"]
    neg = normal < -LIFT_OFF_ROUNDING_REL * np.max(np.abs(normal))
    if neg.any():
        k = int(np.argmax(neg.any(axis=1)))
        rpm = float(np.max(np.abs(X[neg.any(axis=1), 1]))) * 30 / math.pi
        warnings.append(f"a vane would lift off (housing reaction < 0) at t = {t[k]:.4g} s "
                        f"({int(neg.sum())} vane-samples, the rotor at up to {rpm:.0f} rpm then); Model 2 "
                        "assumes contact" + (" (at start-up from rest the vanes are not yet pressed out)"
                                             if rpm < LOW_SPEED_RPM else ""))
    if np.max(np.abs(o["motor_residual"])) > 1e-6:
        warnings.append(f"motor torque balance not closed to 1e-6 N m "
                        f"(max {np.max(np.abs(o['motor_residual'])):.2g})")
    return PumpdownResult(cfg.name, t, cols, summary, r, warnings)


def _contact_result(cfg, r, cols, summary) -> None:
    """Model 1: per vane s_i, sdot_i, normal_i, penetration_i (spec §7's contact columns) and the
    lift-off intervals; the contact work in the budgets."""
    from .contact import QUAD_NAMES, lift_off_text, vane_slices

    N = cfg.vanes
    i_s, i_sd = vane_slices(N)
    pen = r.outputs["penetration"].reshape(len(r.time), N)
    normal = r.outputs["normal"].reshape(len(r.time), N)
    for i in range(N):
        cols[f"s_{i}"] = r.states[:, i_s][:, i]
        cols[f"sdot_{i}"] = r.states[:, i_sd][:, i]
        cols[f"normal_{i}"] = normal[:, i]
        cols[f"penetration_{i}"] = pen[:, i]
    q = dict(zip(QUAD_NAMES, r.quad[-1]))
    summary.update(model="contact", contact_work=q["contact_work"], load_work=q["load_work"],
                   lift_off=[iv.as_dict() for iv in r.lift_off])
    summary["lift_off_text"] = lift_off_text(r.lift_off, N, float(r.time[-1]))


# -- fast path -------------------------------------------------------------------------------------
@dataclass
class PumpMaps:
    """Cycle averages vs booster pressure (ascending pressure)."""

    pressure: np.ndarray  # Pa
    mass_flow: np.ndarray  # kg/s drawn from the booster
    pumping_speed: np.ndarray  # m^3/s at booster conditions (mass_flow R T / p)
    current: np.ndarray  # A
    torque: np.ndarray  # N m (mean shaft torque)
    speed: np.ndarray  # rad/s
    gas_torque: np.ndarray  # N m (mean)
    friction_torque: np.ndarray  # N m (mean)
    wall_time: float = 0.0
    steps: int = 0
    revolutions: list = field(default_factory=list)  # per map point: one revolution's traces
    runup: dict = field(default_factory=dict)  # motor start from rest at the start pressure
    end_states: list = field(default_factory=list)  # per map point: the state its averaging ended on
    p: np.ndarray | None = None  # the runtime parameters the maps ran with (booster held)


def _crossing(theta, k_rev):
    """Fractional sample index where theta first reaches theta[0] + 2 pi k_rev."""
    goal = theta[0] + 2 * math.pi * k_rev
    j = int(np.searchsorted(theta, goal))
    return j - 1 + (goal - theta[j - 1]) / (theta[j] - theta[j - 1])


def _at(arr, s):
    j = int(math.floor(s))
    f = s - j
    return arr[j] * (1 - f) + arr[min(j + 1, len(arr) - 1)] * f


def pump_maps(cfg, pressures, rtol=PUMPDOWN_RTOL, atol=PUMPDOWN_ATOL, p=None) -> PumpMaps:
    """Cycle-averaged maps at the booster pressures given (any order); p: a runtime parameter
    vector to map instead of the config's (its booster volume and leak are replaced)."""
    k = kernels(cfg)
    st = structure_of(cfg)
    if p is None:
        p = parameter_vector(cfg, booster__volume=MAP_BOOSTER_VOLUME, booster__leak=0.0)
    else:
        p = np.array(p, dtype=float)
        p[parameter_index(st, "booster.volume")], p[parameter_index(st, "booster.leak")] = MAP_BOOSTER_VOLUME, 0.0
    v = cfg.pneumatic.values
    RT = v["gas.gas_constant"] * v["gas.temperature"]
    i_bm = 3 + 2 * st.vanes + 2
    rows, revs, runup, wall0, steps = [], [], {}, _time.perf_counter(), 0
    x = None
    for pb in sorted(pressures, reverse=True):
        if x is None:
            x = run.initial_state(cfg, k, p)
            settle = MAP_SETTLE
        else:
            settle = MAP_RESETTLE
        x = run.at_booster_pressure(x, st, p, pb)
        r0 = run.integrate(cfg, settle, 1000.0, p=p, x0=x, rtol=rtol, atol=atol)
        if not runup:  # the first point starts from rest at the start pressure: the run-up
            volt = v["motor.voltage"] if cfg.pneumatic.motor else 0.0
            runup = {"time": settle, "mass": float(r0.states[0, i_bm] - r0.states[-1, i_bm]),
                     "charge": float(r0.quad[-1, 0] / volt) if volt else 0.0,
                     "peak_current": float(r0.peak_current)}
        x = r0.states[-1]
        T_rev = 2 * math.pi / max(x[1], 1.0)
        r = run.integrate(cfg, (MAP_REVOLUTIONS + 0.5) * T_rev, MAP_RATE, p=p, x0=x, rtol=rtol, atol=atol)
        steps += r0.stats["nsteps"] + r.stats["nsteps"]
        th = r.states[:, 0]
        s1 = _crossing(th, MAP_REVOLUTIONS)
        dt = _at(r.time, s1) - r.time[0]
        q = {n: _at(r.quad[:, j], s1) for j, n in enumerate(run.QUAD_NAMES)}
        mdot = (r.states[0, i_bm] - _at(r.states[:, i_bm], s1)) / dt
        w = 2 * math.pi * MAP_REVOLUTIONS / dt
        volt = v["motor.voltage"] if cfg.pneumatic.motor else 0.0
        current = q["electrical_energy"] / (volt * dt) if volt else float(np.mean(r.states[:, 2]))
        rows.append((pb, mdot, mdot * RT / pb, current, q["shaft_work"] / (w * dt), w,
                     q["gas_work"] / (w * dt), q["friction_work"] / (w * dt), r.states[-1]))
        one = slice(0, int(math.ceil(_crossing(th, 1))) + 1)  # the first revolution, for figures
        o = r.outputs
        revs.append({"booster_pressure": pb, "angle": th[one] - th[0], "volume": o["volume"][one, 0],
                     "pressure": o["pressure"][one, 0], "torque": o["torque"][one],
                     "gas_torque": o["gas_torque"][one],
                     "friction_torque": o["friction_power"][one] / r.states[one, 1]})
        x = r.states[-1]
    rows.sort(key=lambda row: row[0])
    a = np.array([row[:-1] for row in rows]).T
    revs.sort(key=lambda d: d["booster_pressure"])
    return PumpMaps(*a, wall_time=_time.perf_counter() - wall0, steps=steps, revolutions=revs,
                    runup=runup, end_states=[row[-1] for row in rows], p=p)


STEADY_OVERSAMPLING = 16  # integrator output samples per requested angle (linear interpolation)


def steady_revolution(cfg, maps: PumpMaps, k: int, angles, names=None,
                      rtol=PUMPDOWN_RTOL, atol=PUMPDOWN_ATOL) -> dict:
    """pump_outputs over one revolution of map point k's periodic steady state, at the rotor
    angles given (one revolution, any start): the run continues from the state the map's averaging
    ended on for one more revolution, and each output is interpolated in angle from
    STEADY_OVERSAMPLING samples per requested one. Per-sample outputs (n,), per cell/vane (n, N)."""
    angles = np.asarray(angles, dtype=float)
    x = maps.end_states[k]
    T_rev = 2 * math.pi / max(x[1], 1.0)
    rate = STEADY_OVERSAMPLING * angles.size / T_rev
    r = run.integrate(cfg, 1.05 * T_rev, rate, p=maps.p, x0=x, rtol=rtol, atol=atol)
    th = r.states[:, 0]
    if np.any(np.diff(th) <= 0):
        raise SolverError("the pump does not turn steadily forward at this operating point, so its "
                          "revolution in periodic steady state is not defined")
    at = th[0] + np.mod(angles - th[0], 2 * math.pi)  # each angle once, within the run's revolution
    out = {}
    for nm, a in r.outputs.items():
        if names is None or nm in names:
            a = np.asarray(a, dtype=float)
            out[nm] = (np.interp(at, th, a) if a.ndim == 1
                       else np.stack([np.interp(at, th, col) for col in a.T], axis=1))
    return out


def fast_pumpdown(cfg, maps: PumpMaps, until=None, duration=120.0) -> dict:
    """Booster pressure from the maps: dp_b/dt = R T / V_b (leak(p_b) - mdot(p_b))."""
    from scipy.integrate import solve_ivp
    from scipy.interpolate import PchipInterpolator

    target = _target(cfg, until)
    v = cfg.pneumatic.values
    RT = v["gas.gas_constant"] * v["gas.temperature"]
    V_b = v["booster.volume"]
    lp = np.log(maps.pressure)
    mdot = PchipInterpolator(lp, maps.mass_flow)
    cur = PchipInterpolator(lp, maps.current)
    leak_area = _leak_area(v)
    # the motor's run-up from rest, from the full model (the first map run): its time, charge
    # and the gas it drew; the maps take over from there
    ru = maps.runup or {"time": 0.0, "mass": 0.0, "charge": 0.0, "peak_current": 0.0}
    p0 = cfg.pneumatic.booster_start - ru["mass"] * RT / V_b
    if target is not None and not maps.pressure[0] <= target:
        raise ConfigError(f"the maps start at {maps.pressure[0]:g} Pa, above the target {target:g} Pa")
    t0 = _time.perf_counter()

    def rhs(t, y):
        pb = y[0]
        x = math.log(min(max(pb, maps.pressure[0]), maps.pressure[-1]))
        return [RT / V_b * (_orifice(v["gas.atmosphere"], pb, leak_area, v) - float(mdot(x))),
                float(cur(x))]

    events = None
    if target is not None:
        def hit(t, y):
            return y[0] - target
        hit.terminal, hit.direction = True, -1
        events = [hit]
    sol = solve_ivp(rhs, (ru["time"], duration), [p0, ru["charge"]], method="RK45", rtol=1e-9,
                    atol=[1e-6, 1e-9], events=events, dense_output=False)
    t_end = float(sol.t[-1])
    volt = v["motor.voltage"] if cfg.pneumatic.motor else 0.0
    charge = float(sol.y[1, -1])
    out = {"time_to_target": t_end if (target is not None and sol.status == 1) else None,
           "final_pressure": float(sol.y[0, -1]), "mean_current": charge / t_end,
           "energy": volt * charge, "peak_current": max(float(np.max(maps.current)), ru["peak_current"]),
           "wall_time": _time.perf_counter() - t0, "rhs_evaluations": int(sol.nfev),
           "time": [float(x) for x in sol.t], "booster_pressure": [float(x) for x in sol.y[0]]}
    if not cfg.pneumatic.motor:
        out.update({k: None for k in MOTOR_FIGURES if k in out})
    return out


def leak_flow(v, p_booster) -> float:
    """The booster leak's mass flow [kg/s] at booster pressure p_booster (gas-table values v)."""
    return _orifice(v["gas.atmosphere"], p_booster, _leak_area(v), v)


def _leak_area(v):
    g, R, T = v["gas.gamma"], v["gas.gas_constant"], v["gas.temperature"]
    flux = v["gas.atmosphere"] / math.sqrt(R * T) * math.sqrt(g) * (2 / (g + 1)) ** ((g + 1) / (2 * (g - 1)))
    return v["booster.leak"] / flux


def orifice_factor(r, v):
    """The kernel's orifice law (codegen/gas.py) without its area and upstream state: the flow
    function of the pressure ratio r = p_down / p_up <= 1 (a number or an array), linearised above
    r = 0.995 so the flow goes to zero smoothly."""
    g = v["gas.gamma"]
    r_crit = (2 / (g + 1)) ** (g / (g - 1))

    def psi(x):
        x = np.maximum(x, r_crit)
        return np.sqrt(np.maximum(2 * g / (g - 1) * (x ** (2 / g) - x ** ((g + 1) / g)), 0.0))

    lin = 0.995
    return np.where(r > lin, psi(lin) * (1 - r) / (1 - lin), psi(r))


def _orifice(p_up, p_down, area, v):
    """The booster leak's orifice flow, p_up >= p_down."""
    if area == 0.0:
        return 0.0
    R, T = v["gas.gas_constant"], v["gas.temperature"]
    return area * p_up / math.sqrt(R * T) * float(orifice_factor(p_down / p_up, v))
