"""What a reader found in a file (`Source`), the filing of MATLAB variables and TDMS channels as
signals or metadata, and how a sample is named in a message."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import DataError
from .units import split_header


@dataclass
class Source:
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
    notes: list = field(default_factory=list)  # what the reader made of the file, said to the user

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


def sort_value(src: Source, name: str, value) -> None:
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




def row_name(row_of, index, where, key):
    """How a message names sample `index`: its row in a text file, else its index in the signal."""
    if row_of is not None:
        return f"row {row_of[index]}"
    return f"sample {index} of {where} '{key}'"
