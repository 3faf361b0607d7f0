"""Bench logs (spec §10): what a pump bench measures -- time, the supply voltage at the motor
terminals, the motor current, the booster pressure (absolute) and optionally the speed -- read from
CSV, MATLAB .mat or NI TDMS (the readers of pumpsim.data) into a validated `BenchLog` in SI units.

Units come from the headers (`booster_pressure [kPa]`, `current (mA)`), else SI. A pressure column
may say whether it is absolute (`kPa abs`, `bara`, `kPa(a)`) or gauge (`kPa g`, `barg`, `psig`);
gauge pressure is refused with the fix (the day's atmosphere is not known here), and so is an
unmarked column that reads as gauge: negative values, or a pump-down from atmosphere whose first
samples lie far below it. Bad rows (NaN, time not increasing, gaps) are named as for torque data.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .data import (SPEED_UNITS, TIME_UNITS, DataOptions, match_column, read_csv, reader_for, row_name,
                   time_gaps, time_resolution, unit_key)
from .data.units import split_header
from .signals import isolated_spikes, measured_noise, noise_sigma
from .errors import DataError

CHANNELS = ("voltage", "current", "booster_pressure")  # required besides time
COMPARED = ("booster_pressure", "current", "speed")  # what the model is compared with, when logged
VOLTAGE_UNITS = {"v": 1.0, "mv": 1e-3, "kv": 1e3}
CURRENT_UNITS = {"a": 1.0, "ma": 1e-3, "ka": 1e3}
PRESSURE_UNITS = {"pa": 1.0, "hpa": 1e2, "kpa": 1e3, "mpa": 1e6, "mbar": 1e2, "bar": 1e5,
                  "psi": 6894.757293168, "torr": 133.322368, "mmhg": 133.322387}
# an unmarked pressure column whose start times a unit's factor lies within this share of the config's
# booster start reads as written in that unit without saying so
UNIT_MATCH = 0.15
# the units a bench writes (table key: spelling), in the order they are guessed
UNIT_GUESSES = {"kpa": "kPa", "mbar": "mbar", "bar": "bar", "psi": "psi", "torr": "torr"}
UNITS = {"time": TIME_UNITS, "voltage": VOLTAGE_UNITS, "current": CURRENT_UNITS,
         "booster_pressure": PRESSURE_UNITS, "speed": SPEED_UNITS}
UNIT_NAMES = {"time": "s, ms, us", "voltage": "V, mV", "current": "A, mA",
              "booster_pressure": "Pa, hPa, kPa, MPa, mbar, bar, psi, torr (with abs or g)",
              "speed": "rad/s, rpm (1/min), rev/s (Hz), deg/s"}
# the marks after a pressure unit, longest first ('pa' itself ends in 'a': the unit is tried whole first)
ABSOLUTE_MARKS = ("(absolute)", "absolute", "(abs)", "abs", "(a)", "a")
GAUGE_MARKS = ("(gauge)", "gauge", "(relative)", "relative", "(rel)", "rel", "(g)", "g")
# an unmarked column whose first samples are below this fraction of a start from atmosphere is
# gauge: an absolute pump-down from atmosphere starts near it, a gauge one near 0
GAUGE_START_FRACTION = 0.5
START_SAMPLES = 20  # samples a quadratic is fitted to for the log's start pressure
# a log that starts above the config's atmosphere by more than this share (and 3 noise sigmas of its
# start) is named: a booster is evacuated from the atmosphere at most
ATMOSPHERE_MARGIN = 0.005
VOLTAGE_FACTOR = 5.0  # a median voltage this far from motor.voltage is a unit mistake
MIN_SAMPLES = 10
# the motor is off where the supply reads under this share of its running level (the 90th
# percentile of |voltage|): a log's idle lead-in before the switch-on, or its tail after a switch-off
IDLE_VOLTAGE_SHARE = 0.1
SPIKE_SIGMAS = 12.0  # a single sample this many noise sigmas off its agreeing neighbours is a glitch
SPIKES_LISTED = 5
# Names loggers give the bench channels, compared in lower case with runs of other characters as
# '_' ('Motor Current (A)' -> 'motor_current'): tried for a channel left at its default name that no
# column carries, and taken only when exactly one column answers
ALIASES = {
    "time": ("t", "time_s"),
    "voltage": ("supply_voltage", "motor_voltage", "terminal_voltage", "battery_voltage", "supply", "u_supply",
                "u_bat", "u_batt", "ubat", "vbat", "v_supply", "u"),
    "current": ("motor_current", "supply_current", "i_motor", "i_mot", "imot", "i_supply", "i"),
    "booster_pressure": ("pressure", "booster", "p_booster", "reservoir_pressure", "p_reservoir", "p"),
    "speed": ("motor_speed", "pump_speed", "rotor_speed"),
}
UNIT_OPTION_OF = {"time": "time_unit", "voltage": "voltage_unit", "current": "current_unit",
                  "booster_pressure": "pressure_unit", "speed": "speed_unit"}


@dataclass
class BenchLog:
    """A bench log in SI units: time [s] (strictly increasing, no gaps), voltage [V], current [A],
    booster_pressure [Pa absolute], optional speed [rad/s]; `source` names the file."""

    time: np.ndarray
    voltage: np.ndarray
    current: np.ndarray
    booster_pressure: np.ndarray
    speed: np.ndarray | None = None
    source: str = ""
    notes: list = field(default_factory=list)

    @property
    def n(self) -> int:
        return self.time.size

    @property
    def name(self) -> str:
        return Path(self.source).name if self.source else "bench log"

    @property
    def step(self) -> float:
        """The mean sample interval [s]."""
        return float((self.time[-1] - self.time[0]) / max(self.n - 1, 1))

    def channels(self) -> dict:
        """{name: samples} of the channels the model is compared with (COMPARED, where logged)."""
        return {c: getattr(self, c) for c in COMPARED if getattr(self, c) is not None}

    def noise(self, channel) -> float:
        """The channel's white-noise sigma: robust sigma of its first differences (a smooth
        pump-down hardly enters them; what the log's sampling aliases of the vane-passing ripple
        does, and is noise to a model compared sample by sample) with its grid's rounding
        (an ADC's counts: measured_noise)."""
        return measured_noise(getattr(self, channel))

    def start_pressure(self) -> float:
        """The booster pressure at the first sample: a quadratic in time fitted to the first
        START_SAMPLES and read at the first (one sample's noise would start the model off by a
        whole sigma, which a fitted leak then absorbs)."""
        m = min(START_SAMPLES, self.n)
        t = self.time[:m] - self.time[0]
        return float(np.polyval(np.polyfit(t, self.booster_pressure[:m], min(2, m - 1)), 0.0))

    def __repr__(self):
        extra = ", speed" if self.speed is not None else ""
        return (f"BenchLog({self.name!r}: {self.n} samples, {self.time[-1] - self.time[0]:.4g} s, voltage, "
                f"current, booster_pressure{extra})")


def start_above_atmosphere(log: BenchLog, cfg) -> str | None:
    """A sentence when the log starts above the config's gas.atmosphere by more than
    ATMOSPHERE_MARGIN and 3 noise sigmas of the start estimate, else None. The model starts the
    cells at, and exhausts to, gas.atmosphere and the booster at the log's start; a pressure
    sensor reading high (span or offset) or a day's atmosphere other than the config's then
    enters every fitted figure, and a span error reads like a model effect on a pump-down log."""
    if cfg is None or cfg.pneumatic is None:
        return None
    atm = cfg.pneumatic.values["gas.atmosphere"]
    start = log.start_pressure()
    sigma = noise_sigma(log.booster_pressure[:max(START_SAMPLES, 50)]) / math.sqrt(min(START_SAMPLES, log.n) / 3)
    if start <= atm * (1 + ATMOSPHERE_MARGIN) or start - atm <= 3 * sigma:
        return None
    return (f"the log starts at {start / 1e3:.4g} kPa, {100 * (start / atm - 1):.2g} % above the config's "
            f"gas.atmosphere {atm / 1e3:.4g} kPa: set gas.atmosphere to the day's barometer reading, or check "
            "the pressure sensor's span and offset against a reference -- a sensor reading high enters every "
            "figure fitted here, and its span error can read as a model effect")


def _reader(p: Path):
    return reader_for(p, read_csv)


def _normalised(name: str) -> str:
    """A column name compared with the channels' names and aliases: no unit, lower case, runs of
    other characters as '_'."""
    return re.sub(r"[^0-9a-z]+", "_", split_header(str(name))[0].lower()).strip("_")


def _find(key: str, wanted: str, names: list, alias: bool):
    hit = match_column(wanted, names)
    if hit in names:
        return hit
    same = [c for c in names if _normalised(c) == _normalised(wanted)]
    if len(same) == 1:
        return same[0]
    if alias:
        like = [c for c in names if _normalised(c) in ALIASES.get(key, ())]
        if len(like) == 1:
            return like[0]
    return None


def _pick(names, columns: dict) -> dict:
    """{channel: the file's column} for the channels found; `columns`: channel -> (wanted name,
    whether its aliases may answer)."""
    names = list(names)
    found = {k: _find(k, w, names, alias) for k, (w, alias) in columns.items() if w}
    return {k: v for k, v in found.items() if v is not None}


def _columns(options: DataOptions) -> dict:
    default = DataOptions()
    # DataOptions names each channel's column in the field of the channel's name
    cols = {k: (getattr(options, k), getattr(options, k) == getattr(default, k)) for k in UNIT_OPTION_OF}
    cols["torque"] = (options.torque, False)
    return cols


def is_bench_log(path, options: DataOptions | None = None) -> bool:
    """Whether the file is a bench log: two or more of voltage, current, booster_pressure and no
    torque column (a torque measurement may log the supply too). An unreadable file is not one
    (load_data then says why)."""
    p = Path(path)
    if not p.is_file():
        return False
    cols = _columns(options or DataOptions())
    try:
        src = _reader(p)(p, lambda names: _pick(names, {"time": cols["time"]}))
    except DataError:
        return False
    found = _pick(src.names or src.cols, cols)
    return "torque" not in found and sum(c in found for c in CHANNELS) >= 2


def unit_of(key: str, unit: str | None, where: str) -> tuple[float, str | None]:
    """(factor to SI, 'absolute' | 'gauge' | None) of a column's unit (None: SI, unmarked)."""
    if unit is None:
        return 1.0, None
    u = unit_key(unit)
    table = UNITS[key]
    if u in table:
        return table[u], None
    if key == "booster_pressure":
        for marks, kind in ((ABSOLUTE_MARKS, "absolute"), (GAUGE_MARKS, "gauge")):
            for m in marks:
                if u.endswith(m) and u[:-len(m)].rstrip("(_-") in table:
                    return table[u[:-len(m)].rstrip("(_-")], kind
    raise DataError(f"{where}: {key} unit must be one of {UNIT_NAMES[key]}, got '{unit}'")


def read_bench_log(path, cfg=None, options: DataOptions | None = None) -> BenchLog:
    """Read and validate a bench log (spec §10). cfg (a §8 config in motor mode): its booster start
    and motor voltage judge the pressure's gauge/absolute reading and the voltage's unit. options:
    the columns' names and units where the file's differ (DataOptions.voltage, .current,
    .booster_pressure, .time, .speed and their units)."""
    p = Path(path)
    try:
        return _load(p, cfg, options or DataOptions())
    except DataError as e:
        msg = str(e)
        raise DataError(msg if msg.startswith(f"data '{p}'") else f"data '{p}': {msg}") from None


def _load(p: Path, cfg, options: DataOptions) -> BenchLog:
    if p.is_dir():
        raise DataError("is a folder, not a data file")
    if not p.exists():
        raise DataError("cannot read data: no such file")
    cols = _columns(options)
    src = _reader(p)(p, lambda names: _pick(names, cols))
    where = src.where
    name = _pick(src.cols, cols)
    missing = [c for c in CHANNELS if c not in name]
    if missing:
        raise DataError(f"is not a complete bench log: no {where} {', '.join(repr(m) for m in missing)} "
                        f"(spec §10: time, voltage, current, booster_pressure[, speed]; found: {src.found()}); "
                        "a column named otherwise is given by name: --voltage-column, --current-column, "
                        "--pressure-column on the command line, DataOptions(voltage=..., current=..., "
                        "booster_pressure=...) in Python")
    notes = list(src.notes)
    if "time" in name:
        t = np.asarray(src.cols[name["time"]], dtype=float)
    else:
        iv = src.interval(name["current"])
        if iv is None:
            raise DataError(f"has no {where} '{cols['time'][0]}' and no sample rate (found: {src.found()})")
        dt, t0, origin = iv
        t = t0 + dt * np.arange(src.cols[name["current"]].size)
        notes.append(f"time from {origin} (no {where} '{cols['time'][0]}')")
    used = {k: np.asarray(src.cols[name[k]], dtype=float) for k in ("voltage", "current", "booster_pressure", "speed")
            if k in name}
    if "time" in name:
        used = {"time": t, **used}
    n = t.size
    if n < MIN_SAMPLES:
        raise DataError(f"has {n} samples; at least {MIN_SAMPLES} are needed")
    for key, arr in used.items():
        if arr.size != n:
            raise DataError(f"{where} '{name[key]}' has {arr.size} samples, {where} "
                            f"'{name.get('time', name['current'])}' has {n}")
        bad = np.nonzero(~np.isfinite(arr))[0]
        if bad.size:
            raise DataError(f"{row_name(src.rows, bad[0], where, name[key])}: {key} is not a finite number")
    si, factor, kind = {}, {}, None
    for key, arr in used.items():
        factor[key], k = _unit(key, src.units.get(name[key]), getattr(options, UNIT_OPTION_OF[key]),
                               f"{where} '{name[key]}'")
        si[key] = arr * factor[key] if factor[key] != 1.0 else arr
        kind = k if key == "booster_pressure" else kind
    if "time" in used:
        t = si["time"]
        _check_time(t, time_resolution(used["time"]) * factor["time"], src.rows, where, name["time"])
    _check_pressure(si["booster_pressure"], kind, cfg, src.rows, where, name["booster_pressure"])
    _check_signs(si, where, name)
    _check_voltage(si["voltage"], cfg, where, name["voltage"])
    for key in ("voltage", "current", "booster_pressure", "speed"):
        if key in si:
            si[key] = _despiked(si[key], key, src.rows, where, name[key], notes)
    keep = _powered(t, si["voltage"], notes)
    si = {k: a[keep] for k, a in si.items()}
    return BenchLog(t[keep], si["voltage"], si["current"], si["booster_pressure"], si.get("speed"), str(p), notes)


def _powered(t, v, notes) -> slice:
    """The samples from the switch-on to the switch-off. The model starts the pump at rest at the
    log's first sample and drives it with the logged voltage, switched on there: a lead-in with the
    motor off is left out up to the first powered sample (as a log that starts at the switch-on;
    a sample interval's ramp from 0 V instead would shape the inrush, which rises over L/R), a
    tail after a switch-off from its first (an open relay: the supply side reads
    0 V while the pump coasts with no current, which a motor model driven by 0 V would brake)."""
    av = np.abs(v)
    on = av >= IDLE_VOLTAGE_SHARE * float(np.percentile(av, 90))
    idx = np.flatnonzero(on)
    if not idx.size:
        raise DataError("has no sample with the motor powered (the supply voltage is 0 throughout)")
    start, stop = int(idx[0]), min(int(idx[-1]) + 2, t.size)
    if start > 0:
        notes.append(f"the first {t[start] - t[0]:.4g} s ({start} samples) are the motor off before its "
                     f"switch-on (supply under {100 * IDLE_VOLTAGE_SHARE:.0f} % of its running level): left "
                     f"out, the model starts at rest, switched on, at t = {t[start]:.6g} s")
    if stop < t.size:
        notes.append(f"the last {t[-1] - t[stop - 1]:.4g} s ({t.size - stop} samples) are the motor off "
                     f"after its switch-off: left out")
    if stop - start < MIN_SAMPLES:
        raise DataError(f"has {stop - start} samples with the motor powered (supply above "
                        f"{100 * IDLE_VOLTAGE_SHARE:.0f} % of its running level); at least {MIN_SAMPLES} are needed")
    return slice(start, stop)


def _unit(key, head, option, where):
    """(factor to SI, absolute/gauge mark) of a used column: the option's unit, else the header's,
    else SI; an option that contradicts the header is refused."""
    if option is None:
        return unit_of(key, head, where)
    factor, kind = unit_of(key, option, f"{where} (the {UNIT_OPTION_OF[key]} option)")
    if head is None:
        return factor, kind
    head_factor, head_kind = unit_of(key, head, where)
    if not math.isclose(head_factor, factor) or (kind and head_kind and kind != head_kind):
        raise DataError(f"{where} is annotated [{head}] but the {UNIT_OPTION_OF[key]} option says '{option}' "
                        f"(--{UNIT_OPTION_OF[key].replace('_', '-')}): drop one")
    return factor, kind or head_kind


def _despiked(x, key, rows, where, column, notes):
    """x with its isolated spikes (a logger's glitches: isolated_spikes) replaced by their
    neighbours' mean, said in `notes` with their rows: one such sample in a least-squares fit
    reads as a model that cannot describe the log."""
    idx = isolated_spikes(x, SPIKE_SIGMAS)
    if idx.size == 0:
        return x
    y = x.copy()
    y[idx] = 0.5 * (x[idx - 1] + x[idx + 1])
    size = float(np.max(np.abs(x[idx] - y[idx])) / measured_noise(x))
    shown = ", ".join(row_name(rows, int(i), where, column) for i in idx[:SPIKES_LISTED])
    more = f" and {idx.size - SPIKES_LISTED} more" if idx.size > SPIKES_LISTED else ""
    notes.append(f"{key}: {idx.size} isolated spike(s) replaced by their neighbours' mean ({shown}{more}; "
                 f"up to {size:.3g} noise sigmas off)")
    return y


def _check_signs(si, where, name) -> None:
    """A supply and a motor current that are negative over most of the log are a probe or a clamp
    the wrong way round: the pump's motor draws current from a positive supply."""
    for key, unit, why in (("voltage", "V", "the voltage probe's leads swapped"),
                           ("current", "A", "the current clamp or shunt mounted the wrong way round")):
        med = float(np.median(si[key]))
        if med < 0:
            raise DataError(f"{where} '{name[key]}': the {key} is negative over most of the log (median "
                            f"{med:.4g} {unit}): {why}? The pump's motor draws positive current from a positive "
                            f"supply: reverse the channel's sign")


def _check_time(t, resolution, rows, where, column) -> None:
    dt = np.diff(t)
    bad = np.nonzero(dt <= 0)[0]
    if bad.size:
        b = bad[0]
        raise DataError(f"{row_name(rows, b + 1, where, column)}: time must be strictly increasing "
                        f"({t[b + 1]:.10g} s after {t[b]:.10g} s)")
    gaps = time_gaps(t, resolution)
    if gaps.gaps.size:
        i = int(gaps.gaps[0])
        size = t[i + 1] - t[i]
        raise DataError(f"{row_name(rows, i + 1, where, column)}: a gap of {size:.6g} s in time after {t[i]:.10g} s "
                        f"({size / gaps.step:.3g} sample intervals of {gaps.step:.6g} s); the model is driven "
                        "by the logged voltage sample by sample: cut the log at the gap or fill it")


def _check_pressure(pb, kind, cfg, rows, where, column) -> None:
    """Absolute pressure only: a gauge column (marked, negative, or a pump-down from atmosphere
    that starts far below it) is refused with the fix."""
    atm = cfg.pneumatic.values["gas.atmosphere"] if cfg is not None and cfg.pneumatic else 101325.0
    fix = (f"add the atmospheric pressure ({atm / 1e3:.6g} kPa, or the day's barometer reading) to the column "
           f"and mark it absolute ('{column} [kPa abs]')")
    if kind == "gauge":
        raise DataError(f"{where} '{column}' is marked gauge; the model needs absolute pressure: {fix}")
    neg = np.nonzero(pb <= 0)[0]
    if neg.size:
        head = "is not positive" if kind == "absolute" else "is not positive: a gauge pressure?"
        raise DataError(f"{row_name(rows, neg[0], where, column)}: booster_pressure {pb[neg[0]]:.6g} Pa {head} "
                        f"The model needs absolute pressure: {fix}")
    if kind is None and cfg is not None and cfg.pneumatic is not None:
        start = cfg.pneumatic.booster_start
        first = float(np.median(pb[:START_SAMPLES]))
        if start >= 0.9 * atm and first < GAUGE_START_FRACTION * start:
            unit = next((u for u in UNIT_GUESSES if abs(first * PRESSURE_UNITS[u] / start - 1) < UNIT_MATCH), None)
            if unit is not None:
                shown = UNIT_GUESSES[unit]
                raise DataError(f"{where} '{column}' starts at {pb[0]:.6g} Pa, far below the atmosphere the config's "
                                f"pump-down starts from (booster.pressure {start:.6g} Pa), as if written in {shown}: "
                                f"give the unit in the header ('{column} [{shown} abs]') or with the pressure unit "
                                f"option (--pressure-unit '{shown} abs')")
            raise DataError(f"{where} '{column}' starts at {pb[0]:.6g} Pa, far below the atmosphere the config's "
                            f"pump-down starts from (booster.pressure {start:.6g} Pa): a gauge pressure? {fix}; "
                            "if the log is absolute and starts there, mark it absolute and set booster.pressure")


def _check_voltage(v, cfg, where, column) -> None:
    if cfg is None or cfg.pneumatic is None or not cfg.pneumatic.motor:
        return
    nominal = cfg.pneumatic.values["motor.voltage"]
    med = float(np.median(np.abs(v)))
    if not nominal / VOLTAGE_FACTOR <= med <= nominal * VOLTAGE_FACTOR:
        raise DataError(f"{where} '{column}': median supply voltage {med:.6g} V against motor.voltage "
                        f"{nominal:.6g} V: a unit mistake? give the unit in the header ('{column} [mV]') or "
                        "check the channel")


def write_bench_log(path, log: BenchLog) -> None:
    """The log as CSV with unit headers (pressure in kPa absolute), written atomically."""
    from .io import atomic_path

    cols = {"time [s]": log.time, "voltage [V]": log.voltage, "current [A]": log.current,
            "booster_pressure [kPa abs]": log.booster_pressure / 1e3}
    if log.speed is not None:
        cols["speed [rad/s]"] = log.speed
    with atomic_path(path) as tmp:
        np.savetxt(tmp, np.column_stack(list(cols.values())), delimiter=",", header=",".join(cols),
                   comments="", fmt="%.10g")


def fit_percent(y, yhat) -> float:
    """NRMSE fit in % (spec §10): 100 (1 - |y - yhat| / |y - mean y|); 100 for a perfect fit."""
    y, yhat = np.asarray(y, float), np.asarray(yhat, float)
    spread = float(np.linalg.norm(y - y.mean()))
    return 100.0 * (1.0 - float(np.linalg.norm(y - yhat)) / spread) if spread > 0 else math.nan
