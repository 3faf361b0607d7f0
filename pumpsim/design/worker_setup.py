"""Preloaded into each worker process of the local Dask cluster (cluster.connect).

A terminal's Ctrl-C reaches every process of its process group: the workers ignore it, and the
run's own process, which owns the interruption, closes them (otherwise each worker prints its own
KeyboardInterrupt traceback while the client is shutting the cluster down).

The worker also imports what a task runs (NumPy, CasADi, the kernels' loader, Arrow) as it
starts: the cluster starts while the run's own process loads the kernels and times the pilot
(execute.run_study), so the first task does not pay for the imports."""
import signal
import threading


def dask_setup(worker):
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    import pyarrow  # noqa: F401

    from pumpsim.design import evaluate, store  # noqa: F401
