"""Write a Record as a real rig's logger would (only formats pumpsim's README says it reads)."""
from __future__ import annotations

import numpy as np

FORMATS = ("csv", "csv_speed", "csv_speed_noisy", "csv_angle", "csv_nmm", "csv_semicolon", "tdms", "mat")
SUFFIX = {"tdms": ".tdms", "mat": ".mat"}
# more of what loggers write (not in FORMATS, so the balanced grid keeps its cases): units in the
# header (time in ms, torque in N*mm, speed in rpm) with the columns in another order, an extra
# column and a comment; tab-separated with decimal commas; comma-separated with quoted decimal
# commas (a spreadsheet's export in a German locale)
EXTRA_FORMATS = ("csv_units", "csv_tab_comma", "csv_quoted_comma")
# unit mistakes a user makes: time in ms, speed in rpm, without a unit in the header; the right
# answer is a refusal (exit 2) naming the column, with nothing written
BAD_FORMATS = ("csv_ms_bare", "csv_rpm_bare")


def _columns(rec, fmt, rng):
    cols = {"time": rec.t, "torque": rec.torque}
    if fmt in ("csv_speed", "csv_semicolon", "mat") + EXTRA_FORMATS + BAD_FORMATS:
        cols["speed"] = rec.omega
    if fmt == "csv_speed_noisy":
        cols["speed"] = rec.omega * (1 + 0.003 * rng.standard_normal(len(rec.t)))
    if fmt == "csv_angle":
        cols["angle"] = np.mod(rec.theta, 2 * np.pi)      # an encoder's angle, wrapped each revolution
    return cols


def write(rec, fmt, path_stem):
    """Write rec in format fmt; returns the path. Seeded by the record (reproducible)."""
    rng = np.random.default_rng(rec.seed + 7919)
    cols = _columns(rec, fmt, rng)
    path = str(path_stem) + SUFFIX.get(fmt, ".csv")
    if fmt == "tdms":
        from nptdms import ChannelObject, TdmsWriter
        with TdmsWriter(path) as w:
            w.write_segment([ChannelObject("Measurement", k, np.asarray(v, dtype=float)) for k, v in cols.items()])
    elif fmt == "mat":
        from scipy.io import savemat
        savemat(path, {k: np.asarray(v, dtype=float).reshape(-1, 1) for k, v in cols.items()})
    elif fmt == "csv_nmm":
        with open(path, "w") as f:
            f.write("# torque cell T22, logged by rig PC\ntime,torque [N·mm]\n")
            for t, q in zip(rec.t, rec.torque * 1e3):
                f.write(f"{t:.7f},{q:.6f}\n")
    elif fmt in EXTRA_FORMATS + BAD_FORMATS:
        _write_logger(path, fmt, cols, rng)
    elif fmt == "csv_semicolon":
        with open(path, "w") as f:
            f.write("time;torque;speed\n")
            for row in zip(*cols.values()):
                f.write(";".join(f"{x:.9g}".replace(".", ",") for x in row) + "\n")
    else:
        names = list(cols)
        data = np.column_stack([cols[k] for k in names])
        np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.10g")
    return path


def _write_logger(path, fmt, cols, rng):
    """The EXTRA_FORMATS and BAD_FORMATS text files."""
    t, q, w = cols["time"], cols["torque"], cols["speed"]
    if fmt == "csv_units":
        head = "speed [rpm],temperature [degC],torque [N*mm],time [ms]"
        rows = zip(w * 60 / (2 * np.pi), 40 + 0.1 * rng.standard_normal(t.size), q * 1e3, t * 1e3)
    elif fmt == "csv_ms_bare":
        head, rows = "time,torque,speed", zip(t * 1e3, q, w)
    elif fmt == "csv_rpm_bare":
        head, rows = "time,torque,speed", zip(t, q, w * 60 / (2 * np.pi))
    else:
        head, rows = "time [s]\ttorque [N*m]\tspeed [rad/s]", zip(t, q, w)
    with open(path, "w") as f:
        f.write("# rig PC export\n")
        if fmt == "csv_quoted_comma":
            f.write(head.replace("\t", ",") + "\n")
            for row in rows:
                f.write(",".join(f'"{x:.9g}"'.replace(".", ",") for x in row) + "\n")
            return
        sep = "\t" if fmt == "csv_tab_comma" else ","
        f.write(head + "\n")
        for row in rows:
            line = sep.join(f"{x:.9g}" for x in row)
            f.write((line.replace(".", ",") if fmt == "csv_tab_comma" else line) + "\n")
