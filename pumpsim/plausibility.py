"""Unit-mistake checks before any work: a config in mm/g instead of SI, a speed column in rpm, a
torque column in N mm, a time column in ms.

Each check compares a magnitude with what a rotary vane pump can physically be, or with what the
model gives for the configuration; when the mismatch matches a unit factor (1000, 60/2 pi, ...)
the message names the likely unit and the option or key that fixes it. `force=True` (`--force`)
turns a refusal into a warning. The limits are generous on purpose: they catch factors of 10 to
10^9, not engineering judgement.
"""
from __future__ import annotations

import math

import numpy as np

from .errors import ConfigError, DataError
from .model_spec.housings import config_key
from .pneumatics.config import MIN_BOOSTER_PRESSURE

# A vane tip faster than this is no vane pump (automotive pumps run at 10-30 m/s, large
# industrial ones below 40 m/s): an operation.speed given in rpm gives ~10x.
MAX_TIP_SPEED = 100.0  # m/s
MAX_LENGTH = 1.0  # m: no rotor, housing or vane dimension of a vane pump reaches a metre
MAX_DENSITY = 20000.0  # kg/m^3: above tungsten (19,300)
MAX_AXIAL_LENGTH = 1.0  # m: bounds a vane's width / the rotor's length for the mass checks
MIN_SAMPLES_PER_REV = 8  # fewer cannot resolve even the first shaft orders
TORQUE_MARGIN = 10.0  # a torque level 10x outside the model's COF range [MIN_COF, 2] is implausible
# No vane slides on a housing with a COF below 0.01 (lubricated contacts are at 0.02-0.1); with the
# margin a torque level below the model's at COF 0.001 is a unit mistake (N*m read as N*mm)
MIN_COF = 0.01
# Gas tables (spec §8): a vessel of a cubic metre is 250 brake boosters (2-8 L): 4 for 4 L gives
# 4 m^3 and a pump-down that "never reaches" its target; an atmosphere below 10 kPa (the air at
# 16 km) is a pressure in kPa or bar, not Pa
MAX_VESSEL_VOLUME = 1.0  # m^3
MIN_ATMOSPHERE = 1.0e4  # Pa
# A gas or wall temperature below 150 K is a temperature in degrees Celsius.
MIN_TEMPERATURE = 150.0  # K

TORQUE_FACTORS = {"N*mm (set the torque unit N*mm, or a 'torque [N*mm]' header)": 1e3,
                  "N*cm (set the torque unit N*cm, or a 'torque [N*cm]' header)": 1e2,
                  "N*m, but the torque unit option or the header says N*mm": 1e-3}
SPEED_FACTORS = {"rpm (set the speed unit rpm, or a 'speed [rpm]' header)": 60 / (2 * math.pi),
                 "rev/s (set the speed unit rev/s)": 1 / (2 * math.pi),
                 "deg/s (use a 'speed [deg/s]' header)": 180 / math.pi,
                 "rad/s, but the speed unit option or the header says rpm": 2 * math.pi / 60}
TIME_FACTORS = {"ms (set the time unit ms, or a 'time [ms]' header)": 1e3,
                "us (set the time unit us, or a 'time [us]' header)": 1e6}
# a torque unit is named alone when its factor brings the level nearer the model's at the configured
# COF by half a decade than the next unit's does (N*cm and N*mm, a decade apart, are told apart
# unless the configured COF is ~3x off the data's); otherwise both are named
AMBIGUOUS_DECADES = 0.5
ANGLE_FACTORS = {"degrees": 180 / math.pi}
FACTOR_TOL = 0.15  # relative: a ratio within 15 % of a unit factor is taken as that unit


def _refuse(problem, force, error):
    if force:
        return [f"{problem} (forced: proceeding)"]
    raise error(f"{problem}; the force option proceeds anyway")


def config_problems(cfg) -> list[str]:
    """Magnitudes a pump config in SI units cannot have (lengths in mm, masses in g, speeds in rpm)."""
    v = cfg.values
    out = []
    for key in ("rotor.radius", "housing.a", "housing.b", "vane.length", "vane.thickness"):
        if v[key] > MAX_LENGTH:
            shown, factor = config_key(cfg.shape, key)  # as the file gives it (housing.radius)
            given = v[key] / factor
            out.append(f"{shown} = {given:g} m is larger than any vane pump: config values are SI "
                       f"(metres); {given:g} mm is {given / 1000:g}")
            return out  # one length in mm: the rest follow, and mass checks would mislead
    L, h = v["vane.length"], v["vane.thickness"]
    heaviest = MAX_DENSITY * L * h * MAX_AXIAL_LENGTH
    if v["vane.mass"] > heaviest:
        out.append(f"vane.mass = {v['vane.mass']:g} kg is heavier than a tungsten vane of {L * 1e3:g} x "
                   f"{h * 1e3:g} mm and {MAX_AXIAL_LENGTH:g} m width ({heaviest:.3g} kg): config values are SI "
                   f"(kg); {v['vane.mass']:g} g is {v['vane.mass'] / 1000:g}")
    R = v["rotor.radius"]
    most = MAX_DENSITY * math.pi / 2 * R**4 * MAX_AXIAL_LENGTH
    if v["rotor.inertia"] > most:
        out.append(f"rotor.inertia = {v['rotor.inertia']:g} kg m^2 exceeds a solid tungsten rotor of radius "
                   f"{R * 1e3:g} mm and {MAX_AXIAL_LENGTH:g} m length ({most:.3g} kg m^2): config values are SI "
                   "(kg m^2; 1 g mm^2 = 1e-9 kg m^2)")
    bar = v["vane.mass"] * (L**2 + h**2) / 12
    if not 0.1 * bar <= v["vane.inertia"] <= 10 * bar:
        out.append(f"vane.inertia = {v['vane.inertia']:g} kg m^2 is {v['vane.inertia'] / bar:.3g} x that of a "
                   f"{L * 1e3:g} x {h * 1e3:g} mm bar of vane.mass ({bar:.3g}): config values are SI (kg m^2)")
    if cfg.speed:
        tip = cfg.speed * max(v["housing.a"], v["housing.b"])
        if tip > MAX_TIP_SPEED:
            out.append(f"operation.speed = {cfg.speed:g} rad/s gives a vane tip speed of {tip:.3g} m/s "
                       f"(limit {MAX_TIP_SPEED:g}): operation.speed is in rad/s (SI); for {cfg.speed:g} rpm "
                       f"write operation.speed_rpm = {cfg.speed:g} instead")
    return out + gas_problems(cfg)


def gas_problems(cfg) -> list[str]:
    """Magnitudes of the spec §8 tables that are unit mistakes: a booster volume in litres, an
    atmosphere (and so every pressure given beside it) in kPa or bar."""
    if getattr(cfg, "pneumatic", None) is None:
        return []
    v, out = cfg.pneumatic.values, []
    if v["booster.volume"] > MAX_VESSEL_VOLUME:
        out.append(f"booster.volume = {v['booster.volume']:g} m^3 is larger than any vessel a vane pump "
                   f"evacuates (limit {MAX_VESSEL_VOLUME:g} m^3): config values are SI (m^3); "
                   f"{v['booster.volume']:g} L is {v['booster.volume'] / 1000:g}")
    if v["gas.atmosphere"] < MIN_ATMOSPHERE:
        out.append(f"gas.atmosphere = {v['gas.atmosphere']:g} Pa is below {MIN_ATMOSPHERE:g} Pa: pressures "
                   f"are absolute in Pa (SI); {v['gas.atmosphere']:g} kPa is {v['gas.atmosphere'] * 1000:g}")
    for key, p in (("booster.pressure", cfg.pneumatic.booster_start),
                   ("booster.target", cfg.pneumatic.booster_target)):
        if p is not None and p < MIN_BOOSTER_PRESSURE:
            out.append(f"{key} = {p:g} Pa is below any vane pump's ultimate pressure (limit "
                       f"{MIN_BOOSTER_PRESSURE:g} Pa): pressures are absolute in Pa (SI); {p:g} kPa is {p * 1000:g}")
    for key in ("gas.temperature", "gas.wall_temperature"):
        if v[key] < MIN_TEMPERATURE:
            out.append(f"{key} = {v[key]:g} K is below {MIN_TEMPERATURE:g} K: temperatures are in kelvin (SI); "
                       f"{v[key]:g} degC is {v[key] + 273.15:g}")
    return out


def check_config(cfg, force=False) -> list[str]:
    """Refuse (ConfigError) a config whose magnitudes suggest non-SI units; warnings under force."""
    problems = config_problems(cfg)
    if not problems:
        return []
    return _refuse("; ".join(problems), force, ConfigError)


def _match(ratio, factors):
    for unit, f in factors.items():
        if ratio > 0 and abs(math.log(ratio / f)) < math.log1p(FACTOR_TOL):
            return unit
    return None


def check_measurement(cfg, ds, params=(), force=False) -> list[str]:
    """Compare a measurement with the configuration before fitting: the speed column with the
    configured speed and a pump's tip-speed limit, the sampling with the revolution, and the torque
    level with the model's at COFs 0 and 2 (the fit's bounds). Refuses (DataError, naming the file
    and the likely unit) unless force; returns warnings."""
    warnings = []
    name = ds.name
    radius = max(cfg.values["housing.a"], cfg.values["housing.b"])
    speed = None
    if ds.speed is not None:
        speed = float(np.mean(ds.speed))
        if speed < -0.5 * float(np.sqrt(np.mean(ds.speed**2))):
            warnings += _refuse(f"data '{name}': the speed column is negative (mean {speed:.5g} rad/s): the "
                                "model's rotor turns in the positive sense, so the speed sensor's sign is "
                                "reversed; negate the speed column", force, DataError)
        tip = abs(speed) * radius
        if cfg.mode == "speed" and cfg.speed:
            unit = _match(speed / cfg.speed, SPEED_FACTORS)
            if unit:
                warnings += _refuse(f"data '{name}': the speed column's mean {speed:.5g} rad/s is "
                                    f"{speed / cfg.speed:.4g} x the configured {cfg.speed:.5g} rad/s: "
                                    + _which_speed(cfg, ds, speed, unit), force, DataError)
        if tip > MAX_TIP_SPEED and not warnings:
            warnings += _refuse(f"data '{name}': the speed column's mean {speed:.5g} rad/s gives a vane tip "
                                f"speed of {tip:.3g} m/s (limit {MAX_TIP_SPEED:g}); rpm? (set the speed unit rpm)",
                                force, DataError)
    w = speed if speed and speed > 0 else (cfg.speed if cfg.speed else None)
    if w and ds.angle is not None and ds.n > 2 and not warnings:
        warnings += _check_angle_unit(ds, w, "the speed" if speed and speed > 0 else "the configured speed", force)
    if w and "speed" not in params and ds.n > 1:
        dt = float(np.median(np.diff(ds.time)))
        per_rev = 2 * math.pi / (w * dt)
        if per_rev < MIN_SAMPLES_PER_REV:
            # a unit that would make the record shorter than a revolution is not the record's
            span = float(ds.time[-1] - ds.time[0])
            unit = next((u for u, f in TIME_FACTORS.items() if per_rev * f >= MIN_SAMPLES_PER_REV
                         and w * span / f >= 2 * math.pi), None)
            vanes = cfg.vanes
            hint = f": the time column looks like {unit}" if unit else (
                f": the log is too slow for this pump (read in ms or us the {span:.3g} s record would be "
                f"shorter than a revolution); log at {MIN_SAMPLES_PER_REV * w / (2 * math.pi):.3g} Hz or "
                f"faster (the vane passing of {vanes} vanes at {w:.5g} rad/s is at "
                f"{vanes * w / (2 * math.pi):.3g} Hz)")
            warnings += _refuse(f"data '{name}': {per_rev:.3g} samples per revolution at {w:.5g} rad/s "
                                f"(sample interval {dt:.4g} s; at least {MIN_SAMPLES_PER_REV} needed){hint}",
                                force, DataError)
    if w:
        warnings += _check_torque_level(cfg, ds, w, force)
    return warnings


def _which_speed(cfg, ds, speed, unit) -> str:
    """Which of two speeds a unit factor apart is wrong: the one at which no COF in [MIN_COF, 2]
    gives the measured torque level (the model's torque grows with the speed) -- the config's
    names its key, the column's its unit; both when the torque tells neither apart."""
    level = float(np.sqrt(np.mean(ds.torque**2)))
    fits = {w: lo <= level <= hi for w, ((lo, _), (hi, _), _) in
            ((w, _model_torques(cfg, w)) for w in (speed, cfg.speed))}
    column = f"the column looks like {unit}"
    key = (f"operation.speed = {cfg.speed:.5g} rad/s (operation.speed_rpm = {cfg.speed * 30 / math.pi:.5g}) "
           f"looks wrong: write the pump's speed in rad/s as operation.speed, or in rpm as operation.speed_rpm")
    if fits[speed] and not fits[cfg.speed]:
        return (f"the torque level ({level:.3g} N m RMS) fits the model at the column's speed, not at the "
                f"configured one: {key}")
    if fits[cfg.speed] and not fits[speed]:
        return column
    return f"{column}, or {key}"


def _check_angle_unit(ds, speed, against, force) -> list:
    """An angle column whose slope is a unit factor times `speed` [rad/s]: degrees read as rad. The
    median step, not the end-to-end slope, so an angle wrapped at 360 (or 2 pi) reads the same."""
    step = float(np.median(np.diff(ds.angle))) / float(np.median(np.diff(ds.time)))
    unit = _match(step / speed, ANGLE_FACTORS)
    if not unit:
        return []
    return _refuse(f"data '{ds.name}': the angle column looks like {unit} (its slope {step:.5g} /s is "
                   f"{step / speed:.3g}x {against}, {speed:.5g} rad/s): give its header as 'angle [deg]'",
                   force, DataError)


def _model_torques(cfg, speed):
    """[(RMS, mean)] of the model torque over one revolution at `speed` for COFs MIN_COF and 2
    (housing and slot, statics scaled by the configured ratios): the range a fit of mu can reach;
    then at the configured COF: the level the data should have."""
    from .config import as_array
    from .kernels import load_kernels, sampled_inverse_dynamics

    pv = cfg.parameters("constrained")
    kern = load_kernels(pv.structure)
    grid = np.linspace(0, 2 * math.pi, 360, endpoint=False)
    out = []
    for mu in (MIN_COF, 2.0, pv.values["friction.housing.dynamic"]):
        vals = dict(pv.values)
        for side in ("housing", "slot"):
            ratio = vals[f"friction.{side}.static"] / max(vals[f"friction.{side}.dynamic"], 1e-300)
            vals[f"friction.{side}.dynamic"] = mu
            vals[f"friction.{side}.static"] = mu * ratio
        pv2 = pv.copy()
        pv2.values.update(vals)
        tq = sampled_inverse_dynamics(kern, as_array(pv2), grid, speed, 0.0, ("torque",))["torque"]
        out.append((float(np.sqrt(np.mean(tq**2))), float(np.mean(tq))))
    return out


def _nearest_units(level, nominal, candidates) -> list:
    """The unit whose factor brings `level` nearest the model's `nominal` level (log distance);
    both nearest when the runner-up is within half a decade of as near (ambiguous)."""
    if nominal <= 0:
        return [u for u, _ in candidates[:1]]
    ranked = sorted(candidates, key=lambda uf: abs(math.log10(level / uf[1] / nominal)))
    far = [abs(math.log10(level / f / nominal)) for _, f in ranked]
    return [u for (u, _), d in zip(ranked[:2], far[:2]) if d - far[0] < AMBIGUOUS_DECADES]


def _check_torque_level(cfg, ds, speed, force):
    (lo, low_mean), (hi, high_mean), (nominal, _) = _model_torques(cfg, speed)
    level, mean = float(np.sqrt(np.mean(ds.torque**2))), float(np.mean(ds.torque))
    if mean < -0.5 * level and min(low_mean, high_mean) > 0:
        return _refuse(f"data '{ds.name}': the torque column's mean is negative ({mean:.4g} N m) where the "
                       f"model's is positive for every COF ({low_mean:.3g} .. {high_mean:.3g} N m at "
                       f"{speed:.5g} rad/s): the torque sensor's sign is reversed; negate the torque column",
                       force, DataError)
    if not level > 0 or hi <= 0 or lo / TORQUE_MARGIN <= level <= hi * TORQUE_MARGIN:
        return []
    fits = _nearest_units(level, nominal, [(u, f) for u, f in TORQUE_FACTORS.items() if lo / 2 <= level / f <= 2 * hi])
    why = f": the torque looks like {' or '.join(fits)}" if fits else \
        ": check the torque unit and the configuration (lengths m, masses kg)"
    return _refuse(f"data '{ds.name}': torque RMS {level:.4g} N m is outside what the model gives at "
                   f"{speed:.5g} rad/s for any COF in [{MIN_COF:g}, 2] ({lo:.3g} .. {hi:.3g} N m){why}",
                   force, DataError)
