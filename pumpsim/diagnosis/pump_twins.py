"""Twin bench logs with a known fault, for the bench-log diagnosis's tests and benchmark grid: the
library's effects (pump_effects; a sensor's calibration error maps the model's channels, the log's
own noise added after) and faults outside it -- what an independent rig plausibly has that the
model of the config does not: another booster volume, a supply ripple the logger filters out."""
from __future__ import annotations

import dataclasses

import numpy as np

from ..identification import bench_sensors
from ..identification.pumpdown_fit import twin_log
from ..tolerances import BENCH_FIT_ATOL, BENCH_FIT_RTOL
from .pump_effects import BY_NAME, RISE, SUPPLY

HEATING_ITERATIONS = 3  # fixed-point passes for the heated drive's current (the rise is a small correction)

# faults outside the library: (what changes, how it is set)
OUTSIDE = {
    "booster_volume": "the booster's volume differs from the config (booster.volume x size)",
    "voltage_ripple": "the supply carries a 100 Hz ripple of `size` V amplitude that the logged voltage "
                      "does not show (the logger's filter averages it)",
}
RIPPLE_HZ = 100.0  # a full-wave rectified 50 Hz supply


def fault_values(cfg, effect: str, size: float) -> dict:
    """The config values a library effect of `size` (its parameter's change from absent) sets;
    {} for the effects that are not config keys (SUPPLY as motor.resistance, RISE: heated_twin, a
    sensor's: twin_with_fault reads the channels through it)."""
    e = BY_NAME[effect]
    if e.param == SUPPLY:
        return {"motor.resistance": cfg.pneumatic.values["motor.resistance"] + size}
    if e.param == RISE or e.param in bench_sensors.BY_NAME:
        return {}
    return {e.param: e.absent_value(cfg) + size}


def twin_with_fault(cfg, duration, rate, fault=None, size=0.0, values=None, noise=0.005, seed=0,
                    rtol=BENCH_FIT_RTOL, atol=BENCH_FIT_ATOL):
    """A twin bench log (pumpdown_fit.twin_log) of a pump with `fault` (a library effect's name or
    one of OUTSIDE; None: none) of `size`: a parameter change in its unit (a sensor gain's from 1,
    its offset in Pa), a volume factor. A winding heating is simulated with the drive V - dR (t/T) i, i the model's own
    current (fixed point), and logged with the supply's voltage."""
    vals = dict(values or {})
    if fault in BY_NAME:
        vals.update(fault_values(cfg, fault, size))
    elif fault == "booster_volume":
        vals["booster.volume"] = cfg.pneumatic.values["booster.volume"] * size
    elif fault not in (None, "voltage_ripple"):
        raise ValueError(f"fault must be a library effect or one of {', '.join(OUTSIDE)}, got {fault!r}")
    kw = {"values": vals, "noise": noise, "seed": seed, "rtol": rtol, "atol": atol}
    if fault is not None and BY_NAME.get(fault) is not None and BY_NAME[fault].param == RISE:
        return _heated_twin(cfg, duration, rate, size, kw)
    if fault == "voltage_ripple":
        return _rippled_twin(cfg, duration, rate, size, kw)
    if fault in BY_NAME and BY_NAME[fault].param in bench_sensors.BY_NAME:
        return _misread_twin(cfg, duration, rate, BY_NAME[fault], size, kw)
    return twin_log(cfg, duration, rate, **kw)


def _misread_twin(cfg, duration, rate, effect, size, kw):
    """The log a sensor with this calibration error writes: the log's channels, noise and all (the
    noise of what the sensor reads), read through it (bench_sensors.read)."""
    log = twin_log(cfg, duration, rate, **kw)
    read = bench_sensors.read({c: getattr(log, c) for c in ("current", "booster_pressure")},
                              {effect.param: effect.absent + size})
    return dataclasses.replace(log, **read)


def _rippled_twin(cfg, duration, rate, amplitude, kw):
    v = cfg.pneumatic.values["motor.voltage"]
    log = twin_log(cfg, duration, rate, voltage=lambda t: v + amplitude * np.sin(2 * np.pi * RIPPLE_HZ * t), **kw)
    # logged: the supply's mean with the log's noise
    return dataclasses.replace(log, voltage=log.voltage - amplitude * np.sin(2 * np.pi * RIPPLE_HZ * log.time))


def _heated_twin(cfg, duration, rate, rise, kw):
    v = cfg.pneumatic.values["motor.voltage"]
    current = None
    for _ in range(HEATING_ITERATIONS):
        drive = _drive(v, rise, duration, current)
        current = twin_log(cfg, duration, rate, voltage=drive, **{**kw, "noise": 0.0}).current
    drive = _drive(v, rise, duration, current)
    log = twin_log(cfg, duration, rate, voltage=drive, **kw)
    # logged: the supply's voltage (with the log's noise), not the drive the winding sees
    return dataclasses.replace(log, voltage=log.voltage + (v - drive(log.time)))


def _drive(v, rise, duration, current):
    if current is None:
        return lambda t: np.full_like(t, v)
    return lambda t: v - rise * (t / duration) * current[:t.size]
