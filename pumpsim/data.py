"""Measured data (spec §6): CSV, MATLAB .mat and NI TDMS files -> a validated `Dataset`.

Columns: time (s, strictly increasing), torque (N m), optional speed (rad/s), optional angle (rad).
Options map other column/channel names and units (torque in N mm, speed in rpm), resample to a
uniform rate and cut out the constant-speed section of a run-up. Bad data is rejected with the row
(or channel) named.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import DataError

TORQUE_UNITS = {"N*m": 1.0, "Nm": 1.0, "N.m": 1.0, "N*mm": 1e-3, "Nmm": 1e-3, "N.mm": 1e-3}
SPEED_UNITS = {"rad/s": 1.0, "rpm": 2 * math.pi / 60}


@dataclass
class Dataset:
    time: np.ndarray
    torque: np.ndarray
    speed: np.ndarray | None = None
    angle: np.ndarray | None = None
    source: str = ""
    notes: list = field(default_factory=list)

    @property
    def n(self) -> int:
        return self.time.size

    def window(self, lo: int, hi: int) -> "Dataset":
        cut = lambda a: None if a is None else a[lo:hi]  # noqa: E731
        return Dataset(self.time[lo:hi], self.torque[lo:hi], cut(self.speed), cut(self.angle),
                       self.source, list(self.notes))


@dataclass
class DataOptions:
    time: str = "time"
    torque: str = "torque"
    speed: str | None = "speed"  # used when present
    angle: str | None = "angle"
    torque_unit: str = "N*m"
    speed_unit: str = "rad/s"
    resample: float | None = None  # Hz
    steady: bool = False  # keep only the constant-speed section
    steady_tolerance: float = 0.01  # relative speed band of the constant-speed section


def load_data(path, options: DataOptions | None = None, min_revolutions: float = 1.0,
              nominal_speed: float | None = None) -> Dataset:
    o = options or DataOptions()
    if o.torque_unit not in TORQUE_UNITS:
        raise DataError(f"torque unit must be one of {', '.join(TORQUE_UNITS)}, got '{o.torque_unit}'")
    if o.speed_unit not in SPEED_UNITS:
        raise DataError(f"speed unit must be one of {', '.join(SPEED_UNITS)}, got '{o.speed_unit}'")
    p = Path(path)
    if not p.exists():
        raise DataError(f"cannot read data '{path}': no such file")
    suffix = p.suffix.lower()
    if suffix == ".mat":
        cols, where = _read_mat(p), "variable"
    elif suffix == ".tdms":
        cols, where = _read_tdms(p), "channel"
    else:
        cols, where = _read_csv(p), "column"
    row_of = cols.pop("__rows__", None)
    for key in ("time", "torque"):
        name = getattr(o, key)
        if name not in cols:
            raise DataError(f"data '{p.name}' has no {where} '{name}' (found: {', '.join(sorted(cols)) or 'none'})")
    t = cols[o.time]
    n = t.size
    for name, arr in cols.items():
        if arr.size != n:
            raise DataError(f"{where} '{name}' has {arr.size} samples, {where} '{o.time}' has {n}")
    opt = {k: (cols[getattr(o, k)] if getattr(o, k) and getattr(o, k) in cols else None)
           for k in ("speed", "angle")}
    used = {"time": t, "torque": cols[o.torque], **{k: v for k, v in opt.items() if v is not None}}
    for key, arr in used.items():
        bad = np.nonzero(~np.isfinite(arr))[0]
        if bad.size:
            raise DataError(f"{_where(row_of, bad[0], where, key)}: {key} is not a finite number")
    dt = np.diff(t)
    bad = np.nonzero(dt <= 0)[0]
    if bad.size:
        raise DataError(f"{_where(row_of, bad[0] + 1, where, 'time')}: time must be strictly increasing "
                        f"({t[bad[0] + 1]:g} s after {t[bad[0]]:g} s)")
    ds = Dataset(t.astype(float), cols[o.torque] * TORQUE_UNITS[o.torque_unit],
                 None if opt["speed"] is None else opt["speed"] * SPEED_UNITS[o.speed_unit],
                 opt["angle"], source=str(p))
    if o.steady:
        ds = steady_section(ds, o.steady_tolerance)
    if o.resample:
        ds = resample(ds, o.resample)
    speed = nominal_speed or (float(np.mean(ds.speed)) if ds.speed is not None else None)
    if speed and speed > 0:
        span = ds.time[-1] - ds.time[0]
        need = min_revolutions * 2 * math.pi / speed
        if span < need * (1 - 1e-9):
            raise DataError(f"data '{p.name}' spans {span:.4g} s ({ds.n} samples): too few samples for "
                            f"one revolution ({need:.4g} s at {speed:.4g} rad/s)")
    if ds.n < 10:
        raise DataError(f"data '{p.name}' has {ds.n} samples; at least 10 are needed")
    return ds


def _where(row_of, index, where, key):
    if row_of is not None:
        return f"row {row_of[index]}"
    return f"sample {index} of {where} '{key}'"


def _read_csv(p: Path) -> dict:
    try:
        lines = p.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise DataError(f"cannot read data '{p}': {e}") from None
    header, rows, line_no = None, [], []
    for i, line in enumerate(lines, start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        if header is None:
            header = [h.strip() for h in s.split(",")]
            if len(set(header)) != len(header):
                raise DataError(f"row {i}: duplicate column names in the header")
            continue
        parts = s.split(",")
        if len(parts) != len(header):
            raise DataError(f"row {i}: {len(parts)} values, the header has {len(header)} columns")
        try:
            rows.append([float(x) for x in parts])
        except ValueError:
            bad = next(x for x in parts if not _is_float(x))
            raise DataError(f"row {i}: '{bad.strip()}' is not a number") from None
        line_no.append(i)
    if header is None:
        raise DataError(f"data '{p.name}' has no header line")
    arr = np.array(rows, dtype=float).reshape(-1, len(header))
    cols = {h: arr[:, j] for j, h in enumerate(header)}
    cols["__rows__"] = np.array(line_no)
    return cols


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
            if not k.startswith("__") and np.asarray(v).dtype.kind in "fiu"}


def _read_tdms(p: Path) -> dict:
    from nptdms import TdmsFile

    try:
        f = TdmsFile.read(str(p))
    except Exception as e:  # npTDMS raises several types for corrupt files
        raise DataError(f"cannot read TDMS file '{p.name}': {e}") from None
    cols = {}
    for group in f.groups():
        for ch in group.channels():
            data = np.asarray(ch[:], dtype=float)
            cols[ch.name] = data
            cols[f"{group.name}/{ch.name}"] = data
    return cols


def resample(ds: Dataset, rate: float) -> Dataset:
    if not rate > 0:
        raise DataError(f"resample rate must be > 0, got {rate}")
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
