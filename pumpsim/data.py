"""Measured data (spec §6): CSV, MATLAB .mat and NI TDMS files -> a validated `Dataset`.

Columns: time (s, strictly increasing), torque (N m), optional speed (rad/s), optional angle (rad).
Options map other column/channel names and units (torque in N mm, speed in rpm), resample to a
uniform rate and cut out the constant-speed section of a run-up. Bad data is rejected with the row
(or channel) named.
"""
from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import stats

from .errors import DataError

# Units as the factor to SI. Keys are normalised (see `unit_key`): lower case, without spaces and the
# separators * . · between unit symbols, so 'N*mm', 'N.mm', 'N·mm' and 'Nmm' are one unit.
TORQUE_UNITS = {"nm": 1.0, "nmm": 1e-3, "mnm": 1e-3, "ncm": 1e-2}
SPEED_UNITS = {"rad/s": 1.0, "rpm": 2 * math.pi / 60, "1/min": 2 * math.pi / 60, "min^-1": 2 * math.pi / 60,
               "min-1": 2 * math.pi / 60, "u/min": 2 * math.pi / 60, "rev/min": 2 * math.pi / 60,
               "r/min": 2 * math.pi / 60, "rev/s": 2 * math.pi, "hz": 2 * math.pi, "deg/s": math.pi / 180}
TIME_UNITS = {"s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "\u00b5s": 1e-6, "\u03bcs": 1e-6}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180, "\u00b0": math.pi / 180}
UNITS = {"time": TIME_UNITS, "torque": TORQUE_UNITS, "speed": SPEED_UNITS, "angle": ANGLE_UNITS}
UNIT_NAMES = {"time": "s, ms, us", "torque": "N*m, N*mm, mN*m, N*cm",
              "speed": "rad/s, rpm (1/min, U/min), rev/s (Hz), deg/s", "angle": "rad, deg"}
SI_UNIT = {"time": "s", "torque": "N*m", "speed": "rad/s", "angle": "rad"}


def unit_key(unit: str) -> str:
    """'N*mm', 'N.mm', 'N\u00b7mm', ' Nmm ' -> 'nmm'; 'min\u207b\u00b9' -> 'min^-1'."""
    u = unit.strip().lower().replace("\u207b\u00b9", "^-1").replace("\u00b9", "")
    return re.sub(r"[\s*.\u00b7\u22c5\u2219]", "", u)


def unit_factor(quantity: str, unit: str, where: str = "") -> float:
    """Factor from `unit` to SI for `quantity` (time, torque, speed, angle); DataError naming the
    known units otherwise."""
    f = UNITS[quantity].get(unit_key(unit))
    if f is None:
        raise DataError(f"{where}{quantity} unit must be one of {UNIT_NAMES[quantity]}, got '{unit}'")
    return f


_ANNOTATION = re.compile(r"^(?P<name>.*?)\s*(?:\[(?P<u1>[^\]]*)\]|\((?P<u2>[^)]*)\)|/\s*(?P<u3>[^/\s]+))$")


def split_header(text: str):
    """'torque [N*mm]' / 'torque (N*mm)' -> ('torque', 'N*mm'); 'torque' -> ('torque', None)."""
    m = _ANNOTATION.match(text.strip())
    if m and m.group("name"):
        return m.group("name").strip(), next(u for u in (m.group("u1"), m.group("u2"), m.group("u3"))
                                           if u is not None).strip()
    return text.strip(), None


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
        the one the model's drive time is scaled by (identification.problem.drive_kinematics)."""
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
                       self.source, list(self.notes))

    def __repr__(self):
        cols = ", ".join(k for k in ("speed", "angle") if getattr(self, k) is not None)
        span = f"{self.time[-1] - self.time[0]:.4g} s" if self.n else "empty"
        return (f"Dataset({self.name!r}: {self.n} samples, {span}, torque"
                f"{', ' + cols if cols else ''})")


@dataclass
class DataOptions:
    """How to read a data file: column (or channel/variable) names and units. A unit of None takes
    the unit from the column header (`torque [N*mm]`), else SI."""

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


def load_data(path, options: DataOptions | None = None, min_revolutions: float = 1.0,
              nominal_speed: float | None = None) -> Dataset:
    """Read a measurement (spec \u00a76) into a `Dataset` in SI units.

    path: CSV/text (`,`, `;`, tab or blank separated, `;`, tab and blank files may use decimal commas, as may
    double-quoted values in `,` files ("0,5"), UTF-8 with or without BOM, UTF-16, Windows-1252,
    `#` comments, headers with units such as `torque [N*mm]`), MATLAB `.mat` (v4-v7) or NI `.tdms`:
    signals are picked by name, other columns, scalars and text are ignored, and without a time
    signal a sample-rate scalar (`Fs`, `SampleRate`, `dt`, TDMS `wf_increment`) gives the time.
    options: `DataOptions` (column names, units, resampling, steady section).
    nominal_speed [rad/s]: the data must span `min_revolutions` revolutions at it.
    Every rejection is a `DataError` naming the file and the row, column or channel; a gap in time
    (see `time_gaps`) is one unless `options.resample` asks to interpolate across it.

    Example::

        ds = pumpsim.load_data("examples/data/test_rig_measurement.csv")
    """
    p = Path(path)
    try:
        return _load(p, options or DataOptions(), min_revolutions, nominal_speed)
    except DataError as e:
        msg = str(e)
        if not msg.startswith(f"data '{p}'"):
            raise DataError(f"data '{p}': {msg}") from None
        raise


def _load(p: Path, o: DataOptions, min_revolutions, nominal_speed) -> Dataset:
    for q in UNITS:  # option units are checked before the file is read
        if getattr(o, f"{q}_unit", None) is not None:
            unit_factor(q, getattr(o, f"{q}_unit"), "")
    if o.resample is not None and o.resample != "auto":
        _check_rate(o.resample)
    if p.is_dir():
        raise DataError("is a folder, not a data file")
    if not p.exists():
        raise DataError("cannot read data: no such file")
    reader = {".mat": _read_mat, ".tdms": _read_tdms}.get(p.suffix.lower(), _read_csv)
    src = reader(p, lambda names: _pick(o, names))
    where, cols = src.where, src.cols
    name = _pick(o, list(cols))
    notes = []
    if "time" not in name and src.interval(name.get("torque")) is None:
        rate_hint = "" if where == "column" else " and no sample rate (a scalar Fs, SampleRate or dt)"
        raise DataError(f"has no {where} '{o.time}'{rate_hint} (found: {src.found()})")
    if "torque" not in name:
        raise DataError(f"has no {where} '{o.torque}' (found: {src.found()})")
    if "time" in name:
        t = cols[name["time"]]
    else:
        dt, t0, origin = src.interval(name["torque"])
        t = t0 + dt * np.arange(cols[name["torque"]].size)
        notes.append(f"time from {origin} (no {where} '{o.time}')")
    n = t.size
    if n == 0:
        raise DataError("has a header but no data rows")
    used = {k: cols[name[k]] for k in ("torque", "speed", "angle") if k in name}
    first = name.get("time", name["torque"])
    for key, arr in used.items():
        if arr.size != n:
            raise DataError(f"{where} '{name[key]}' has {arr.size} samples, {where} '{first}' has {n}")
    if "time" in name:
        used = {"time": t, **used}
    row_of = src.rows
    for key, arr in used.items():
        bad = np.nonzero(~np.isfinite(arr))[0]
        if bad.size:
            raise DataError(f"{_where(row_of, bad[0], where, key)}: {key} is not a finite number")
    scale = {key: _unit_of(key, name[key], src.units, getattr(o, f"{key}_unit"), where) for key in used}
    if "time" in name:
        resolution = _resolution(t) * scale["time"]
        t = t * scale["time"] if scale["time"] != 1.0 else t
    else:
        resolution = 0.0
    dt = np.diff(t)
    bad = np.nonzero(dt <= 0)[0]
    if bad.size:
        b = bad[0]
        # as many digits as tell the two apart (absolute time stamps: 1.7e9 s + fractions)
        digits = max(6, min(17, int(math.ceil(math.log10(max(abs(t[b]), 1e-300) / max(abs(dt[b]), 1e-300)))) + 2))
        again = (f" ({int(np.sum(dt == 0))} repeated times: written with too few digits for the sample "
                 "rate?)" if dt[b] == 0 else "")
        raise DataError(f"{_where(row_of, b + 1, where, 'time')}: time must be strictly increasing "
                        f"({t[b + 1]:.{digits}g} s after {t[b]:.{digits}g} s){again}")
    si = {k: (used[k] * scale[k] if scale[k] != 1.0 else used[k]) if k in used else None
          for k in ("torque", "speed", "angle")}
    ds = Dataset(t, si["torque"], si["speed"], si["angle"], source=str(p), notes=notes)
    lo = 0
    if o.steady:
        ds = steady_section(ds, o.steady_tolerance)
        lo = int(np.searchsorted(t, ds.time[0]))
    gaps = time_gaps(ds.time, resolution)
    if gaps.gaps.size and o.resample is None:
        raise DataError(gaps.message(lambda i: _where(row_of, lo + i, where, "time")))
    if gaps.jitter:
        ds.notes.append(gaps.jitter)
    if o.resample is not None:
        ds = resample(ds, 1.0 / gaps.step if o.resample == "auto" else o.resample, gaps)
    speed = nominal_speed or (float(np.mean(ds.speed)) if ds.speed is not None else None)
    if ds.n < 10:
        raise DataError(f"has {ds.n} samples; at least 10 are needed")
    if speed and speed > 0:
        span = ds.time[-1] - ds.time[0]
        need = min_revolutions * 2 * math.pi / speed
        if span < need * (1 - 1e-9):
            raise DataError(f"spans {span:.4g} s ({ds.n} samples): too few samples for "
                            f"one revolution ({need:.4g} s at {speed:.4g} rad/s)")
    return ds


def _pick(o: DataOptions, names) -> dict:
    """{quantity: the file's column} for the options' names that the file has."""
    found = {k: _column(getattr(o, k), names) for k in ("time", "torque", "speed", "angle")}
    return {k: v for k, v in found.items() if v and v in names}


def _column(wanted, cols):
    """The file's column for an option's name: exact, else without a unit annotation
    ('torque [N*mm]' -> 'torque'), else the one column equal to it ignoring case ('Torque')."""
    if not wanted or wanted in cols:
        return wanted
    base = split_header(wanted)[0]
    if base in cols:
        return base
    same = [c for c in cols if c.lower() == base.lower()]
    return same[0] if len(same) == 1 else wanted


def _unit_of(key, column, header_units, option_unit, where):
    """Factor to SI of a used column: the option's unit, else the header's, else SI; an option
    that contradicts the header is refused."""
    head = header_units.get(column)
    if option_unit is not None:
        f = unit_factor(key, option_unit)
        if head is not None and not math.isclose(f, unit_factor(key, head, f"{where} '{column}': ")):
            raise DataError(f"{where} '{column}' is annotated [{head}] but --{key}-unit says "
                            f"'{option_unit}'; drop one")
        return f
    if head is not None:
        return unit_factor(key, head, f"{where} '{column} [{head}]': ")
    return 1.0


def _where(row_of, index, where, key):
    if row_of is not None:
        return f"row {row_of[index]}"
    return f"sample {index} of {where} '{key}'"


# --- Sampling: gaps, jitter and quantised time stamps -----------------------------------------------

# A step longer than 1.5 regular steps is a gap: midway between one step (T) and two (one sample
# missing), so jitter up to +-T/2 passes and a single missing sample is caught. Time stamps written
# with resolution q put a regular step anywhere in (T - q, T + q) and a one-sample gap in
# (2T - q, 2T + q): the limit is T + max(T/2, q), which keeps every record whose time stamps
# increase (q < T) and still catches each missing sample that q leaves detectable (q <= T/2).
GAP_STEPS = 1.5
# a regular step is one below 2.5 median steps (a gap of 1.5 samples or more is surely not one): the
# mean over them is the sample interval, also when quantised steps alternate (3e-4, 4e-4 s at 3 kHz)
REGULAR_STEPS = 2.5
JITTER_NOTE = 0.01  # steps that vary by more than 1 % of the interval are named in a note


def _resolution(t) -> float:
    """The decimal resolution the time stamps were written with (1e-4 for '0.0123'), in the
    column's unit, or 0.0 when they are not on a decimal grid (binary time channels)."""
    t = np.asarray(t, dtype=float)

    def on_grid(values, d):
        x = values * 10.0 ** d
        return bool(np.all(np.abs(x - np.round(x)) <= 1e-6 + 1e-14 * np.abs(x)))

    probe = t[:: max(1, t.size // 10000)]
    for d in range(0, 13):  # a probe first, then all in blocks (no temporaries the size of the column)
        if on_grid(probe, d) and all(on_grid(t[i:i + 65536], d) for i in range(0, t.size, 65536)):
            return 10.0 ** -d
    return 0.0


@dataclass
class TimeGaps:
    """The sampling of a time column: the regular step (s), the steps longer than `limit` (their
    indices i: a gap between samples i and i + 1) and a note on jitter ('' when steady)."""

    time: np.ndarray
    step: float
    limit: float
    gaps: np.ndarray
    jitter: str

    def message(self, row) -> str:
        """The refusal: the first gap by row (row(i) names sample i), time and size, and the fix."""
        i = int(self.gaps[0])
        size = self.time[i + 1] - self.time[i]
        more = f" ({self.gaps.size - 1} more after it)" if self.gaps.size > 1 else ""
        return (f"{row(i + 1)}: a gap of {size:.6g} s in time after {self.time[i]:.10g} s, "
                f"{size / self.step:.3g} times the sample interval {self.step:.6g} s (about "
                f"{max(1, round(size / self.step) - 1)} samples missing){more}; cut the record at the gap, or "
                "pass --resample HZ (or --resample auto) to interpolate onto a uniform grid across it")

    def bridged(self) -> str:
        if not self.gaps.size:
            return ""
        sizes = self.time[self.gaps + 1] - self.time[self.gaps]
        return (f" across {self.gaps.size} gap{'s' if self.gaps.size > 1 else ''} in time (the longest "
                f"{sizes.max():.6g} s after {self.time[self.gaps[np.argmax(sizes)]]:.10g} s)")


def time_gaps(time, resolution: float = 0.0) -> TimeGaps:
    """Gaps and jitter of a strictly increasing time column (see GAP_STEPS); resolution [s]: the
    time stamps' (see `_resolution`)."""
    dt = np.diff(time)
    if dt.size == 0:
        return TimeGaps(time, 1.0, math.inf, np.zeros(0, int), "")
    regular = dt[dt <= REGULAR_STEPS * np.median(dt)]
    step = float(np.mean(regular))
    limit = step + max((GAP_STEPS - 1) * step, resolution)
    jitter = ""
    lo, hi = float(regular.min()), float(regular.max())
    if hi - lo > JITTER_NOTE * step:
        quantised = 0 < hi - lo <= resolution * (1 + 1e-6)
        cause = f"time stamps written to {resolution:.3g} s" if quantised else "jitter"
        jitter = (f"time steps vary between {lo:.6g} and {hi:.6g} s about the interval {step:.6g} s "
                  f"({cause}); accepted as measured")
    return TimeGaps(time, step, limit, np.flatnonzero(dt > limit), jitter)


def _read_bytes(p: Path) -> bytes:
    try:
        return p.read_bytes()
    except OSError as e:
        raise DataError(f"cannot read: {e.strerror}") from None


def _decode(p: Path) -> str:
    """Text of a data or config file: UTF-8 (BOM or not), UTF-16 with BOM (spreadsheet 'Unicode
    text'), else Windows-1252; binary files are refused."""
    return decode_text(_read_bytes(p), DataError)


_UTF8_BOM = b"\xef\xbb\xbf"
# a character of two to four bytes in UTF-8: cp1252 text almost never holds one (it would read 'Ã¼')
_UTF8_MULTIBYTE = re.compile(rb"[\xc2-\xdf][\x80-\xbf]|[\xe0-\xef][\x80-\xbf]{2}|[\xf0-\xf4][\x80-\xbf]{3}")


def _refuse_binary(raw: bytes, error) -> None:
    if raw.startswith(b"PK\x03\x04"):
        raise error("is a ZIP archive (an Excel .xlsx workbook?), not text; save it as CSV")
    if b"\x00" in raw[:4096]:
        raise error("is a binary file, not text (UTF-8 or UTF-16 with BOM)")


def decode_text(raw: bytes, error=DataError) -> str:
    """UTF-16 with BOM, else UTF-8 (a BOM stripped), else Windows-1252 (also with a UTF-8 BOM in
    front, as some exporters write). Bytes that fit neither are refused naming the byte, its offset
    and line, never decoded to look-alike characters."""
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            return raw.decode("utf-16")
        except UnicodeDecodeError:
            raise error("is not readable UTF-16 text") from None
    _refuse_binary(raw, error)
    skip = len(_UTF8_BOM) if raw.startswith(_UTF8_BOM) else 0
    body = raw[skip:]
    try:
        return body.decode("utf-8")
    except UnicodeDecodeError as e:
        utf8_bad = e.start

    def at(i):
        line = body.count(b"\n", 0, i) + 1
        return f"byte 0x{body[i]:02x} at byte offset {i + skip} (line {line})"

    if _UTF8_MULTIBYTE.search(body):
        raise error(f"is UTF-8 text with an invalid {at(utf8_bad)}: the file is damaged or mixes "
                    "encodings; save it again as UTF-8")
    try:
        return body.decode("cp1252")
    except UnicodeDecodeError as e:
        raise error(f"is neither UTF-8 ({at(utf8_bad)} is not UTF-8) nor Windows-1252 ({at(e.start)} "
                    "is undefined there); save it as UTF-8") from None


@dataclass
class _Source:
    """What a reader found: numeric signals by name, header or channel units, the row number of
    each sample (CSV) and what it left aside, for messages."""

    where: str  # 'column', 'variable' or 'channel'
    cols: dict
    units: dict = field(default_factory=dict)
    rows: object = None
    ignored: dict = field(default_factory=dict)  # name -> why it is not a signal ('scalar', 'text', ...)
    scalars: dict = field(default_factory=dict)  # name -> value, for a sample rate
    waveforms: dict = field(default_factory=dict)  # channel -> (dt, t0): TDMS waveform properties
    names: list | None = None  # every column of the file (a CSV reader keeps only those used)

    def found(self) -> str:
        names = sorted(self.names or self.cols) + [f"{k} ({v})" for k, v in sorted(self.ignored.items())]
        return ", ".join(names) or "none"

    def interval(self, channel):
        """(dt [s], t0 [s], where it came from) of a channel without a time column, or None."""
        if channel in self.waveforms:
            dt, t0 = self.waveforms[channel]
            return dt, t0, f"the waveform properties of {self.where} '{channel}' (wf_increment = {dt:.6g} s)"
        rates = {}
        for k, v in self.scalars.items():
            key = re.sub(r"[\s_\-]", "", k.rsplit(".", 1)[-1].rsplit("/", 1)[-1].lower())
            if key in RATE_NAMES and v > 0:
                rates[k] = (1.0 / v, f"{k} = {v:.6g} Hz")
            elif key in INTERVAL_NAMES and v > 0:
                rates[k] = (float(v), f"{k} = {v:.6g} s")
        if not rates:
            return None
        values = list(rates.values())
        if any(not math.isclose(dt, values[0][0], rel_tol=1e-9) for dt, _ in values):
            raise DataError(f"has no {self.where} time and sample rates that disagree: "
                            f"{', '.join(w for _, w in values)}; add a time {self.where} or keep one rate")
        return values[0][0], 0.0, "the sample rate " + values[0][1]


# metadata scalars that give the sample rate [Hz] or interval [s], compared lower case without
# blanks, '_' and '-'
RATE_NAMES = {"fs", "samplerate", "samplingrate", "samplefrequency", "samplingfrequency", "rate", "srate"}
INTERVAL_NAMES = {"dt", "ts", "sampleinterval", "samplinginterval", "sampletime", "samplingtime",
                  "wfincrement", "increment"}


def _header(s: str, i: int):
    """The separator and [(name, unit)] of header line `s` (line number i)."""
    sep = next((c for c in (";", "\t", ",") if c in s), " " if _BLANKS.search(s) else ",")
    fields = [h.strip().strip('"').strip() for h in _fields(s, sep)]
    if fields and fields[-1] == "" and len(fields) > 1:  # trailing separator
        fields = fields[:-1]
    header = [split_header(h) for h in fields]
    names = [h for h, _ in header]
    if any(not h for h in names):
        raise DataError(f"row {i}: empty column name in the header")
    if len(set(names)) != len(names):
        raise DataError(f"row {i}: duplicate column names in the header")
    return sep, header


_HEAD = 1 << 16  # the header is looked for in the first 64 KB (a longer preamble: the whole file)
_BLOCK = 1 << 20  # bytes per read when scanning the data and per pyarrow block


def _header_end(raw: bytes):
    """(line number, end offset) of the header line, the first neither blank nor a comment; None
    when `raw` has none."""
    pos, line = (len(_UTF8_BOM) if raw.startswith(_UTF8_BOM) else 0), 0
    while pos <= len(raw):
        nl = raw.find(b"\n", pos)
        end = len(raw) if nl < 0 else nl
        line += 1
        s = raw[pos:end].strip()
        if s and not s.startswith(b"#"):
            return line, end
        if nl < 0:
            return None
        pos = end + 1
    return None


class _Body:
    """The data rows of a text file after its header: from the file itself (no copy of a large
    file in memory) or from bytes already read (UTF-16 re-encoded, old Mac line ends)."""

    def __init__(self, p: Path, raw: bytes | None, start: int):
        self.p, self.raw, self.start = p, raw, start

    def chunks(self):
        if self.raw is not None:
            yield self.raw[self.start:]
            return
        with open(self.p, "rb") as f:
            f.seek(self.start)
            while block := f.read(_BLOCK):
                yield block

    def stream(self):
        import pyarrow as pa

        if self.raw is not None:
            return pa.BufferReader(pa.py_buffer(self.raw)[self.start:])
        f = pa.OSFile(str(self.p))
        f.seek(self.start)
        return f

    def size(self) -> int:
        return len(self.raw) - self.start if self.raw is not None else max(0, self.p.stat().st_size - self.start)

    def has(self, *needles) -> set:
        return {n for n in needles if any(n in c for c in self.chunks())}


def _read_csv(p: Path, pick, fast: bool = True) -> _Source:
    """A text file's columns that `pick(names)` uses: streamed through pyarrow's CSV reader where
    the dialect allows (the common case, and the one a 10^6-row record needs), else line by line,
    which also gives every refusal its row."""
    try:
        with open(p, "rb") as f:
            head = f.read(_HEAD)
    except OSError as e:
        raise DataError(f"cannot read: {e.strerror}") from None
    raw = None
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        raw = decode_text(_read_bytes(p)).encode("utf-8")
    else:
        _refuse_binary(head, DataError)
    if raw is None and b"\n" not in head and b"\r" in head:  # old Mac line ends
        raw = _read_bytes(p).replace(b"\r", b"\n")
    found = _header_end(raw if raw is not None else head)
    if found is None and raw is None and len(head) == _HEAD:
        raw = _read_bytes(p)
        found = _header_end(raw)
    if found is None:
        raise DataError("has no header line")
    line, end = found
    text = raw if raw is not None else head
    sep, header = _header(decode_text(text[:end]).splitlines()[-1].strip(), line)
    names = [h for h, _ in header]
    keep = [j for j, h in enumerate(names) if h in set(pick(names).values())]
    body = _Body(p, raw, end + 1)
    cols = _arrow_columns(body, sep, names, keep) if fast and keep else None
    if cols is not None:
        rows = _RowNumbers(body, line + 1)
    else:
        cols, rows = _python_columns(_decode(p) if raw is None else raw.decode("utf-8"), header, keep)
    return _Source("column", cols, {h: u for h, u in header if u is not None}, rows, names=names)


class _RowNumbers:
    """The line number (as an editor shows it) of each data row read by pyarrow, counted only when a
    message needs one: the data holds no comments there, so the rows are its non-blank lines."""

    def __init__(self, body: _Body, first_line: int):
        self._body, self._first, self._rows = body, first_line, None

    def __getitem__(self, index):
        if self._rows is None:
            lines = b"".join(self._body.chunks()).splitlines()
            self._rows = np.array([self._first + k for k, s in enumerate(lines) if s.strip()])
        return int(self._rows[index])


def _arrow_columns(body: _Body, sep: str, names, keep):
    """{name: float array} of columns `keep` read by pyarrow block by block, or None where its
    dialect is not the file's (blank-separated, comments among the rows) or anything is refused:
    the line-by-line reader then finds and names it."""
    import pyarrow as pa
    from pyarrow import csv as pacsv

    marks = body.has(b"#", b'"', b",")
    if sep == " " or b"#" in marks:
        return None
    sample = next(body.chunks(), b"")[:_HEAD]
    first = next((s.strip() for s in sample.splitlines() if s.strip()), b"")
    # the rows the file holds, from the length of its first lines, with 10 % to spare
    rows = int(1.1 * body.size() / max(1.0, len(sample) / max(1, sample.count(b"\n")))) + 16
    cols = list(names) + (["\0trailing"] if first.endswith(sep.encode()) else [])
    if b'"' in marks:
        points = [".", ","]  # quoted values of a ',' file may use decimal commas ("0,5")
    else:
        points = ["," if sep != "," and b"," in marks else "."]
    types = {n: pa.float64() for n in names}
    types.update({c: pa.string() for c in cols[len(names):]})
    include = [names[j] for j in keep] + cols[len(names):]
    for point in points:
        out = _Columns(len(keep), rows)
        try:
            with pacsv.open_csv(
                    body.stream(), read_options=pacsv.ReadOptions(column_names=cols, block_size=_BLOCK),
                    parse_options=pacsv.ParseOptions(delimiter=sep),
                    convert_options=pacsv.ConvertOptions(column_types=types, include_columns=include,
                                                         decimal_point=point, null_values=[],
                                                         strings_can_be_null=False,
                                                         quoted_strings_can_be_null=False)) as reader:
                for batch in reader:
                    # a trailing separator: its column must be empty on every row
                    if len(cols) > len(names) and any(len(s) for s in batch.column(len(keep)).to_pylist()):
                        return None
                    out.append([_float_array(batch.column(k)) for k in range(len(keep))])
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            continue
        if out.n == 0:
            return None
        return {names[j]: a for j, a in zip(keep, out.arrays())}
    return None


class _Columns:
    """Float columns filled batch by batch into arrays sized for `rows` (grown by half when short),
    so that the kept samples are held once and no batch outlives its copy."""

    def __init__(self, count, rows):
        self.n, self.cols = 0, [np.empty(rows) for _ in range(count)]

    def append(self, arrays):
        m = len(arrays[0])
        if self.n + m > self.cols[0].size:
            grown = max(self.n + m, int(1.5 * self.cols[0].size))
            self.cols = [np.concatenate([c[:self.n], np.empty(grown - self.n)]) for c in self.cols]
        for c, a in zip(self.cols, arrays):
            c[self.n:self.n + m] = a
        self.n += m

    def arrays(self):
        return [c[:self.n] for c in self.cols]


def _float_array(array) -> np.ndarray:
    """A float64 array without nulls as a NumPy view of its data buffer (to_numpy would import
    pandas, 0.7 s)."""
    if array.null_count:
        raise ValueError("nulls in a float column")
    return np.frombuffer(array.buffers()[1], dtype=np.float64, count=len(array), offset=8 * array.offset)


def _python_columns(text: str, header, keep):
    """{name: float array} of the columns `keep`, line by line, and the line number of each row."""
    sep, width, values, line_no = None, len(header), [], []
    header_seen = False
    for i, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        if not header_seen:
            header_seen = True
            sep = _header(s, i)[0]
            continue
        parts = [x.strip().strip('"') for x in _fields(s, sep)]
        if len(parts) == width + 1 and parts[-1] == "":
            parts = parts[:-1]
        if len(parts) != width:
            raise DataError(f"row {i}: {len(parts)} values, the header has {width} columns")
        # a comma inside a value is a decimal comma: with ';' or tab separators, or quoted ("0,5")
        parts = [parts[j].replace(",", ".") for j in keep]
        try:
            values.append([float(x) for x in parts])
        except ValueError:
            bad = next(x for x in parts if not _is_float(x))
            raise DataError(f"row {i}: '{bad.strip()}' is not a number") from None
        line_no.append(i)
    arr = np.array(values, dtype=float).reshape(len(values), len(keep))
    return {header[j][0]: arr[:, k].copy() for k, j in enumerate(keep)}, np.array(line_no)


# blanks between columns of a blank-separated file; not those before or inside a unit ('torque [N m]')
_BLANKS = re.compile(r"\s+(?![\[(])(?![^\[(]*[\])])")


def _fields(line, sep):
    """One line split at sep (' ': any run of blanks); a double-quoted field may hold the
    separator (spreadsheet exports)."""
    if '"' not in line:
        return _BLANKS.split(line) if sep == " " else line.split(sep)
    return next(csv.reader([line], delimiter=sep, skipinitialspace=True))


def _is_float(x):
    try:
        float(x)
        return True
    except ValueError:
        return False


def _sort_value(src: _Source, name: str, value) -> None:
    """File a MATLAB variable or TDMS channel: a numeric vector is a signal (its name's unit
    annotation, 'Torque [N*mm]', split off as in a CSV header), a numeric scalar metadata (maybe
    the sample rate); anything else is named as ignored."""
    if isinstance(value, (str, bytes)):
        src.ignored[name] = "text"
        return
    arr = np.asarray(value)
    if arr.dtype.kind not in "fiub":
        src.ignored[name] = "text" if arr.dtype.kind in "USO" else f"{arr.dtype.kind} data"
        return
    shape = [s for s in arr.shape if s != 1]
    if len(shape) > 1:
        src.ignored[name] = f"matrix {'x'.join(str(s) for s in arr.shape)}"
    elif arr.size == 1:
        src.scalars[name] = float(arr.ravel()[0])
        src.ignored[name] = f"scalar {float(arr.ravel()[0]):.6g}"
    elif arr.size == 0:
        src.ignored[name] = "empty"
    else:
        base, unit = split_header(name)
        src.cols[base] = arr.astype(float).ravel()
        if unit:
            src.units[base] = unit


MAT73 = b"MATLAB 7.3 MAT-file"


def _read_mat(p: Path, pick=None) -> _Source:
    """A MATLAB v4-v7 file: numeric vectors are signals, also the fields of a struct (as
    'struct.field' and, where no other has that name, 'field'); scalars, text, matrices and cells
    are left aside (a scalar 'Fs', 'SampleRate' or 'dt' gives the time when no variable does)."""
    from scipy.io import loadmat

    with open(p, "rb") as f:
        if f.read(len(MAT73)) == MAT73:
            raise DataError("is a MATLAB v7.3 (HDF5) file, which pumpsim cannot read; save it in "
                            "MATLAB with save(FILE, ..., '-v7') or export it as CSV")
    try:
        m = loadmat(str(p), simplify_cells=True)
    except Exception as e:  # scipy raises several types for corrupt files
        raise DataError(f"cannot read MATLAB file '{p.name}': {e}") from None
    src = _Source("variable", {})
    fields: dict = {}
    for k, v in m.items():
        if k.startswith("__"):
            continue
        if isinstance(v, dict):
            for fk, fv in v.items():
                if isinstance(fv, dict):
                    src.ignored[f"{k}.{fk}"] = "struct"
                    continue
                _sort_value(src, f"{k}.{fk}", fv)
                fields.setdefault(split_header(fk)[0], []).append(f"{k}.{fk}")
        else:
            _sort_value(src, k, v)
    for short, full in fields.items():  # a field's own name when it is the only one of that name
        if len(full) == 1 and short not in src.cols and full[0] in src.cols:
            src.cols[short] = src.cols[full[0]]
            if full[0] in src.units:
                src.units[short] = src.units[full[0]]
    return src


def _read_tdms(p: Path, pick=None) -> _Source:
    """An NI TDMS file: numeric channels by name (also 'group/name'; a bare name in several groups
    only with its group), waveform properties (wf_increment, wf_start_offset) and numeric file or
    group properties as sample-rate candidates."""
    from nptdms import TdmsFile

    try:
        f = TdmsFile.read(str(p))
    except Exception as e:  # npTDMS raises several types for corrupt files
        raise DataError(f"cannot read TDMS file '{p.name}': {e}") from None
    src = _Source("channel", {})
    for owner, prefix in [(f, "")] + [(g, f"{g.name}/") for g in f.groups()]:
        for k, v in owner.properties.items():
            if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool):
                src.scalars[f"{prefix}{k}"] = float(v)
    groups_of: dict = {}
    for group in f.groups():
        for ch in group.channels():
            full = f"{group.name}/{ch.name}"
            try:
                data = np.asarray(ch[:], dtype=float).ravel()
            except (TypeError, ValueError):
                src.ignored[full] = "text or time stamps"
                continue
            base, head_unit = split_header(ch.name)
            unit = str(ch.properties.get("unit_string", "") or "").strip() or head_unit
            if data.size < 2:
                src.ignored[full] = "scalar" if data.size else "empty"
                continue
            src.cols[f"{group.name}/{base}"] = data
            groups_of.setdefault(base, []).append(group.name)
            if unit:
                src.units[f"{group.name}/{base}"] = unit
            inc = ch.properties.get("wf_increment")
            if inc is not None and float(inc) > 0:
                src.waveforms[f"{group.name}/{base}"] = (float(inc), float(ch.properties.get("wf_start_offset", 0.0)))
    for base, groups in groups_of.items():
        if len(groups) == 1:
            g = groups[0]
            for d in (src.cols, src.units, src.waveforms):
                if f"{g}/{base}" in d:
                    d[base] = d[f"{g}/{base}"]
    return src


def _check_rate(rate) -> None:
    if not (isinstance(rate, (int, float)) and rate > 0 and math.isfinite(rate)):
        raise DataError(f"--resample must be a rate > 0 [Hz] or 'auto', got {rate}")


def resample(ds: Dataset, rate: float, gaps: TimeGaps | None = None) -> Dataset:
    """`ds` linearly interpolated onto a uniform grid at `rate` [Hz] from its first sample; the note
    says so, and names the gaps bridged (`gaps`: from `time_gaps`)."""
    _check_rate(rate)
    if (ds.time[-1] - ds.time[0]) * rate > 5_000_000:
        raise DataError(f"--resample {rate:g} Hz over {ds.time[-1] - ds.time[0]:.4g} s gives more than "
                        "5,000,000 samples")
    t = np.arange(ds.time[0], ds.time[-1] + 0.5 / rate, 1.0 / rate)
    t = t[t <= ds.time[-1] + 1e-6 / rate]  # the last sample also when rounding puts it a hair beyond
    f = lambda a: None if a is None else np.interp(t, ds.time, a)  # noqa: E731
    note = f"resampled to {rate:.6g} Hz (linear interpolation){gaps.bridged() if gaps else ''}"
    out = Dataset(t, f(ds.torque), f(ds.speed), f(np.unwrap(ds.angle)) if ds.angle is not None else None,
                  ds.source, ds.notes + [note])
    return out


def steady_section(ds: Dataset, tolerance: float = 0.01) -> Dataset:
    """The longest run of samples whose speed stays within tolerance of that run's median speed
    (the report fitted only the constant-speed part of a run-up)."""
    if ds.speed is None:
        raise DataError("the constant-speed section needs a speed column (or drop the steady option)")
    w = ds.speed
    ref = np.median(w[w > 0.5 * w.max()])
    inside = np.abs(w - ref) <= tolerance * abs(ref)
    best, start, best_span = None, None, (0, 0)
    for i, ok in enumerate(np.append(inside, False)):
        if ok and start is None:
            start = i
        elif not ok and start is not None:
            if i - start > best_span[1] - best_span[0]:
                best_span = (start, i)
            start = None
    lo, hi = best_span
    if hi - lo < 10:
        raise DataError(f"no constant-speed section: fewer than 10 samples stay within "
                        f"{tolerance:.1%} of {ref:.4g} rad/s")
    best = ds.window(lo, hi)
    best.notes.append(f"constant-speed section t = {ds.time[lo]:.6g} .. {ds.time[hi - 1]:.6g} s "
                      f"(speed within {tolerance:.1%} of {ref:.5g} rad/s)")
    return best


# --- The measured speed's slow variation (a drifting motor) ---------------------------------------

TREND_MAX_DEGREE = 20  # Legendre degrees tried for the speed column's trend (BIC chooses; a run-up needs ~18)
TREND_ALPHA = 1e-3  # F-test level at which the trend counts as significant against the column's noise
TREND_REVOLUTIONS_PER_DEGREE = 2.0  # a degree per two revolutions at most: the trend stays below order 1


@dataclass(frozen=True)
class SpeedTrend:
    """The slow part of a measured speed column: omega_s(t) = sum c_j P_j(x), x = 2 t / span - 1
    (Legendre polynomials, t from the first sample), fitted by least squares. `mean` is the mean of
    the column (= the mean of omega_s over the samples: the fit has a constant term); `degree` was
    chosen by BIC and `p_value` is the F-test of that fit against a constant.

    Assumptions: the column is the shaft speed plus noise that is white and much faster than the
    trend, and any shaft-synchronous speed ripple (orders >= 1) is left to the model's ripple --
    a polynomial of at most one degree per two revolutions cannot follow it."""

    coef: np.ndarray
    span: float
    mean: float
    degree: int
    p_value: float

    def _x(self, t):
        return 2.0 * np.asarray(t, dtype=float) / self.span - 1.0

    def speed(self, t) -> np.ndarray:
        return np.polynomial.legendre.legval(self._x(t), self.coef)

    def acceleration(self, t) -> np.ndarray:
        return np.polynomial.legendre.legval(self._x(t), np.polynomial.legendre.legder(self.coef)) * 2 / self.span

    def warped_time(self, t) -> np.ndarray:
        """tau(t) = integral_0^t omega_s / mean dt': the time at which a rotor at the constant mean
        speed reaches the drifting rotor's angle (tau = t for a constant speed)."""
        integral = np.polynomial.legendre.legint(self.coef, lbnd=-1.0) * self.span / 2
        return np.polynomial.legendre.legval(self._x(t), integral) / self.mean

    def change(self) -> float:
        """Largest minus smallest trend speed over the record, relative to the mean."""
        w = self.speed(np.linspace(0.0, self.span, 201))
        return float((w.max() - w.min()) / abs(self.mean))


def speed_trend(time, speed) -> SpeedTrend | None:
    """The speed column's slow trend if it is significant against the column's own noise (F-test
    at TREND_ALPHA of the BIC-chosen Legendre fit against a constant), else None: the column is
    constant within its noise and its mean is the speed."""
    if speed is None or len(time) < 20:
        return None
    t = np.asarray(time, dtype=float) - time[0]
    w = np.asarray(speed, dtype=float)
    span, mean = float(t[-1]), float(np.mean(w))
    revolutions = abs(mean) * span / (2 * math.pi)
    top = int(min(TREND_MAX_DEGREE, revolutions / TREND_REVOLUTIONS_PER_DEGREE, (t.size - 2) // 10))
    if top < 1 or span <= 0 or mean == 0 or np.ptp(w) <= 1e-12 * abs(mean):  # a constant column (rounding aside)
        return None
    V = np.polynomial.legendre.legvander(2 * t / span - 1, top)
    fits = [np.linalg.lstsq(V[:, :d + 1], w, rcond=None)[0] for d in range(top + 1)]
    rss = np.array([float(np.sum((w - V[:, :d + 1] @ c) ** 2)) for d, c in enumerate(fits)])
    n = t.size
    bic = n * np.log(np.maximum(rss, 1e-300) / n) + np.arange(1, top + 2) * math.log(n)
    d = int(np.argmin(bic))
    if d == 0:
        return None
    f = ((rss[0] - rss[d]) / d) / (max(rss[d], 1e-300) / (n - d - 1))
    p = float(stats.f.sf(f, d, n - d - 1))
    if p >= TREND_ALPHA:
        return None
    return SpeedTrend(fits[d], span, mean, d, p)
