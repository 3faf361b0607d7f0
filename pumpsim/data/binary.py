"""Binary records: MATLAB .mat (v4-v7), NI .tdms and Apache Parquet files; `reader_for` picks a
file's reader by its suffix (text otherwise)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataError
from .source import Source, sort_value
from .units import split_header

MAT73 = b"MATLAB 7.3 MAT-file"


def read_mat(p: Path, pick=None) -> Source:
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
    src = Source("variable", {})
    fields: dict = {}
    for k, v in m.items():
        if k.startswith("__"):
            continue
        if isinstance(v, dict):
            for fk, fv in v.items():
                if isinstance(fv, dict):
                    src.ignored[f"{k}.{fk}"] = "struct"
                    continue
                sort_value(src, f"{k}.{fk}", fv)
                fields.setdefault(split_header(fk)[0], []).append(f"{k}.{fk}")
        else:
            sort_value(src, k, v)
    for short, full in fields.items():  # a field's own name when it is the only one of that name
        if len(full) == 1 and short not in src.cols and full[0] in src.cols:
            src.cols[short] = src.cols[full[0]]
            if full[0] in src.units:
                src.units[short] = src.units[full[0]]
    return src


def read_tdms(p: Path, pick=None) -> Source:
    """An NI TDMS file: numeric channels by name (also 'group/name'; a bare name in several groups
    only with its group), waveform properties (wf_increment, wf_start_offset) and numeric file or
    group properties as sample-rate candidates."""
    from nptdms import TdmsFile

    try:
        f = TdmsFile.read(str(p))
    except Exception as e:  # npTDMS raises several types for corrupt files
        raise DataError(f"cannot read TDMS file '{p.name}': {e}") from None
    src = Source("channel", {})
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


def read_parquet(p: Path, pick=None) -> Source:
    """An Apache Parquet table (pyarrow, already a dependency for study results): numeric columns
    are signals (a unit in the name as in CSV headers, 'torque [N*mm]'); a time-stamp column
    becomes seconds since its first sample; text columns are left aside."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(str(p))
    except Exception as e:  # pyarrow raises several types for corrupt files
        raise DataError(f"cannot read Parquet file '{p.name}': {e}") from None
    src = Source("column", {}, names=list(table.column_names))
    for name, column in zip(table.column_names, table.columns):
        base, unit = split_header(name)
        if pa.types.is_timestamp(column.type):
            ns = column.cast(pa.timestamp("ns")).cast(pa.int64()).to_numpy(zero_copy_only=False)
            data = (ns - ns[0]) * 1e-9 if ns.size else ns.astype(float)
            unit = "s"
            src.notes.append(f"column '{name}' holds time stamps: read as seconds since the first")
        elif pa.types.is_integer(column.type) or pa.types.is_floating(column.type):
            data = column.to_numpy(zero_copy_only=False).astype(float)
        else:
            src.ignored[name] = "text"
            continue
        src.cols[base] = data
        if unit:
            src.units[base] = unit
    return src


READERS = {".mat": read_mat, ".tdms": read_tdms, ".parquet": read_parquet, ".pq": read_parquet}


def reader_for(p: Path, text_reader):
    """The reader of a file by its suffix; text_reader (CSV) for any other."""
    return READERS.get(Path(p).suffix.lower(), text_reader)
