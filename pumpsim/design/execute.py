"""Run a study's designs on dask.distributed and keep the results as Parquet parts.

- Default: a LocalCluster with one single-threaded worker process per core; `scheduler` (an
  address, or `study.scheduler`) runs the same study on an existing cluster (cluster.py).
- Tasks are batches of designs sized from a pilot run's time per design: on several workers by
  guided self-scheduling (guided_bounds: large batches first, >= TASK_SECONDS while more than two
  per worker remain, shrinking to ~TAIL_TASK_SECONDS so the workers finish together), else equal
  batches of >= TASK_SECONDS. A task carries the study (plain data) and its designs' key values;
  the worker loads or builds the compiled variant from the hashed cache itself. Compiled
  functions never travel. RunStats splits the workers' idle time by where it falls.
- Every design's values are fixed on the client before any task runs (sampling.py), and each
  design is evaluated on its own, so the table is the same for 1 or 64 workers and any batching.
- Each finished batch is written by the client as a Parquet part of the results folder
  (store.py); a rerun with the same study skips the parts already there (resume).
"""
from __future__ import annotations

import contextlib
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import interrupt
from ..errors import ConfigError, OutputError, SolverError
from ..fsfaults import guard
from ..io import atomic_path
from ..locks import study_folder
from .cluster import connect, quiet_dask, worker_name
from .vector import covered
from .sampling import design_matrix
from .store import (PART, check_out_dir, columns, ordered, read_manifest, read_results,  # noqa: F401 (read_manifest: the CLI)
                    write_manifest)
from .summary import coverage, coverage_text

TASK_SECONDS = 0.5  # work per task: Dask's per-task cost (~1-5 ms) stays below 1 %
TAIL_TASK_SECONDS = 0.1  # the last tasks (guided_bounds): shorter, so the workers finish together
# guided_bounds: a batch is 1/(this x workers) of what remains. 2 lets the first batch hold a
# quarter of a 2-worker study, which a worker slowed by other processes then holds up (measured:
# 15 % idle at the end on the shared machine); 4 keeps the first to an eighth.
GUIDED_SHARE = 4
PILOT_DESIGNS = 6
PILOT_BATCH = 64  # designs timed when PILOT_DESIGNS take little (evaluate.BATCH_DESIGNS per kernel call)
# About what a LocalCluster's start costs (each worker process imports the runtime). A study left
# to choose its workers runs in this process unless its designs' CPU time T pays for that start S
# on W workers: S + T / W < T, i.e. T > S W / (W - 1) (worth_a_cluster). CPU, not wall time: on a
# shared machine the wall time of a pilot says more about the other processes than about the study.
IN_PROCESS_SECONDS = 2.0


def worth_a_cluster(cpu_seconds: float, workers: int) -> bool:
    """Whether W local workers would finish work of `cpu_seconds` sooner than this process,
    counting their start (IN_PROCESS_SECONDS; a single worker never does)."""
    return workers > 1 and cpu_seconds > IN_PROCESS_SECONDS * workers / (workers - 1)


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
    from .evaluate import fast_kernel, one_vane

    out = {}
    for st in structures(study):
        out[st.variant] = load_kernels(st).key
        fast = fast_kernel(st) if st.model == "constrained" else None
        if fast is not None:
            out[f"{st.variant} (SIMD)"] = fast.key
        one = one_vane(st) if st.model == "constrained" else None
        if one is not None:
            out[f"{st.variant} (SIMD, one vane)"] = one.fast.key
    return out


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
    from .evaluate import evaluate_table

    w0, t0, c0 = time.time(), time.perf_counter(), time.thread_time()
    table = evaluate_table(study, X, ids)
    sec = time.perf_counter() - t0
    return ids[0], table, sec, (worker_name(), w0, w0 + sec, time.thread_time() - c0)


def pilot_time_per_design(study, X, repeats=3) -> tuple[float, float]:
    """(wall, CPU) seconds per design on this process (which also builds any missing variant into
    the cache before the workers look for it): the least of `repeats` timings of PILOT_DESIGNS
    designs, as the machine may be shared and a disturbed timing only ever reads long."""
    from .evaluate import evaluate_table

    evaluate_table(study, X[:1], np.arange(1))  # load kernels, make the maps
    n = min(len(X), PILOT_DESIGNS)
    best = _best_time(study, X[:n], repeats)
    if best[0] < 0.05 * TASK_SECONDS and len(X) > n:  # fast designs: a call's own cost would weigh on
        n = min(len(X), PILOT_BATCH)  # a few; time a kernel batch's worth instead
        best = _best_time(study, X[:n], repeats)
    return max(best[0] / n, 1e-6), max(best[1] / n, 1e-6)


def _best_time(study, X, repeats) -> tuple[float, float]:
    from .evaluate import evaluate_table

    best = cpu = math.inf
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.thread_time()
        evaluate_table(study, X, np.arange(len(X)))
        best, cpu = min(best, time.perf_counter() - t0), min(cpu, time.thread_time() - c0)
        if best > 2 * TASK_SECONDS:  # slow designs: one timing says enough
            break
    return best, cpu


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
    # cheap designs (parameter vectors): timed before any cluster starts, which they may not need
    lazy = workers is None and not scheduler and client is None and covered(study)
    X = study_designs(study) if X is None else np.asarray(X, dtype=float)
    check_out_dir(out, study.study_hash())
    # one run at a time per folder (a second one fails here, before any work); the manifest is
    # read again under the lock: a run that just ended may have changed it
    with study_folder(out) if out is not None else contextlib.nullcontext():
        man = check_out_dir(out, study.study_hash())
        t0 = time.perf_counter()
        starting = _Cluster(scheduler, workers, processes, client,
                            lambda c: _warm_workers(study, X, workers, c), lazy)
        try:
            return _run(study, X, man, out, scheduler, workers, batch_size, progress, on_batch,
                        starting, t0)
        except BaseException:
            quiet_dask()
            raise
        finally:
            starting.close()


class _Cluster:
    """The run's Dask client: given, or connected now (a scheduler address: fails fast on a bad
    one, before any work or output), or a LocalCluster started in a thread while this process
    builds or loads the kernels and times the pilot (its worker processes import the runtime as
    they start: worker_setup). warm(client): the warm-up tasks, submitted as soon as there is a
    client (held here: they are not released before they ran). lazy: the LocalCluster starts when
    `get()` first asks for it, unless `stay_local()` came first (then there is none: workers 0).
    `get()` waits for the client; `close()` closes what the run started."""

    def __init__(self, scheduler, workers, processes, client, warm, lazy=False):
        self.client, self.own, self.thread, self.error, self.warm = client, None, None, None, []
        self.warm_up = warm
        self.lazy, self.local = (workers, processes) if lazy else None, workers == 0
        if workers == 0 or lazy:
            return
        if client is not None or scheduler:
            if client is None:
                self.client, self.own = connect(scheduler, workers, processes)
            self.warm = warm(self.client)
            return
        self._start(workers, processes)

    def _start(self, workers, processes):
        import threading

        def start():
            try:
                self.client, self.own = connect(None, workers, processes)
                self.warm = self.warm_up(self.client)
            except BaseException as e:  # noqa: BLE001 - raised again by get() in the run's thread
                self.error = e

        self.thread = threading.Thread(target=start, name="pumpsim-cluster-start", daemon=True)
        self.thread.start()

    def stay_local(self):
        self.lazy, self.local = None, True

    def get(self):
        if self.lazy is not None:
            self._start(*self.lazy)
            self.lazy = None
        if self.thread is not None:
            self.thread.join()
            self.thread = None
        if self.error is not None:
            raise self.error
        return self.client

    def close(self):
        if self.thread is not None:  # the run failed while the cluster started: wait, then close it
            self.thread.join()
        if self.own is not None:
            self.client.close()
            if self.own is not self.client:
                self.own.close()


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

    from .evaluate import fast_kernel, one_vane

    for st in structures(study):
        load_kernels(st)
        if st.model == "constrained":
            fast_kernel(st)
            one_vane(st)


def _plan(study, X, man, batch_size, starting) -> Plan:
    """The batches: of the size asked (option, then study key), of a resumed run's manifest, or
    from the pilot's time per design -- equal batches of >= TASK_SECONDS on one worker (or in
    this process: a lazy cluster not worth starting, IN_PROCESS_SECONDS), guided_bounds on
    several."""
    bs = batch_size or study.batch_size
    if man and bs and (man.get("batch_bounds") or int(man.get("batch_size") or 0) != int(bs)):
        raise ConfigError(f"the results folder holds batches laid out as {_layout(man)}, not of {int(bs)} "
                          "designs; resume it without a batch size (option or study.batch_size), or choose "
                          "another folder")
    if bs:
        return Plan(study, X, int(bs))
    if man and man.get("batch_bounds"):
        return Plan(study, X, int(man["batch_size"]), bounds=list(man["batch_bounds"]))
    if man and man.get("batch_size"):
        return Plan(study, X, int(man["batch_size"]))
    # in this process the batches only cut the results into parts: one timing sizes them; a
    # cluster's batches balance its workers: the least of three
    quick = starting.local or starting.lazy is not None
    per, cpu = pilot_time_per_design(study, X, 1 if quick else 3) if len(X) > 1 else (TASK_SECONDS, TASK_SECONDS)
    if starting.lazy is not None and not worth_a_cluster(cpu * len(X), starting.lazy[0] or os.cpu_count() or 1):
        starting.stay_local()
    elif starting.lazy is not None and len(X) > 1:
        per, cpu = pilot_time_per_design(study, X)
    client = starting.get()  # (a LocalCluster started meanwhile)
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


class _Collector:
    """Takes each finished batch: writes its part (when there is a folder), keeps its table,
    counts it for the progress bar, the interruption note and the test hook."""

    def __init__(self, folder, n_designs, todo, done_designs, stats, progress, on_batch):
        self.folder, self.n_designs, self.todo, self.stats = folder, n_designs, todo, stats
        self.tables, self.spans, self.written, self.done_designs = {}, [], 0, done_designs
        self.bar, self.on_batch = _bar(progress, len(todo)), on_batch
        interrupt.progress(_how_far(done_designs, n_designs, folder))

    def __call__(self, b, table, seconds, span):
        self.stats.compute += seconds
        self.spans.append(span)
        with interrupt.deferred():  # a part on disk is a part counted: a signal waits for both
            if self.folder is not None:
                import pyarrow.parquet as pq

                with guard("writing the results part", self.folder / PART.format(b), "--out"):
                    with atomic_path(self.folder / PART.format(b)) as tmp:
                        pq.write_table(table, tmp)
            self.tables[b] = table
            self.written += 1
            self.done_designs += len(table.column("design").unique()) if len(table) else 0
            interrupt.progress(_how_far(self.done_designs, self.n_designs, self.folder))
        if self.bar is not None:
            self.bar.update(1)
        if self.on_batch is not None:
            self.on_batch(self.written, len(self.todo))


def _check_kernels(study, man, out, scheduler) -> None:
    """Builds missing variants here (not on a remote cluster) and refuses to mix a resumed
    folder's parts with results of other compiled kernels."""
    if study.function is not None or scheduler:
        return
    _build_kernels(study)
    if man and man.get("kernel_keys") != kernel_keys(study):
        raise ConfigError(f"results folder '{out}' was written with other compiled kernels "
                          f"({man.get('kernel_keys')}); its parts cannot be mixed with new ones: "
                          "choose another folder or remove it")


def _manifest(folder, study, plan, status, stats=None) -> None:
    keys = kernel_keys(study) if study.function is None else {}
    write_manifest(folder, study, plan, status, keys, stats)


def _run(study, X, man, out, scheduler, workers, batch_size, progress, on_batch, starting, t0):
    stats = RunStats(designs=len(X))
    interrupt.progress(_how_far(0, len(X), out))
    _check_kernels(study, man, out, scheduler)  # (the workers warm up meanwhile: _Cluster)
    plan = _plan(study, X, man, batch_size, starting)
    client = starting.get()
    workers = 0 if starting.local else workers
    stats.batch_size, stats.batches = min(plan.batch_size, max(1, len(X))), plan.n_batches
    stats.guided = plan.bounds is not None
    folder = Path(out) if out else None
    done = set()
    if folder is not None:
        folder.mkdir(exist_ok=True)
        done = {b for b in range(plan.n_batches) if (folder / PART.format(b)).exists()}
        _manifest(folder, study, plan, "running")
    stats.batches_skipped = len(done)
    todo = [b for b in range(plan.n_batches) if b not in done]
    got = _Collector(folder, len(X), todo, sum(len(plan.batch(b)[0]) for b in done), stats, progress, on_batch)
    try:
        stats.setup = time.perf_counter() - t0
        t1, w1 = time.perf_counter(), time.time()
        _evaluate(study, plan, todo, workers, client, stats, got)
        stats.wall = time.perf_counter() - t1
        _idle(stats, got.spans, w1, w1 + stats.wall)
        return _table(study, plan, folder, got.tables, stats), stats  # (a signal here: the parts stay)
    except interrupt.Interrupted as e:
        if folder is not None and got.done_designs:
            e.notes.append(kept_note(got.done_designs, folder))
        raise
    except OutputError as e:  # a full disk, say: what was written stays usable
        if folder is None or not got.done_designs:
            raise
        raise OutputError(f"{e}; {kept_note(got.done_designs, folder)}") from None
    finally:
        if got.bar is not None:
            got.bar.close()


def _table(study, plan, folder, tables, stats):
    """The result table: joined from the batches' tables when they are all the folder holds (or
    there is no folder), else read back from the folder (resumed parts); with a folder, the
    manifest is marked complete."""
    import pandas as pd

    if folder is not None:
        only_ours = len(tables) == plan.n_batches == len(list(folder.glob(PART.replace("{:05d}", "*"))))
        df = _table(study, plan, None, tables, stats) if only_ours else read_results(folder)
        gaps = coverage_text(coverage(df, len(plan.X)))
        _manifest(folder, study, plan, "complete" if gaps is None else "incomplete", stats)
        if gaps:  # parts from elsewhere (another layout, a copied file): the table is not this study
            raise SolverError(f"the results folder '{folder}' does not hold every design once: {gaps}; "
                              "remove it and run the study again")
        return df
    parts = [tables[b].to_pandas() for b in sorted(tables)]
    df = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=[c for c, _ in columns(study)])
    return ordered(df)


def kept_note(done, folder) -> str:
    """What an interrupted or failed run left in its results folder, for its message."""
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


