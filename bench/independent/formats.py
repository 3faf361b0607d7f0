"""Write a Record as a real rig's logger would (only formats pumpsim's README says it reads)."""
from __future__ import annotations

import numpy as np

FORMATS = ("csv", "csv_speed", "csv_speed_noisy", "csv_angle", "csv_nmm", "csv_semicolon", "tdms", "mat")
SUFFIX = {"tdms": ".tdms", "mat": ".mat"}


def _columns(rec, fmt, rng):
    cols = {"time": rec.t, "torque": rec.torque}
    if fmt in ("csv_speed", "csv_semicolon", "mat"):
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
