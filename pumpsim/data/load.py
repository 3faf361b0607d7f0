"""`load_data`: a measurement file -> a validated `Dataset` in SI units."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import DataError
from .binary import reader_for
from .csvfile import read_csv
from .dataset import DataOptions, Dataset
from .sampling import check_rate, resample, steady_section, time_gaps, time_resolution
from .source import row_name
from .units import UNITS, split_header, unit_factor


def load_data(path, options: DataOptions | None = None, min_revolutions: float = 1.0,
              nominal_speed: float | None = None) -> Dataset:
    """Read a measurement into a `Dataset` in SI units.

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
    _check_options(o)
    if p.is_dir():
        raise DataError("is a folder, not a data file")
    if not p.exists():
        raise DataError("cannot read data: no such file")
    reader = reader_for(p, read_csv)
    src = reader(p, lambda names: _pick(o, names))
    name = _pick(o, list(src.cols))
    notes = list(src.notes)
    t = _time(src, name, o, notes)
    used = _signals(src, name, t)
    scale = {key: _unit_of(key, name[key], src.units, getattr(o, f"{key}_unit"), src.where) for key in used}
    if "time" in name:
        resolution = time_resolution(t) * scale["time"]
        t = t * scale["time"] if scale["time"] != 1.0 else t
    else:
        resolution = 0.0
    _check_increasing(t, src.rows, src.where)
    si = {k: (used[k] * scale[k] if scale[k] != 1.0 else used[k]) if k in used else None
          for k in ("torque", "speed", "angle")}
    ds = Dataset(t, si["torque"], si["speed"], si["angle"], source=str(p), notes=notes)
    return _sampled(ds, o, resolution, lambda i: row_name(src.rows, i, src.where, "time"),
                    min_revolutions, nominal_speed)


def _check_options(o: DataOptions) -> None:
    """The options' units and rate, before the file is read."""
    for q in UNITS:
        if getattr(o, f"{q}_unit", None) is not None:
            unit_factor(q, getattr(o, f"{q}_unit"), "")
    if o.resample is not None and o.resample != "auto":
        check_rate(o.resample)


def _time(src, name, o: DataOptions, notes) -> np.ndarray:
    """The time signal in the file's unit: its own, else from a sample rate (said in `notes`)."""
    where = src.where
    if "time" not in name and src.interval(name.get("torque")) is None:
        rate_hint = "" if where == "column" else " and no sample rate (a scalar Fs, SampleRate or dt)"
        raise DataError(f"has no {where} '{o.time}'{rate_hint} (found: {src.found()})")
    if "torque" not in name:
        raise DataError(f"has no {where} '{o.torque}' (found: {src.found()})")
    if "time" in name:
        t = src.cols[name["time"]]
    else:
        dt, t0, origin = src.interval(name["torque"])
        t = t0 + dt * np.arange(src.cols[name["torque"]].size)
        notes.append(f"time from {origin} (no {where} '{o.time}')")
    if t.size == 0:
        raise DataError("has a header but no data rows")
    return t


def _signals(src, name, t) -> dict:
    """{quantity: samples} of the used signals (time first when the file has it), each as long as
    the time and finite."""
    where, n = src.where, t.size
    used = {k: src.cols[name[k]] for k in ("torque", "speed", "angle") if k in name}
    first = name.get("time", name["torque"])
    for key, arr in used.items():
        if arr.size != n:
            raise DataError(f"{where} '{name[key]}' has {arr.size} samples, {where} '{first}' has {n}")
    if "time" in name:
        used = {"time": t, **used}
    for key, arr in used.items():
        bad = np.nonzero(~np.isfinite(arr))[0]
        if bad.size:
            raise DataError(f"{row_name(src.rows, bad[0], where, key)}: {key} is not a finite number")
    return used


def _check_increasing(t, rows, where) -> None:
    dt = np.diff(t)
    bad = np.nonzero(dt <= 0)[0]
    if not bad.size:
        return
    b = bad[0]
    # as many digits as tell the two apart (absolute time stamps: 1.7e9 s + fractions)
    digits = max(6, min(17, int(math.ceil(math.log10(max(abs(t[b]), 1e-300) / max(abs(dt[b]), 1e-300)))) + 2))
    again = (f" ({int(np.sum(dt == 0))} repeated times: written with too few digits for the sample "
             "rate?)" if dt[b] == 0 else "")
    raise DataError(f"{row_name(rows, b + 1, where, 'time')}: time must be strictly increasing "
                    f"({t[b + 1]:.{digits}g} s after {t[b]:.{digits}g} s){again}")


def _sampled(ds: Dataset, o: DataOptions, resolution, row, min_revolutions, nominal_speed) -> Dataset:
    """The steady section (when asked), gaps refused or resampled across, and the length checked.
    row(i): how a message names sample i of the file."""
    lo = 0
    if o.steady:
        t = ds.time
        ds = steady_section(ds, o.steady_tolerance)
        lo = int(np.searchsorted(t, ds.time[0]))
    gaps = time_gaps(ds.time, resolution)
    if gaps.gaps.size and o.resample is None:
        raise DataError(gaps.message(lambda i: row(lo + i)))
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
    found = {k: match_column(getattr(o, k), names) for k in ("time", "torque", "speed", "angle")}
    return {k: v for k, v in found.items() if v and v in names}


def match_column(wanted, cols):
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
