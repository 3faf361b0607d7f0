"""The Dask cluster a study runs on: a new LocalCluster (one single-threaded worker process per
core) or an existing scheduler, reached within CONNECT_TIMEOUT or refused with the reason."""
from __future__ import annotations

import contextlib
import logging
import os
import sys

from .. import interrupt
from ..errors import ConfigError

CONNECT_TIMEOUT = 5.0  # s: an unreachable scheduler fails this fast


def probe_scheduler(address):
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
        raise ConfigError(f"scheduler: '{address}' is not a scheduler address (tcp://HOST:PORT)")
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
        probe_scheduler(scheduler)
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
        quiet_dask()
        for x in (client, cluster):
            if x is not None:
                with contextlib.suppress(Exception):
                    x.close()
        raise
    return client, cluster


def quiet_dask() -> None:
    """A cluster torn down mid-run logs lost tasks and closed connections, even as CRITICAL: not
    news to a user who stopped it."""
    logging.getLogger("distributed").setLevel(logging.CRITICAL + 1)


def worker_name() -> str:
    if "distributed" not in sys.modules:  # a process that never imported Dask runs no Dask task
        return "local"
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):  # not inside a Dask task
        return "local"
