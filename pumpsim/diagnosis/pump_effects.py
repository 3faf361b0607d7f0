"""The pump-level effect library of a bench-log diagnosis (spec §10): what can have moved in a pump
on an end-of-line or durability bench, one declaration per effect, and the problem that fits them.

Most effects are a config key fitted away from its configured value (a booster leak, worn vane
tips, a late exhaust valve, motor friction, a winding resistance). Two are not config keys:

- `supply_resistance`: a series resistance between the logged voltage and the motor terminals
  (harness, connector, a supply that sags). V_log = (R + R_s) i + L di/dt + k omega: it enters
  the model exactly as motor.resistance + R_s, so on a log it is indistinguishable from a constant
  winding-resistance error (`winding_resistance`); the workflow says `confounded` unless the
  winding resistance is known from a separate measurement (resistance_known).
- `winding_heating`: the winding resistance rising over the run, R(t) = R + dR t / T (T the log's
  length). The compiled model has a constant R, so the rise enters through the drive: the motor
  is driven by V_log - dR (t / T) i_log, the logged current standing in for the model's (an
  errors-in-variables approximation: the current's noise enters the drive scaled by dR, far below
  the voltage's own noise for a rise of a few tenths of an ohm).

Three are the bench's sensors, not the pump (identification.bench_sensors: measured = gain * model
+ offset, the booster starting from the start reading mapped back): a current sensor (shunt)
reading `gain` x the current, a pressure sensor whose span or offset is off. They are named like
the pump's effects, or reported `confounded` with the pump effect that reads the same on the log,
with the check that separates them.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..benchlog import BenchLog
from ..identification import bench_sensors
from ..identification.bench_model import START_NAME
from ..identification.pumpdown_fit import BenchLogProblem
from ..signals import noise_sigma, rounding_sigma

SUPPLY = "supply.resistance"  # ohm in series before the motor terminals
RISE = "motor.resistance_rise"  # ohm the winding resistance rises over the log
# the fitted names that are not config keys: a drive's, the sensors'
PSEUDO = (SUPPLY, RISE, *bench_sensors.NAMES)
PSEUDO_BOUNDS = {SUPPLY: (0.0, 10.0), RISE: (-1.0, 10.0), **{s.name: s.bounds for s in bench_sensors.SENSORS}}


@dataclass(frozen=True)
class PumpEffect:
    """One effect of the library: its name (spec §10), the fitted name, its absent value's source
    (None: the configured value; a number: that value), the probe step of its screen column (a
    clear fault's size) and what it means for the pump."""

    name: str
    param: str
    probe: float
    description: str
    absent: float | None = None
    unit: str = ""
    # what would tell it from an effect it is confounded with on one log
    separate: str = ""
    # a change outside the library that reads the same on a pump-down log (said whenever it is named)
    alias: str = ""
    # the effect exists only as a rise from its absent value: a fit that moves it the other way has
    # found something else (what the wrong-way value absorbs), not this effect
    one_way: str = ""

    def absent_value(self, cfg) -> float:
        return float(cfg.pneumatic.values[self.param]) if self.absent is None else self.absent

    def wrong_way(self, change: float) -> str:
        """Why a fitted change from the absent value is not this effect ('' when it may be)."""
        if self.one_way and change <= 0.0:
            return f"its fit moves {self.param} by {change:.3g} {self.unit}: {self.one_way}, not this effect"
        return ""


PUMP_EFFECTS = (
    PumpEffect("booster_leak", "booster.leak", 1e-5, "the booster (reservoir, hoses) leaks", unit="kg/s",
               separate="a hold test: the pump stopped at a low booster pressure, the check valve closed"),
    PumpEffect("tip_clearance", "leak.tip_gap", 5e-6, "the vane-tip clearance has grown (wear)", unit="m",
               separate="a run with the inlet closed: the pressure the pump holds depends on its clearances alone"),
    PumpEffect("valve_late", "valve.cracking", 2000.0,
               "the exhaust valve opens at a higher pressure difference", unit="Pa",
               separate="the pressure sensor checked against a reference at the atmosphere and at a low pressure",
               # measured: a 0.5 s twin with the valve 10 kPa late is fitted to its noise by the vane COF and
               # the pressure reading 5.7 % high, unless the booster's start is known (the barometer read):
               # the span scales the start, the valve does not move it
               alias="a pressure sensor whose span is a few per cent high"),
    PumpEffect("motor_friction", "motor.friction", 5e-3, "the motor's friction torque has grown (bearings, brushes)",
               unit="N m", separate="a free-running current with the inlet open at two voltages"),
    PumpEffect("supply_resistance", SUPPLY, 0.05, "a series resistance before the motor terminals "
               "(harness, connector, supply): a voltage drop the log does not show", absent=0.0, unit="ohm",
               one_way="a negative series resistance",
               separate="the voltage logged at the motor terminals, or a stalled-rotor current at a low voltage "
                        "measured there (the winding resistance alone)"),
    PumpEffect("winding_heating", RISE, 0.05, "the winding resistance rises over the run (the winding warms up)",
               absent=0.0, unit="ohm over the log",
               one_way="a winding that cools while it carries the pump-down's current",
               separate="the winding resistance measured before and after the run"),
    PumpEffect("winding_resistance", "motor.resistance", 0.05,
               "the winding resistance differs from the config (another batch, a warm motor)", unit="ohm",
               separate="a stalled-rotor current at a low voltage measured at the motor terminals"),
    PumpEffect("current_gain", "sensor.current_gain", 0.02,
               "the current sensor (shunt, clamp) reads this factor times the current", absent=1.0, unit="x",
               separate="the current sensor calibrated against a reference ammeter (or the shunt's resistance "
                        "measured)"),
    PumpEffect("pressure_gain", "sensor.pressure_gain", 0.02,
               "the pressure sensor's span is off: it reads this factor times the pressure", absent=1.0, unit="x",
               separate="the pressure sensor read at a low pressure against a reference gauge"),
    PumpEffect("pressure_offset", "sensor.pressure_offset", 1000.0,
               "the pressure sensor reads this much above the pressure (zero offset)", absent=0.0, unit="Pa",
               separate="the pressure sensor read with the booster vented against the barometer"),
)
BY_NAME = {e.name: e for e in PUMP_EFFECTS}
OF_PARAM = {e.param: e for e in PUMP_EFFECTS}


def library(resistance_known: bool = False, exclude=()) -> list:
    """The effects a diagnosis tries: without `winding_resistance` when the winding resistance is
    known (a stalled-rotor measurement); never those named in `exclude` (already in the model)."""
    return [e for e in PUMP_EFFECTS if e.name not in exclude
            and not (resistance_known and e.name == "winding_resistance")]


def heated_drive(log: BenchLog, rise: float) -> BenchLog:
    """The log with the drive that a winding rising by `rise` ohm over the run sees (module doc)."""
    if rise == 0.0:
        return log
    ramp = (log.time - log.time[0]) / max(log.time[-1] - log.time[0], 1e-300)
    return dataclasses.replace(log, voltage=log.voltage - rise * ramp * log.current)


def unweighted(r, w):
    """A weighted residual back in channel sigmas (a value left out, weight inf: 0)."""
    finite = np.isfinite(w)
    return np.where(finite, np.asarray(r, float) * np.where(finite, w, 0.0), 0.0)


class Drives:
    """The bench-log problems of one diagnosis, one per drive (a winding rise heats it), each over
    every real config name any model of the diagnosis holds: the candidates' problems share them,
    and with them their compiled integrators and the last run."""

    def __init__(self, cfg, log: BenchLog, values: dict, rtol, atol, start_known: bool = False):
        self.cfg, self.log, self.rtol, self.atol = cfg, log, rtol, atol
        # the booster's start pressure (START_NAME's value) is known (the config's booster start, the
        # barometer read), not the pressure sensor's start reading
        self.start_known = start_known
        self.names = [n for n in values if n not in PSEUDO]
        self.values = {n: float(values[n]) for n in self.names}
        self._by_rise = {}
        self._retired = 0  # runs of the problems no longer kept
        # per compared value, the residual's own noise level in units of its channel's sigma (1: the
        # log's channel noise; set_weights): the model's block-mean current carries the logged
        # voltage's noise too (its integral drives it), which the current's own sigma does not count
        self.weight = None

    @staticmethod
    def _rounding(base) -> dict:
        """Per channel the sigma of its rounding (q^2 / 12 of the grid its values lie on; 0 off a
        grid) in the channel's noise sigmas."""
        return {c: rounding_sigma(base.measured[c]) / base.sigma[c] for c in base.channel_names}

    def rounding_floors(self) -> dict:
        """_rounding in the units of the weighted residual (set_weights)."""
        base = self.get(0.0)
        floor = self._rounding(base)
        if self.weight is None:
            return floor
        sizes = [base.measured[c].size for c in base.channel_names]
        parts = np.split(self.weight, np.cumsum(sizes)[:-1])
        return {c: floor[c] / float(np.median(w)) for c, w in zip(base.channel_names, parts)}

    def set_weights(self, residual):
        """Each channel's weight: the robust white-noise level of `residual` (a fit's, in channel
        sigmas) on that channel's values: every channel's residual noise then has unit variance."""
        base = self.get(0.0)
        sizes = [base.measured[c].size for c in base.channel_names]
        r = np.asarray(residual, float) if self.weight is None else unweighted(residual, self.weight)
        parts = np.split(r, np.cumsum(sizes)[:-1])
        # a channel rounded to a grid (an ADC's counts) carries at least its rounding, which the
        # residual's first differences miss where the channel moves less than a step per sample
        floor = self._rounding(base)
        w = {c: np.full(r.size, max(noise_sigma(r), floor[c], 1e-12)) for c, r in zip(base.channel_names, parts)}
        # the first current block holds the switch-on inrush (rising over L/R, a fraction of a
        # millisecond): the log's trapezoidal mean of samples milliseconds apart does not measure
        # it (a clean twin's first block misses by ~19 sigmas), so it is left out
        if "current" in w:
            w["current"][0] = np.inf
        self.weight = np.concatenate([w[c] for c in base.channel_names])

    @property
    def runs(self) -> int:
        """Model runs of the whole log so far."""
        return self._retired + sum(p.n_eval for p in self._by_rise.values())

    def get(self, rise: float) -> BenchLogProblem:
        key = float(rise)
        if key in self._by_rise:  # least recently used goes first: the no-heating problem stays
            self._by_rise[key] = self._by_rise.pop(key)
        else:
            if len(self._by_rise) >= 4:  # each holds a compiled integrator: keep the last few
                self._retired += self._by_rise.pop(next(iter(self._by_rise))).n_eval
            self._by_rise[key] = BenchLogProblem(self.cfg, heated_drive(self.log, key), self.names,
                                                 initial=self.values, rtol=self.rtol, atol=self.atol)
        return self._by_rise[key]


class EffectProblem:
    """The bench-log problem with the library's two effects that are not config keys: SUPPLY added
    to motor.resistance, RISE through the drive (module doc). What the optimiser needs: names, x0,
    lower, upper, y, model, model_and_jacobian (secant columns), keep_at, n_eval."""

    def __init__(self, drives: Drives, names, values: dict):
        self.drives = drives
        self.names = list(names)
        self.values = dict(values)  # every value the model holds; fitted names start here
        base = drives.get(self.values.get(RISE, 0.0))
        self.w = 1.0 if drives.weight is None else drives.weight
        self.y, self.sigma, self.channel_names = base.y / self.w, base.sigma, base.channel_names
        bounds = [PSEUDO_BOUNDS[n] if n in PSEUDO else (base.lower[base.names.index(n)], base.upper[base.names.index(n)])
                  for n in self.names]
        self.lower, self.upper = (np.array(b, float) for b in zip(*bounds))
        self.x0 = np.array([self.values[n] for n in self.names], float)
        self.n_eval = 0

    def _point(self, x) -> tuple:
        """(the bench-log problem, its x, every value) for fitted values x: the booster starts from
        the start reading mapped back through the pressure sensor (bench_sensors.true_start), or
        from the known start (Drives.start_known)."""
        v = {**self.values, **dict(zip(self.names, map(float, x)))}
        inner = self.drives.get(v.get(RISE, 0.0))
        xi = np.array([bench_sensors.true_start(v[n], v) if n == START_NAME and not self.drives.start_known else
                       v[n] + (v.get(SUPPLY, 0.0) if n == "motor.resistance" else 0.0) for n in inner.names])
        return inner, xi, v

    def model(self, x):
        self.n_eval += 1
        inner, xi, v = self._point(x)
        m = inner.model(xi)
        if not bench_sensors.calibrated(v):  # the run is the one just made (inner caches it)
            m = inner.scaled(bench_sensors.read(inner.simulate(xi), v))
        return m / self.w

    def channels(self, x) -> dict:
        """{channel: model values (unscaled), as the sensors read them} at x, as compared."""
        inner, xi, v = self._point(x)
        return bench_sensors.read(inner.simulate(xi), v)

    def column(self, x, j, h, m) -> np.ndarray:
        """The secant column of name j over a step h (away from the upper bound), m the model at x."""
        x = np.asarray(x, float)
        xp = x.copy()
        xp[j] = x[j] + h if x[j] + h <= self.upper[j] else x[j] - h
        return (self.model(xp) - m) / (xp[j] - x[j])

    def model_and_jacobian(self, x, cols=None):
        x = np.asarray(x, float)
        cols = list(range(len(self.names)) if cols is None else cols)
        m = self.model(x)
        J = np.column_stack([self.column(x, j, self.step(j, x), m) for j in cols]) if cols else np.zeros((m.size, 0))
        return m, J

    def step(self, j, x) -> float:
        """A difference step: an effect's probe, a clear fault's size (at rtol 1e-4 the integrator's
        step-size noise is ~1e-4 of a channel, ~2 % of the change a tenth of a probe makes: a column
        that noisy stalled Gauss-Newton short of the fit), else 1 % of the value."""
        n = self.names[j]
        return OF_PARAM[n].probe if n in OF_PARAM else 1e-2 * max(abs(x[j]), 1e-3)

    def keep_at(self, x):
        return None
