"""A study's results on disk: the table's columns, Parquet parts written by the client (temporary
file + rename), and manifest.json (the study hash, kernel keys, package versions, seed and batch
layout) that lets a rerun of the same study resume where it stopped."""
from __future__ import annotations

import functools
import importlib.metadata
import json
import platform
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..fsfaults import guard, probe_folder
from ..io import write_text
from ..locks import LOCK_FILES
from .outputs import BOOL_OUTPUTS, per_vane_name

PART = "part-{:05d}.parquet"
MANIFEST = "manifest.json"
PACKAGES = ("pumpsim", "casadi", "numpy", "scipy", "dask", "distributed", "pyarrow", "SALib", "pymoo")


@functools.lru_cache(maxsize=1)
def _versions() -> tuple:
    """The installed versions, read once per process (each manifest write asked for them)."""
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = None
    return tuple(out.items())


def package_versions() -> dict:
    return dict(_versions())


def max_vanes(study) -> int:
    if study.function is not None:
        return 0
    base = int(study.base["rotor"]["vanes"])
    for v in study.variables:
        if v.key == "rotor.vanes":
            return int(max(v.values))
    return base


def columns(study) -> list[tuple[str, str]]:
    """(name, type) of the result table in order: design, speed, keys, outputs, status."""
    cols = [("design", "int")]
    if study.function is None:
        cols.append(("speed", "float"))
    cols += [(k, "float") for k in study.keys]
    for o in study.outputs:
        cols.append((o, "bool" if o in BOOL_OUTPUTS else "float"))
        if o == "friction_power":
            cols += [(per_vane_name(i), "float") for i in range(max_vanes(study))]
    cols.append(("status", "str"))
    return cols


def rows_to_table(study, rows):
    """The Arrow table of row dicts (a key a row lacks: null)."""
    return columns_to_table(study, {name: [r.get(name) for r in rows] for name, _ in columns(study)})


def columns_to_table(study, data: dict):
    """The Arrow table of {column: values}: floats as sequences (None or NaN: NaN), booleans as
    sequences of bool/None or float arrays (NaN: null), design as ints, status as strings."""
    import pyarrow as pa

    types = {"int": pa.int64(), "float": pa.float64(), "bool": pa.bool_(), "str": pa.string()}
    arrays, fields = {}, []
    for name, typ in columns(study):
        vals = data[name]
        if typ == "float":  # a missing value (None) is NaN
            vals = np.asarray(vals, dtype=float) if len(vals) else np.empty(0)
        if typ == "bool" and isinstance(vals, np.ndarray) and vals.dtype.kind == "f":
            arrays[name] = pa.array(vals == 1.0, type=pa.bool_(), mask=np.isnan(vals))
        else:
            arrays[name] = pa.array(vals, type=types[typ])
        fields.append(pa.field(name, types[typ]))
    return pa.table(arrays, schema=pa.schema(fields))


def check_out_dir(out, study_hash) -> dict | None:
    """Before any work: the folder is new, or holds this same study (resume). Returns its manifest."""
    if out is None:
        return None
    d = Path(out)
    if not d.parent.is_dir():
        raise ConfigError(f"results folder '{d}': its parent '{d.parent}' does not exist")
    if d.exists() and not d.is_dir():
        raise ConfigError(f"results folder '{d}' exists and is not a folder")
    probe_folder(d, "--out", create=True)
    if not d.exists():
        return None
    mpath = d / MANIFEST
    if not mpath.exists():
        if any(p.name not in LOCK_FILES for p in d.iterdir()):
            raise ConfigError(f"results folder '{d}' is not empty and holds no {MANIFEST}; choose a new folder")
        return None
    try:
        man = json.loads(mpath.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ConfigError(f"results folder '{d}': unreadable {MANIFEST} ({e})") from None
    if man.get("study_hash") != study_hash:
        raise ConfigError(f"results folder '{d}' holds results of a different study (hash {man.get('study_hash')}, "
                          f"this study {study_hash}); choose another folder or remove it")
    return man


def write_manifest(folder, study, plan, status, kernel_keys, stats=None):
    """manifest.json of a study folder: what was run, with which kernels and packages, how far."""
    man = {
        "study_hash": study.study_hash(), "study": study.path, "config": study.config_path,
        "function": study.function, "sampler": study.sampler, "seed": study.seed,
        "samples": study.samples, "designs": int(len(plan.X)), "batch_size": plan.batch_size,
        "batch_bounds": plan.bounds, "batches": plan.n_batches, "part_pattern": PART, "keys": study.keys,
        "speeds": study.speeds, "outputs": study.outputs, "model": study.model,
        "revolution_samples": study.revolution_samples,
        "limits": {k: list(v) for k, v in study.limits.items()},
        "kernel_keys": kernel_keys, "versions": package_versions(),
        "columns": [c for c, _ in columns(study)], "status": status,
    }
    if stats is not None:
        man["run"] = stats.as_dict()
    with guard("writing the study manifest", folder / MANIFEST, "--out"):
        write_text(folder / MANIFEST, json.dumps(man, indent=1))


def ordered(df):
    keys = [c for c in ("design", "speed") if c in df.columns]
    return df.sort_values(keys, kind="stable").reset_index(drop=True)


def read_manifest(folder) -> dict:
    mpath = Path(folder) / MANIFEST
    try:
        return json.loads(mpath.read_text())
    except OSError:
        raise ConfigError(f"'{folder}' holds no study results ({MANIFEST} missing)") from None
    except json.JSONDecodeError as e:
        raise ConfigError(f"'{mpath}' is not valid JSON: {e}") from None


def read_results(folder, arrays: bool = False):
    """The result table of a study folder as a pandas DataFrame (design, speed order), or with
    arrays=True a dict of NumPy arrays by column."""
    import pandas as pd
    import pyarrow.parquet as pq

    man = read_manifest(folder)
    parts = sorted(Path(folder).glob("part-*.parquet"))
    if parts:
        df = pd.concat([pq.read_table(p).to_pandas() for p in parts], ignore_index=True)
    else:
        df = pd.DataFrame(columns=man.get("columns", []))
    df = ordered(df)
    if arrays:
        return {c: df[c].to_numpy() for c in df.columns}
    return df
