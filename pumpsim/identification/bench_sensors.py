"""A bench's sensors as the model's output mapping (spec §10): what a logged channel reads is its
sensor's gain times the model's value plus its offset, measured = gain * model + offset. The
physics is untouched; a calibration error only maps the model's channels onto the log.

The pressure sensor also reads the log's start, from which the model's booster starts
(`true_start`): the booster's own pressure there is the reading mapped back, (reading - offset) /
gain. So a span or offset error does not start the pump-down off by the error and the mapping
at its absent values (gain 1, offset 0) is the model without it.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Sensor:
    """One calibration figure: its name, the logged channel it maps, how (`gain` or `offset`), its
    absent value (a calibrated sensor) and its plausible range."""

    name: str
    channel: str
    kind: str
    absent: float
    bounds: tuple


SENSORS = (
    Sensor("sensor.current_gain", "current", "gain", 1.0, (0.5, 2.0)),
    Sensor("sensor.pressure_gain", "booster_pressure", "gain", 1.0, (0.5, 2.0)),
    Sensor("sensor.pressure_offset", "booster_pressure", "offset", 0.0, (-50e3, 50e3)),  # Pa
)
BY_NAME = {s.name: s for s in SENSORS}
NAMES = tuple(BY_NAME)


IDENTITY = {"gain": 1.0, "offset": 0.0}  # a channel without a sensor figure of that kind


def _figure(values: dict, channel: str, kind: str) -> float:
    s = next((s for s in SENSORS if s.channel == channel and s.kind == kind), None)
    return IDENTITY[kind] if s is None else float(values.get(s.name, s.absent))


def calibrated(values: dict) -> bool:
    """Whether every sensor figure in `values` is at its absent value (the mapping is the identity)."""
    return all(float(values.get(s.name, s.absent)) == s.absent for s in SENSORS)


def read(channels: dict, values: dict) -> dict:
    """The channels as the sensors with the figures in `values` (name -> value; a missing one
    calibrated) read them: gain * model + offset, each channel by its own sensor."""
    return {c: _figure(values, c, "gain") * y + _figure(values, c, "offset") for c, y in channels.items()}


def true_start(reading: float, values: dict) -> float:
    """The booster's pressure behind a start reading of the pressure sensor with these figures."""
    return (reading - _figure(values, "booster_pressure", "offset")) / _figure(values, "booster_pressure", "gain")
