"""Text files (CSV and its dialects): the header, then the used columns streamed through pyarrow's
CSV reader where the dialect allows, else read line by line, which names every refusal's row."""
from __future__ import annotations

import csv
import re
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..errors import DataError
from .source import Source
from .text import UTF8_BOM, decode_file, decode_text, read_bytes, refuse_binary
from .units import split_header


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
    pos, line = (len(UTF8_BOM) if raw.startswith(UTF8_BOM) else 0), 0
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


def read_csv(p: Path, pick, fast: bool = True) -> Source:
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
        raw = decode_text(read_bytes(p)).encode("utf-8")
    else:
        refuse_binary(head, DataError)
    if raw is None and b"\n" not in head and b"\r" in head:  # old Mac line ends
        raw = read_bytes(p).replace(b"\r", b"\n")
    found = _header_end(raw if raw is not None else head)
    if found is None and raw is None and len(head) == _HEAD:
        raw = read_bytes(p)
        found = _header_end(raw)
    if found is None:
        raise DataError("has no header line")
    line, end = found
    text = raw if raw is not None else head
    sep, header = _header(decode_text(text[:end]).splitlines()[-1].strip(), line)
    notes = []
    below = _units_row(text, line, end, sep, len(header))
    if below is not None:
        line, end, units = below
        header = [(h, u or below_u) for (h, u), below_u in zip(header, units)]
        notes.append(f"units from row {line}, under the header")
    names = [h for h, _ in header]
    picked = pick(names)
    keep = [j for j, h in enumerate(names) if h in set(picked.values())]
    body = _Body(p, raw, end + 1)
    cols = _arrow_columns(body, sep, names, keep) if fast and keep else None
    units = {h: u for h, u in header if u is not None}
    if cols is not None:
        rows = RowNumbers(body, line + 1)
    else:
        clock = _Clock(picked.get("time"))
        cols, rows = _python_columns(decode_file(p) if raw is None else raw.decode("utf-8"), header, keep,
                                     2 if below is not None else 1, clock)
        if clock.first is not None:
            units[clock.column] = "s"
            notes.append(f"time from the time stamps of column '{clock.column}', in seconds after the first "
                         f"({clock.first_text})")
    return Source("column", cols, units, rows, names=names, notes=notes)


def _units_row(text: bytes, line: int, end: int, sep: str, width: int):
    """(line number, end offset, units) of a line of units right under the header ('s,V,A,kPa'),
    or None: a line holding no number whose fields are short or bracketed, one per column."""
    pos = end + 1
    while pos < len(text):
        nl = text.find(b"\n", pos)
        stop = len(text) if nl < 0 else nl
        line += 1
        s = decode_text(text[pos:stop]).strip()
        if s and not s.startswith("#"):
            fields = [f.strip().strip('"').strip() for f in _fields(s, sep)]
            if len(fields) == width + 1 and fields[-1] == "":
                fields = fields[:-1]
            units = [f.strip("[]()").strip() for f in fields]
            if (len(fields) != width or any(_is_float(f.replace(",", ".")) for f in fields if f)
                    or not any(units) or any(len(u) > UNIT_CHARS or _stamp(u) for u in units)):
                return None
            return line, stop, [u or None for u in units]
        if nl < 0:
            return None
        pos = stop + 1
    return None


UNIT_CHARS = 16  # a unit row's longest field ('N*mm', 'kPa abs', 'rad/s')


def _stamp(text: str):
    """The datetime of an ISO 8601 time stamp ('2026-11-27 10:00:00.001', 'T' or blank, a zone),
    or None."""
    if len(text) < 10 or text[4:5] != "-":
        return None
    try:
        return datetime.fromisoformat(text)
    except ValueError:
        return None


class _Clock:
    """Time stamps in the time column, read as seconds after the first (to the microsecond: the
    difference of two datetimes, not of two epoch seconds)."""

    def __init__(self, column):
        self.column, self.first, self.first_text = column, None, ""

    def seconds(self, text: str) -> float:
        stamp = _stamp(text)
        if stamp is None:
            raise ValueError(text)
        if stamp.tzinfo is not None:
            stamp = stamp.astimezone(timezone.utc).replace(tzinfo=None)
        if self.first is None:
            self.first, self.first_text = stamp, text
        return (stamp - self.first).total_seconds()


class RowNumbers:
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


def _python_columns(text: str, header, keep, head_lines=1, clock=None):
    """{name: float array} of the columns `keep`, line by line, and the line number of each row;
    `head_lines`: the header's lines (2 with a line of units); `clock` reads time stamps in the
    time column."""
    sep, width, values, line_no = None, len(header), [], []
    seen = 0
    stamped = next((k for k, j in enumerate(keep) if clock is not None and header[j][0] == clock.column), None)
    for i, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        if seen < head_lines:
            seen += 1
            sep = sep or _header(s, i)[0]
            continue
        parts = [x.strip().strip('"') for x in _fields(s, sep)]
        if len(parts) == width + 1 and parts[-1] == "":
            parts = parts[:-1]
        if len(parts) != width:
            raise DataError(f"row {i}: {len(parts)} values, the header has {width} columns")
        # a comma inside a value is a decimal comma: with ';' or tab separators, or quoted ("0,5")
        parts = [parts[j] for j in keep]
        try:
            values.append([clock.seconds(x) if k == stamped and _stamp(x) else float(x.replace(",", "."))
                           for k, x in enumerate(parts)])
        except ValueError:
            bad = next(x for k, x in enumerate(parts)
                       if not _is_float(x.replace(",", ".")) and not (k == stamped and _stamp(x)))
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
