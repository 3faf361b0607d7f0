"""Exclusive outputs: one run at a time writes a study folder or an output file.

An OS file lock (the `filelock` package: flock on POSIX, msvcrt on Windows) is taken before any
work and held until the run ends; the OS drops it when the process dies, so a killed run leaves
no stale lock, and a rerun resumes as soon as the first run is gone. Beside the lock an info file
names the holder (pid, host, command, start), which a refused second run prints (exit 2).

- a study folder (`sweep --out DIR`): the lock is DIR/.pumpsim.lock, so runs on other hosts
  sharing the folder see it too;
- an output file: the lock lives in a per-user folder under the system's temporary folder
  (TMPDIR), named by the file's absolute path, so nothing is added beside the user's files.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import socket
import sys
import tempfile
import time
from pathlib import Path

from . import fsfaults
from .errors import OutputError

LOCK = ".pumpsim.lock"
INFO = ".pumpsim.lock.info"
LOCK_FILES = (LOCK, INFO)  # what a study folder holds besides its results while a run is on
_session: list = []  # the command line's (ExitStack, paths held): hold_files registers there


def _holder(info: Path) -> str:
    try:
        d = json.loads(info.read_text())
        return (f"pid {d['pid']} on host {d['host']}, started {d['started']}: {d['command']}; wait for "
                f"it to end (or stop it: kill {d['pid']} on {d['host']})")
    except (OSError, ValueError, KeyError, TypeError):
        return "it has not yet recorded its process; wait for it to end"


@contextlib.contextmanager
def _locked(lock_path: Path, info_path: Path, what: str, option: str, elsewhere: str):
    from filelock import FileLock, Timeout

    lock = FileLock(str(lock_path), timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise OutputError(f"{option} {what} is being written by another pumpsim run ({_holder(info_path)}), "
                          f"or {elsewhere}") from None
    except OSError as e:
        raise fsfaults.error(e, "locking", lock_path, option) from None
    try:
        info = {"pid": os.getpid(), "host": socket.gethostname(),
                "started": time.strftime("%Y-%m-%d %H:%M:%S"),
                "command": " ".join(["pumpsim", *sys.argv[1:]])[:300]}
        with fsfaults.guard("writing the lock record", info_path, option):
            info_path.write_text(json.dumps(info))
        yield
    finally:
        with contextlib.suppress(OSError):
            info_path.unlink()
        lock.release()


@contextlib.contextmanager
def study_folder(folder, option: str = "--out"):
    """Hold `folder` for this run (created if missing; removed again if the run leaves nothing in
    it). Raises OutputError (exit 2) when another run holds it or it cannot be written."""
    d = Path(folder)
    created = not d.exists()
    with fsfaults.guard("creating the results folder", d, option):
        d.mkdir(exist_ok=True)
    try:
        with _locked(d / LOCK, d / INFO, f"'{d}'", option, "choose another folder"):
            yield d
    finally:
        if created:
            with contextlib.suppress(OSError):
                if not any(p.name not in LOCK_FILES for p in d.iterdir()):
                    for name in LOCK_FILES:
                        with contextlib.suppress(FileNotFoundError):
                            (d / name).unlink()
                    d.rmdir()


def holder_of(folder) -> str | None:
    """Who holds a study folder now (None: nobody), without taking it."""
    from filelock import FileLock, Timeout

    d = Path(folder)
    if not (d / LOCK).exists():
        return None
    lock = FileLock(str(d / LOCK), timeout=0)
    try:
        lock.acquire()
    except Timeout:
        return _holder(d / INFO)
    except OSError:  # a read-only folder: no run can be writing it
        return None
    lock.release()
    return None


def _lock_dir() -> Path:
    # one folder per user: filelock refuses a lock file another account owns in a shared folder.
    # Its files (empty, one per output path ever written) stay: removing a lock file races with
    # a run that has just opened it
    uid = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
    d = Path(tempfile.gettempdir()) / f"pumpsim-locks-{uid}"
    with fsfaults.guard("creating the lock folder", d, "TMPDIR"):
        d.mkdir(mode=0o700, exist_ok=True)
    return d


def file_lock(path, option: str):
    """A context manager holding output file `path` for the run."""
    key = hashlib.sha256(os.path.abspath(path).encode()).hexdigest()[:24]
    d = _lock_dir()
    return _locked(d / f"{key}.lock", d / f"{key}.info", f"'{path}'", option, "give another file name")


@contextlib.contextmanager
def session():
    """The command line's scope: output files held with hold_files are released at its end."""
    with contextlib.ExitStack() as stack:
        entry = (stack, set())
        _session.append(entry)
        try:
            yield
        finally:
            _session.remove(entry)


def hold_files(paths: dict) -> None:
    """Hold every output file {option: path (None: not given)} until the session ends (nothing
    outside a session: the library API leaves locking to its caller)."""
    if not _session:
        return
    stack, held = _session[-1]
    for option, path in paths.items():
        if path is not None and os.path.abspath(path) not in held:  # a second flock would refuse us
            stack.enter_context(file_lock(path, option))
            held.add(os.path.abspath(path))
