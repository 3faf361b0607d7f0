"""Measured data: CSV, MATLAB .mat and NI TDMS files -> a validated `Dataset`.

Columns: time (s, strictly increasing), torque (N m), optional speed (rad/s), optional angle (rad).
Options map other column/channel names and units (torque in N mm, speed in rpm), resample to a
uniform rate and cut out the constant-speed section of a run-up. Bad data is rejected with the row
(or channel) named.

Modules: `load` (load_data), `dataset` (Dataset, DataOptions), the readers `csvfile`, `binary`
(.mat, .tdms) over `source`, `text` (decoding) and `units`; `sampling` (gaps, resampling, the
steady section) and `trend` (the speed column's slow trend).
"""
from .binary import MAT73, read_mat, read_parquet, read_tdms, reader_for
from .csvfile import RowNumbers, read_csv
from .dataset import DataOptions, Dataset
from .load import load_data, match_column
from .sampling import GAP_STEPS, JITTER_NOTE, REGULAR_STEPS, TimeGaps, check_rate, resample, steady_section, \
    time_gaps, time_resolution
from .source import INTERVAL_NAMES, RATE_NAMES, Source, row_name
from .text import decode_file, decode_text
from .trend import TREND_ALPHA, TREND_MAX_DEGREE, TREND_REVOLUTIONS_PER_DEGREE, SpeedTrend, speed_trend
from .units import ANGLE_UNITS, SI_UNIT, SPEED_UNITS, TIME_UNITS, TORQUE_UNITS, UNIT_NAMES, UNITS, split_header, \
    unit_factor, unit_key

__all__ = [
    "load_data", "Dataset", "DataOptions", "SpeedTrend", "speed_trend", "TimeGaps", "time_gaps", "resample",
    "steady_section", "time_resolution", "check_rate", "read_csv", "read_mat", "read_tdms", "read_parquet", "reader_for", "RowNumbers",
    "Source", "row_name", "match_column", "decode_text", "decode_file", "split_header", "unit_factor",
    "unit_key", "UNITS", "UNIT_NAMES", "SI_UNIT", "TIME_UNITS", "TORQUE_UNITS", "SPEED_UNITS", "ANGLE_UNITS",
    "GAP_STEPS", "REGULAR_STEPS", "JITTER_NOTE", "TREND_ALPHA", "TREND_MAX_DEGREE",
    "TREND_REVOLUTIONS_PER_DEGREE", "RATE_NAMES", "INTERVAL_NAMES", "MAT73",
]
