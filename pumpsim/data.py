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
    resample: float | None = None  # Hz
    steady: bool = False  # keep only the constant-speed section
    steady_tolerance: float = 0.01  # relative speed band of the constant-speed section


def load_data(path, options: DataOptions | None = None, min_revolutions: float = 1.0,
              nominal_speed: float | None = None) -> Dataset:
    """Read a measurement (spec \u00a76) into a `Dataset` in SI units.

    path: CSV/text (`,`, `;`, tab or blank separated, `;`, tab and blank files may use decimal commas, as may
    double-quoted values in `,` files ("0,5"), UTF-8 with or
    without BOM, UTF-16, `#` comments, headers with units such as `torque [N*mm]`), MATLAB `.mat`
    or NI `.tdms`. options: `DataOptions` (column names, units, resampling, steady section).
    nominal_speed [rad/s]: the data must span `min_revolutions` revolutions at it.
    Every rejection is a `DataError` naming the file and the row, column or channel.

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
    if p.is_dir():
        raise DataError("is a folder, not a data file")
    if not p.exists():
        raise DataError("cannot read data: no such file")
    suffix = p.suffix.lower()
    if suffix == ".mat":
        cols, where = _read_mat(p), "variable"
    elif suffix == ".tdms":
        cols, where = _read_tdms(p), "channel"
    else:
        cols, where = _read_csv(p), "column"
    row_of = cols.pop("__rows__", None)
    header_units = cols.pop("__units__", {})
    name = {k: _column(getattr(o, k), cols) for k in ("time", "torque", "speed", "angle")}
    for key in ("time", "torque"):
        if name[key] not in cols:
            raise DataError(f"has no {where} '{getattr(o, key)}' (found: {', '.join(sorted(cols)) or 'none'})")
    t = cols[name["time"]]
    n = t.size
    if n == 0:
        raise DataError("has a header but no data rows")
    for col, arr in cols.items():
        if arr.size != n:
            raise DataError(f"{where} '{col}' has {arr.size} samples, {where} '{name['time']}' has {n}")
    used = {k: cols[name[k]] for k in ("time", "torque", "speed", "angle") if name[k] in cols}
    for key, arr in used.items():
        bad = np.nonzero(~np.isfinite(arr))[0]
        if bad.size:
            raise DataError(f"{_where(row_of, bad[0], where, key)}: {key} is not a finite number")
    scale = {key: _unit_of(key, name[key], header_units, getattr(o, f"{key}_unit"), where)
             for key in used}
    t = t * scale["time"]
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
    si = {k: (used[k] * scale[k] if k in used else None) for k in ("torque", "speed", "angle")}
    ds = Dataset(t.astype(float), si["torque"], si["speed"], si["angle"], source=str(p))
    if o.steady:
        ds = steady_section(ds, o.steady_tolerance)
    if o.resample is not None:
        ds = resample(ds, o.resample)
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


def _decode(p: Path) -> str:
    """Text of a data or config file: UTF-8 (BOM or not), UTF-16 with BOM (spreadsheet 'Unicode
    text'), else Windows-1252; binary files are refused."""
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise DataError(f"cannot read: {e.strerror}") from None
    return decode_text(raw, DataError)


def decode_text(raw: bytes, error=DataError) -> str:
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            return raw.decode("utf-16")
        except UnicodeDecodeError:
            raise error("is not readable UTF-16 text") from None
    if raw.startswith(b"PK\x03\x04"):
        raise error("is a ZIP archive (an Excel .xlsx workbook?), not text; save it as CSV")
    if b"\x00" in raw[:4096]:
        raise error("is a binary file, not text (UTF-8 or UTF-16 with BOM)")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("cp1252", errors="replace")


def _read_csv(p: Path) -> dict:
    lines = _decode(p).splitlines()
    header, rows, line_no, sep = None, [], [], ","
    for i, line in enumerate(lines, start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        if header is None:
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
            continue
        parts = [x.strip().strip('"') for x in _fields(s, sep)]
        if len(parts) == len(header) + 1 and parts[-1] == "":
            parts = parts[:-1]
        if len(parts) != len(header):
            raise DataError(f"row {i}: {len(parts)} values, the header has {len(header)} columns")
        # a comma inside a value is a decimal comma: with ';' or tab separators, or quoted ("0,5")
        parts = [x.replace(",", ".") for x in parts]
        try:
            rows.append([float(x) for x in parts])
        except ValueError:
            bad = next(x for x in parts if not _is_float(x))
            raise DataError(f"row {i}: '{bad.strip()}' is not a number") from None
        line_no.append(i)
    if header is None:
        raise DataError("has no header line")
    arr = np.array(rows, dtype=float).reshape(-1, len(header))
    cols = {h: arr[:, j] for j, (h, _) in enumerate(header)}
    cols["__rows__"] = np.array(line_no)
    cols["__units__"] = {h: u for h, u in header if u is not None}
    return cols


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


def _read_mat(p: Path) -> dict:
    from scipy.io import loadmat

    try:
        m = loadmat(str(p), squeeze_me=True)
    except Exception as e:  # scipy raises several types for corrupt files
        raise DataError(f"cannot read MATLAB file '{p.name}': {e}") from None
    return {k: np.asarray(v, dtype=float).ravel() for k, v in m.items()
            if not k.startswith("__") and np.asarray(v).dtype.kind in "fiub"}


def _read_tdms(p: Path) -> dict:
    from nptdms import TdmsFile

    try:
        f = TdmsFile.read(str(p))
    except Exception as e:  # npTDMS raises several types for corrupt files
        raise DataError(f"cannot read TDMS file '{p.name}': {e}") from None
    cols, units = {}, {}
    for group in f.groups():
        for ch in group.channels():
            try:
                data = np.asarray(ch[:], dtype=float).ravel()
            except (TypeError, ValueError):
                continue  # a text or timestamp channel: not a signal
            unit = str(ch.properties.get("unit_string", "") or "").strip()
            for name in (ch.name, f"{group.name}/{ch.name}"):
                cols[name] = data
                if unit:
                    units[name] = unit
    cols["__units__"] = units
    return cols


def resample(ds: Dataset, rate: float) -> Dataset:
    if not (rate > 0 and math.isfinite(rate)):
        raise DataError(f"--resample must be a rate > 0 [Hz], got {rate}")
    if (ds.time[-1] - ds.time[0]) * rate > 5_000_000:
        raise DataError(f"--resample {rate:g} Hz over {ds.time[-1] - ds.time[0]:.4g} s gives more than "
                        "5,000,000 samples")
    t = np.arange(ds.time[0], ds.time[-1] + 0.5 / rate, 1.0 / rate)
    t = t[t <= ds.time[-1]]
    f = lambda a: None if a is None else np.interp(t, ds.time, a)  # noqa: E731
    out = Dataset(t, f(ds.torque), f(ds.speed), f(np.unwrap(ds.angle)) if ds.angle is not None else None,
                  ds.source, ds.notes + [f"resampled to {rate:g} Hz (linear interpolation)"])
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
