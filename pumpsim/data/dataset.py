"""A measurement in SI units (`Dataset`) and the options that say how to read one (`DataOptions`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .trend import SpeedTrend, speed_trend


@dataclass
class Dataset:
    """A measurement in SI units: time [s] (strictly increasing), torque [N m], optional speed
    [rad/s] and angle [rad], one value per sample. `source` names the file (or 'arrays').

    Example::

        ds = Dataset(time=t, torque=tq)              # from arrays already in SI
        ds = pumpsim.load_data("rig.csv")           # from a file (CSV, .mat, .tdms)
    """

    time: np.ndarray
    torque: np.ndarray
    speed: np.ndarray | None = None
    angle: np.ndarray | None = None
    source: str = ""
    notes: list = field(default_factory=list)
    # per sample, False where resampling interpolated inside a gap in time (sampling.resample):
    # invented values a fit leaves out of its residual; None: every sample measured
    measured: np.ndarray | None = None
    _trend: object = field(default=None, init=False, repr=False, compare=False)

    @property
    def n(self) -> int:
        return self.time.size

    def speed_trend(self) -> "SpeedTrend | None":
        """The speed column's significant slow trend (see `speed_trend`), or None; computed once."""
        if self._trend is None:
            self._trend = (speed_trend(self.time, self.speed),)
        return self._trend[0]

    def turned(self) -> np.ndarray:
        """The angle the speed column turns from the first sample (trapezoidal integral)."""
        return np.concatenate([[0.0], np.cumsum(0.5 * (self.speed[1:] + self.speed[:-1]) * np.diff(self.time))])

    def mean_speed(self) -> float | None:
        """The speed column's mean over the longest stretch of whole revolutions from the first
        sample (None without a column): the angle it turns (trapezoidal integral) over the time it
        takes. A plain mean over a record that ends part-way through a revolution carries the
        unfinished part of any shaft-periodic speed content: a 2.8 % order-3 speed ripple over
        1 s biased it by 1e-5 (0.005 rad of angle by the end, lines of 2.3 x the noise at order 3
        left after the ripple's fit). Over whole revolutions every integer shaft order averages
        out, to within one sample's share. A column with a significant slow trend: the trend's mean,
        the one the model's drive time is scaled by (identification.sampled.drive_kinematics)."""
        if self.speed is None:
            return None
        if self.speed_trend() is not None:
            return self.speed_trend().mean
        turned = self.turned()
        revs = math.floor(turned[-1] / (2 * math.pi) + 1e-9)
        if revs < 1:
            return float(np.mean(self.speed))
        end = int(np.searchsorted(turned, revs * 2 * math.pi, side="right")) - 1
        if end < 1:
            return float(np.mean(self.speed))
        return float(turned[end] / (self.time[end] - self.time[0]))

    @property
    def name(self) -> str:
        return Path(self.source).name if self.source else "data"

    def window(self, lo: int, hi: int) -> "Dataset":
        cut = lambda a: None if a is None else a[lo:hi]  # noqa: E731
        return Dataset(self.time[lo:hi], self.torque[lo:hi], cut(self.speed), cut(self.angle),
                       self.source, list(self.notes), cut(self.measured))

    def __repr__(self):
        cols = ", ".join(k for k in ("speed", "angle") if getattr(self, k) is not None)
        span = f"{self.time[-1] - self.time[0]:.4g} s" if self.n else "empty"
        return (f"Dataset({self.name!r}: {self.n} samples, {span}, torque"
                f"{', ' + cols if cols else ''})")


@dataclass
class DataOptions:
    """How to read a data file: column (or channel/variable) names and units. A unit of None takes
    the unit from the column header (`torque [N*mm]`), else SI. `voltage`, `current`,
    `booster_pressure` and their units are a bench log's (spec §10); `pressure_unit` may carry the
    absolute/gauge mark ('kPa abs')."""

    time: str = "time"
    torque: str = "torque"
    speed: str | None = "speed"  # used when present
    angle: str | None = "angle"
    torque_unit: str | None = None
    speed_unit: str | None = None
    time_unit: str | None = None
    angle_unit: str | None = None
    resample: float | str | None = None  # Hz, or 'auto': the measured sample interval's rate
    steady: bool = False  # keep only the constant-speed section
    steady_tolerance: float = 0.01  # relative speed band of the constant-speed section
    voltage: str = "voltage"
    current: str = "current"
    booster_pressure: str = "booster_pressure"
    voltage_unit: str | None = None
    current_unit: str | None = None
    pressure_unit: str | None = None
