"""Run a study's designs on dask.distributed and keep the results as Parquet parts.

- Default: a LocalCluster with one single-threaded worker process per core; `scheduler` (the
  `--scheduler ADDRESS` option or `study.scheduler`) runs the same study on an existing cluster.
- Tasks are batches of designs sized from a pilot run's time per design: on several workers by
  guided self-scheduling (guided_bounds: large batches first, >= TASK_SECONDS while more than two
  per worker remain, shrinking to ~TAIL_TASK_SECONDS so the workers finish together), else equal
  batches of >= TASK_SECONDS. A task carries the study (plain data) and its designs' key values;
  the worker loads or builds the compiled variant from the hashed cache itself. Compiled
  functions never travel. RunStats splits the workers' idle time by where it falls.
- Every design's values are fixed on the client before any task runs (sampling.py), and each
  design is evaluated on its own, so the table is the same for 1 or 64 workers and any batching.
- Each finished batch is written by the client as `part-NNNNN.parquet` (temporary file + rename);
  `manifest.json` holds the study hash, kernel keys, package versions, seed and batch layout. A
  rerun with the same study skips the parts already there (resume).
"""
from __future__ import annotations

import contextlib
import importlib.metadata
import json
import logging
import math
import os
import platform
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import interrupt
from ..errors import ConfigError, OutputError, SolverError
from ..fsfaults import guard, probe_folder
from ..io import atomic_path, write_text
from ..locks import LOCK_FILES, study_folder
from .outputs import BOOL_OUTPUTS, per_vane_name
from .sampling import design_matrix
from .summary import coverage, coverage_text

TASK_SECONDS = 0.5  # work per task: Dask's per-task cost (~1-5 ms) stays below 1 %
TAIL_TASK_SECONDS = 0.1  # the last tasks (guided_bounds): shorter, so the workers finish together
# guided_bounds: a batch is 1/(this x workers) of what remains. 2 lets the first batch hold a
# quarter of a 2-worker study, which a worker slowed by other processes then holds up (measured:
# 15 % idle at the end on the shared machine); 4 keeps the first to an eighth.
GUIDED_SHARE = 4
PILOT_DESIGNS = 6
CONNECT_TIMEOUT = 5.0  # s: an unreachable scheduler fails this fast
PART = "part-{:05d}.parquet"
MANIFEST = "manifest.json"
PACKAGES = ("pumpsim", "casadi", "numpy", "scipy", "dask", "distributed", "pyarrow", "SALib", "pymoo")


def package_versions() -> dict:
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = None
    return out


def max_vanes(study) -> int:
    if study.function is not None:
        return 0
    base = int(study.base["rotor"]["vanes"])
    for v in study.variables:
        if v.key == "rotor.vanes":
            return int(max(v.values))
    return base


def structures(study) -> list:
    """The compiled variants a study needs."""
    if study.function is not None:
        return []
    from ..config import config_from_dict

    counts = {int(study.base["rotor"]["vanes"])}
    for v in study.variables:
        if v.key == "rotor.vanes":
            counts = {int(x) for x in v.values}
    out = []
    for n in sorted(counts):
        try:
            cfg = config_from_dict(study.design_dict({"rotor.vanes": n}))
        except ConfigError:
            continue
        out.append(cfg.structure_for("constrained"))
        if study.model == "contact":
            out.append(cfg.structure_for("contact"))
        if study.booster_pressure is not None:
            from ..kernels.pneumatic import structure_of

            out.append(structure_of(cfg))
    return out


def kernel_keys(study) -> dict:
    """Variant -> content key of the compiled library this process loads (or builds)."""
    from ..kernels import load_kernels
    from .evaluate import _fast

    out = {}
    for st in structures(study):
        out[st.variant] = load_kernels(st).key
        fast = _fast(st) if st.model == "constrained" else None
        if fast is not None:
            out[f"{st.variant} (SIMD)"] = fast.key
    return out


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
    import pyarrow as pa

    types = {"int": pa.int64(), "float": pa.float64(), "bool": pa.bool_(), "str": pa.string()}
    data, fields = {}, []
    for name, typ in columns(study):
        vals = [r.get(name) for r in rows]
        if typ == "float":
            vals = [math.nan if v is None else float(v) for v in vals]
        data[name] = pa.array(vals, type=types[typ])
        fields.append(pa.field(name, types[typ]))
    return pa.table(data, schema=pa.schema(fields))


@dataclass
class Plan:
    """The designs cut into batches: equal ones of batch_size, or (bounds given) the batch b is
    rows bounds[b]:bounds[b + 1] (guided_bounds)."""

    study: object
    X: np.ndarray  # (designs, keys)
    batch_size: int
    ids: np.ndarray = field(default=None)
    bounds: list | None = None

    def __post_init__(self):
        if self.ids is None:
            self.ids = np.arange(len(self.X))

    @property
    def n_batches(self) -> int:
        if self.bounds is not None:
            return len(self.bounds) - 1
        return math.ceil(len(self.X) / self.batch_size)

    def batch(self, b: int):
        if self.bounds is not None:
            lo, hi = self.bounds[b], self.bounds[b + 1]
        else:
            lo, hi = b * self.batch_size, min(len(self.X), (b + 1) * self.batch_size)
        return self.ids[lo:hi], self.X[lo:hi]


def guided_bounds(n: int, per_design: float, workers: int) -> list[int]:
    """Batch bounds for n designs on `workers` workers (guided self-scheduling): each batch is
    1/(GUIDED_SHARE workers) of what remains, so the first are large (few tasks, little per-task
    cost) and they shrink toward the end, where the last ones take ~TAIL_TASK_SECONDS and the
    workers finish together. Batches stay >= TASK_SECONDS of work until <= 2 such batches per
    worker remain."""
    big = max(1, math.ceil(TASK_SECONDS / per_design))
    small = max(1, math.ceil(TAIL_TASK_SECONDS / per_design))
    bounds, lo = [0], 0
    while lo < n:
        rem = n - lo
        floor = big if rem > 2 * workers * big else small
        size = max(math.ceil(rem / (GUIDED_SHARE * workers)), floor)
        if rem - size < small:
            size = rem
        lo += size
        bounds.append(lo)
    return bounds


def study_designs(study) -> np.ndarray:
    import warnings

    with warnings.catch_warnings():  # Sobol' balance needs 2^m points; any n is still a valid design
        warnings.simplefilter("ignore", UserWarning)
        return design_matrix(study.variables, study.sampler, study.samples, study.seed)


def run_batch(study, ids, X):
    """The task: evaluate designs on whichever process runs it. Returns (first id, Arrow table,
    seconds, (worker, start, stop on its wall clock, CPU seconds of its thread)))."""
    from .evaluate import evaluate_rows

    w0, t0, c0 = time.time(), time.perf_counter(), time.thread_time()
    rows = evaluate_rows(study, X, ids, max_vanes(study))
    table = rows_to_table(study, rows)
    sec = time.perf_counter() - t0
    return ids[0], table, sec, (_worker_name(), w0, w0 + sec, time.thread_time() - c0)


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):  # not inside a Dask task
        return "local"


def pilot_time_per_design(study, X) -> float:
    """Seconds per design on this process (which also builds any missing variant into the cache
    before the workers look for it): the least of three timings of PILOT_DESIGNS designs, as the
    machine may be shared and a disturbed timing only ever reads long."""
    from .evaluate import evaluate_rows

    n = min(len(X), PILOT_DESIGNS)
    evaluate_rows(study, X[:1], np.arange(1), max_vanes(study))  # load kernels, make the maps
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        evaluate_rows(study, X[:n], np.arange(n), max_vanes(study))
        best = min(best, time.perf_counter() - t0)
        if best > 2 * TASK_SECONDS:  # slow designs: one timing says enough
            break
    return max(best / n, 1e-6)



def check_out_dir(out, study_hash) -> dict | None:
    """Before any work: the folder is new, or holds this same study (resume). Returns its manifest."""
    if out is None:
        return None
    d = Path(out)
    if not d.parent.is_dir():
        raise ConfigError(f"--out: folder '{d.parent}' does not exist")
    if d.exists() and not d.is_dir():
        raise ConfigError(f"--out '{d}' exists and is not a folder")
    probe_folder(d, "--out", create=True)
    if not d.exists():
        return None
    mpath = d / MANIFEST
    if not mpath.exists():
        if any(p.name not in LOCK_FILES for p in d.iterdir()):
            raise ConfigError(f"--out '{d}' is not empty and holds no {MANIFEST}; choose a new folder")
        return None
    try:
        man = json.loads(mpath.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ConfigError(f"--out '{d}': unreadable {MANIFEST} ({e})") from None
    if man.get("study_hash") != study_hash:
        raise ConfigError(f"--out '{d}' holds results of a different study (hash {man.get('study_hash')}, "
                          f"this study {study_hash}); choose another folder or remove it")
    return man


def _probe(address):
    """A refused or unroutable TCP address fails at once instead of after Dask's retries."""
    import socket
    from urllib.parse import urlsplit

    if "://" not in address:
        address = "tcp://" + address
    u = urlsplit(address)
    if u.scheme not in ("tcp", "tls"):
        return  # other transports (inproc, ucx): leave it to Dask
    try:
        host, port = u.hostname, u.port
    except ValueError:
        host = port = None
    if not host or not port:
        raise ConfigError(f"--scheduler: '{address}' is not a scheduler address (tcp://HOST:PORT)")
    try:
        socket.create_connection((host, port), timeout=CONNECT_TIMEOUT).close()
    except OSError as e:
        raise ConfigError(f"cannot reach the Dask scheduler at '{address}' ({e.strerror or e}); "
                          "is it running, and is the address right?") from None


def connect(scheduler=None, workers=None, processes=True):
    """A dask.distributed Client: on an existing scheduler (fails within CONNECT_TIMEOUT with a
    ConfigError), or on a new LocalCluster (one single-threaded worker per core)."""
    from dask.distributed import Client, LocalCluster

    if scheduler:
        _probe(scheduler)
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT}s")
            return client, client  # ours to close; the cluster is not
        except Exception as e:  # timeouts, refused handshakes, something else on that port
            raise ConfigError(f"no Dask scheduler answers at '{scheduler}' within {CONNECT_TIMEOUT:g} s "
                              f"({type(e).__name__}: {str(e)[:200]})") from None
    n = workers or os.cpu_count() or 1
    logging.getLogger("distributed").setLevel(logging.ERROR)  # start/stop chatter is not ours to print
    import warnings

    # its HTTP endpoint moves to a free port when another cluster holds the default one
    warnings.filterwarnings("ignore", message="Port .* is already in use", category=UserWarning)
    # the workers' own logs: a failing task reaches the client as its exception, and a cluster
    # torn down by an interruption would print lost-connection tracebacks from every worker
    cluster = client = None
    interrupt.progress("while the local Dask cluster started (no design done)")
    try:
        with interrupt.deferred():  # a half-started cluster cannot be closed (Dask complains at exit)
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=processes,
                                   dashboard_address=None, silence_logs=logging.CRITICAL,
                                   preload=["pumpsim.design.worker_setup"] if processes else None)
            client = Client(cluster)
    except BaseException:
        _quiet_dask()
        for x in (client, cluster):
            if x is not None:
                with contextlib.suppress(Exception):
                    x.close()
        raise
    return client, cluster


def _quiet_dask() -> None:
    """A cluster torn down mid-run logs lost tasks and closed connections, even as CRITICAL: not
    news to a user who stopped it."""
    logging.getLogger("distributed").setLevel(logging.CRITICAL + 1)


@dataclass
class RunStats:
    designs: int = 0
    batches: int = 0
    batches_skipped: int = 0
    batch_size: int = 0  # designs per batch (guided: of the first)
    guided: bool = False  # batches by guided_bounds
    workers: int = 0
    wall: float = 0.0  # evaluation phase
    compute: float = 0.0  # sum of in-task times
    setup: float = 0.0  # cluster start + pilot
    # where workers x wall - compute went (worker-seconds, from the tasks' wall-clock spans):
    idle_start: float = 0.0  # evaluation phase start -> a worker's first task (scatter, submit, dispatch)
    idle_between: float = 0.0  # between a worker's tasks (result hand-off, next task's dispatch)
    idle_end: float = 0.0  # a worker's last task -> the end (the tail, the last result's transfer and write)
    compute_cpu: float = 0.0  # CPU time of the tasks' threads: below `compute` when other processes took the cores

    @property
    def overhead_share(self) -> float:
        """Share of the workers' time (workers x wall) not spent evaluating designs."""
        if self.wall <= 0 or self.workers <= 0:
            return 0.0
        return max(0.0, 1.0 - self.compute / (self.workers * self.wall))

    @property
    def between_tasks_share(self) -> float:
        """The per-task part of overhead_share: workers' idle time between their tasks (result
        hand-off, next task's dispatch), without the run's start and end."""
        return self.idle_between / (self.workers * self.wall) if self.wall > 0 and self.workers > 0 else 0.0

    def as_dict(self):
        d = dict(self.__dict__)
        d["overhead_share"] = self.overhead_share
        d["between_tasks_share"] = self.between_tasks_share
        return d


def run_study(study, out=None, scheduler=None, workers=None, processes=True, batch_size=None,
              progress=None, on_batch=None, client=None, X=None):
    """Evaluate every design of `study` (or the rows of X) and return (DataFrame, RunStats).
    out: results folder (Parquet parts + manifest; resumes). workers=0: in this process, no Dask.
    on_batch(done, total): called after each batch is written (a test may interrupt here)."""
    scheduler = scheduler or study.scheduler
    workers = study.workers if workers is None else workers
    X = study_designs(study) if X is None else np.asarray(X, dtype=float)
    check_out_dir(out, study.study_hash())
    # one run at a time per folder (a second one fails here, before any work); the manifest is
    # read again under the lock: a run that just ended may have changed it
    with study_folder(out) if out is not None else contextlib.nullcontext():
        man = check_out_dir(out, study.study_hash())
        t0 = time.perf_counter()
        own = None
        if workers != 0 and client is None:  # fail fast on a bad address, before any work or output
            client, own = connect(scheduler, workers, processes)
        try:
            return _run(study, X, man, out, scheduler, workers, batch_size, progress, on_batch,
                        client, t0)
        except BaseException:
            _quiet_dask()
            raise
        finally:
            if own is not None:
                client.close()
                if own is not client:
                    own.close()


def _warm_workers(study, X, workers, client) -> list:
    """Each worker imports the runtime and loads its kernels while this process times the pilot."""
    warm = []
    if client is not None and workers != 0 and len(X):
        for addr in client.scheduler_info().get("workers", {}):
            warm.append(client.submit(run_batch, study, np.arange(1), X[:1], workers=[addr],
                                      allow_other_workers=False, pure=False))
    return warm


def _build_kernels(study) -> None:
    """Builds missing kernel variants once, before local workers look."""
    from ..kernels import load_kernels

    from .evaluate import _fast

    for st in structures(study):
        load_kernels(st)
        if st.model == "constrained":
            _fast(st)


def _plan(study, X, man, batch_size, client) -> Plan:
    """The batches: of the size asked (option, then study key), of a resumed run's manifest, or
    from the pilot's time per design -- equal batches of >= TASK_SECONDS on one worker,
    guided_bounds on several."""
    bs = batch_size or study.batch_size
    if man and bs and (man.get("batch_bounds") or int(man.get("batch_size") or 0) != int(bs)):
        raise ConfigError(f"the results folder holds batches laid out as {_layout(man)}, not of {int(bs)} "
                          "designs; resume it without --batch-size (and study.batch_size), or choose "
                          "another folder")
    if bs:
        return Plan(study, X, int(bs))
    if man and man.get("batch_bounds"):
        return Plan(study, X, int(man["batch_size"]), bounds=list(man["batch_bounds"]))
    if man and man.get("batch_size"):
        return Plan(study, X, int(man["batch_size"]))
    per = pilot_time_per_design(study, X) if len(X) > 1 else TASK_SECONDS
    n_workers = len(client.scheduler_info().get("workers", {})) if client is not None else 1
    if n_workers > 1:
        bounds = guided_bounds(len(X), per, n_workers)
        return Plan(study, X, bounds[1] - bounds[0], bounds=bounds)
    return Plan(study, X, max(1, math.ceil(TASK_SECONDS / per)))


def _layout(man) -> str:
    if man.get("batch_bounds"):
        return f"guided batches ({man['batch_bounds'][1]} designs first, shrinking)"
    return f"batches of {man.get('batch_size')} designs"


def _idle(stats, spans, t_start, t_end) -> None:
    """Splits the workers' idle time (workers x wall - compute) by where it falls: before a
    worker's first task, between its tasks, after its last (spans: (worker, start, stop, cpu))."""
    by_worker: dict = {}
    for w, a, b, cpu in spans:
        by_worker.setdefault(w, []).append((a, b))
        stats.compute_cpu += cpu
    for iv in by_worker.values():
        iv.sort()
        stats.idle_start += max(0.0, iv[0][0] - t_start)
        stats.idle_between += sum(max(0.0, b[0] - a[1]) for a, b in zip(iv, iv[1:]))
        stats.idle_end += max(0.0, t_end - iv[-1][1])
    stats.idle_start += max(0, stats.workers - len(by_worker)) * (t_end - t_start)  # never given a task


def _run(study, X, man, out, scheduler, workers, batch_size, progress, on_batch, client, t0):
    import pandas as pd

    stats = RunStats(designs=len(X))
    interrupt.progress(_how_far(0, len(X), out))
    _warm = _warm_workers(study, X, workers, client)  # held so the warm-up tasks are not released
    if study.function is None and not scheduler:
        _build_kernels(study)
    if man and study.function is None and not scheduler and man.get("kernel_keys") != kernel_keys(study):
        raise ConfigError(f"--out '{out}' was written with other compiled kernels "
                          f"({man.get('kernel_keys')}); its parts cannot be mixed with new ones: "
                          "choose another folder or remove it")
    plan = _plan(study, X, man, batch_size, client)
    stats.batch_size, stats.batches = min(plan.batch_size, max(1, len(X))), plan.n_batches
    stats.guided = plan.bounds is not None
    folder = Path(out) if out else None
    done = set()
    if folder is not None:
        folder.mkdir(exist_ok=True)
        done = {b for b in range(plan.n_batches) if (folder / PART.format(b)).exists()}
        write_manifest(folder, study, plan, "running")
    stats.batches_skipped = len(done)
    todo = [b for b in range(plan.n_batches) if b not in done]
    tables = {}
    bar = _bar(progress, len(todo))
    written = [0]
    done_designs = [sum(len(plan.batch(b)[0]) for b in done)]
    interrupt.progress(_how_far(done_designs[0], len(X), folder))

    spans = []

    def finish(b, table, seconds, span):
        stats.compute += seconds
        spans.append(span)
        if folder is not None:
            import pyarrow.parquet as pq

            with guard("writing the results part", folder / PART.format(b), "--out"):
                with atomic_path(folder / PART.format(b)) as tmp:
                    pq.write_table(table, tmp)
        tables[b] = table
        written[0] += 1
        done_designs[0] += len(table.column("design").unique()) if len(table) else 0
        interrupt.progress(_how_far(done_designs[0], len(X), folder))
        if bar is not None:
            bar.update(1)
        if on_batch is not None:
            on_batch(written[0], len(todo))

    try:
        stats.setup = time.perf_counter() - t0
        t1, w1 = time.perf_counter(), time.time()
        _evaluate(study, plan, todo, workers, client, stats, finish)
        stats.wall = time.perf_counter() - t1
        _idle(stats, spans, w1, w1 + stats.wall)
    except interrupt.Interrupted as e:
        if folder is not None and done_designs[0]:
            e.notes.append(_kept(done_designs[0], folder))
        raise
    except OutputError as e:  # a full disk, say: what was written stays usable
        if folder is None or not done_designs[0]:
            raise
        raise OutputError(f"{e}; {_kept(done_designs[0], folder)}") from None
    finally:
        if bar is not None:
            bar.close()
    if folder is not None:
        df = read_results(folder)
        gaps = coverage_text(coverage(df, len(X)))
        write_manifest(folder, study, plan, "complete" if gaps is None else "incomplete", stats)
        if gaps:  # parts from elsewhere (another layout, a copied file): the table is not this study
            raise SolverError(f"the results folder '{folder}' does not hold every design once: {gaps}; "
                              "remove it and run the study again")
        return df, stats
    parts = [tables[b].to_pandas() for b in sorted(tables)]
    df = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=[c for c, _ in columns(study)])
    return _ordered(df), stats


def _kept(done, folder) -> str:
    return f"the {done} designs done are kept in '{folder}' (the same command resumes there)"


def _how_far(done, total, folder) -> str:
    return f"with {done} of {total} designs done" + ("" if folder is not None else " (none kept: no --out folder)")


def _evaluate(study, plan, todo, workers, client, stats, finish) -> None:
    """The batches `todo`, here (workers=0) or on the cluster; finish(b, table, seconds, span)
    takes each as it completes."""
    if workers == 0 or not todo:
        stats.workers = 1
        for b in todo:
            ids, Xb = plan.batch(b)
            finish(b, *run_batch(study, ids, Xb)[1:])
        return
    from dask.distributed import as_completed

    stats.workers = max(1, len(client.scheduler_info().get("workers", {})) or (workers or 1))
    sfut = client.scatter(study, broadcast=True)
    futs = {}
    for b in todo:
        ids, Xb = plan.batch(b)
        futs[client.submit(run_batch, sfut, ids, Xb, pure=False)] = b
    for fut in as_completed(futs):  # a batch a lost worker held is run again elsewhere: once here
        finish(futs[fut], *fut.result()[1:])


def _bar(progress, total):
    if progress is False or (progress is None and not sys.stderr.isatty()):
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="batch", file=sys.stderr, leave=False, desc="designs")


def write_manifest(folder, study, plan, status, stats=None):
    man = {
        "study_hash": study.study_hash(), "study": study.path, "config": study.config_path,
        "function": study.function, "sampler": study.sampler, "seed": study.seed,
        "samples": study.samples, "designs": int(len(plan.X)), "batch_size": plan.batch_size,
        "batch_bounds": plan.bounds, "batches": plan.n_batches, "part_pattern": PART, "keys": study.keys,
        "speeds": study.speeds, "outputs": study.outputs, "model": study.model,
        "revolution_samples": study.revolution_samples,
        "limits": {k: list(v) for k, v in study.limits.items()},
        "kernel_keys": kernel_keys(study), "versions": package_versions(),
        "columns": [c for c, _ in columns(study)], "status": status,
    }
    if stats is not None:
        man["run"] = stats.as_dict()
    with guard("writing the study manifest", folder / MANIFEST, "--out"):
        write_text(folder / MANIFEST, json.dumps(man, indent=1))


def _ordered(df):
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
    df = _ordered(df)
    if arrays:
        return {c: df[c].to_numpy() for c in df.columns}
    return df
