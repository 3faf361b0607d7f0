"""SIGINT and SIGTERM end a run as their own outcome: exit 130 (143 for SIGTERM), never a failure.

`handling()` (the command line) installs a handler that records the signal and raises
`Interrupted` in the main thread. Native code that calls back into Python turns an exception
raised there into its own failure (CasADi's SUNDIALS interfaces check for signals in their
callbacks: CV_RHSFUNC_FAIL, and SUNDIALS prints its complaint), so an integrator call runs
`deferred()`: the first signal only sets the flag, the call ends its (short) chunk, and the check
after it raises; a second signal raises at once. Every place that turns a native failure into
SolverError, or keeps going past one failed design, asks `check()` first.

`progress(text)` records how far the run got (simulated time reached, designs done); the message
the command line prints names it.
"""
from __future__ import annotations

import atexit
import contextlib
import os
import signal
import sys
import threading

_state = {"signal": None, "progress": None, "defer": 0, "stage": None, "written": [], "ran": False, "guarded": False}
SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(KeyboardInterrupt):
    """The run was stopped by a signal. A KeyboardInterrupt, so `except Exception` (one design's
    failure, a report's provenance) never swallows it. partial: what was computed so far."""

    def __init__(self, signum=None, partial=None):
        self.signum = int(signum or _state["signal"] or signal.SIGINT)
        self.partial = partial
        self.notes: list[str] = []  # what the command kept (e.g. a --keep-partial file)
        super().__init__(signal.Signals(self.signum).name)

    @property
    def exit_status(self) -> int:
        return 128 + self.signum

    def message(self) -> str:
        """One line: the signal, how far the run got, what is left on disk."""
        where = _state["progress"]
        unsaid = [w for w in _state["written"] if not any(w in n for n in self.notes)]  # (a note may name it)
        parts = self.notes + ([", ".join(unsaid) + " written and complete"] if unsaid else [])
        kept = "; ".join(parts) if parts else "no output file written"
        return (f"interrupted by {signal.Signals(self.signum).name}"
                + (f" {where}" if where else "") + f"; {kept}")


def written(paths) -> None:
    """Outputs this run has put in place whole: an interruption after them says so."""
    _state["written"] += [str(p) for p in paths]


def written_outputs() -> list[str]:
    return list(_state["written"])


def pending() -> int | None:
    """The signal received during this run, if any."""
    return _state["signal"]


def check(partial=None) -> None:
    """Raise Interrupted if a signal arrived (call where a native failure or a caught exception
    may stand for it)."""
    if _state["signal"] is not None:
        raise Interrupted(_state["signal"], partial) from None


def progress(text: str, detail: bool = False) -> None:
    """How far the run got, in words that follow 'interrupted by SIGINT' (e.g. 'at t = 0.2 s').
    detail=True: how far one model run got (a simulation's time); inside a `stage` it is said after
    the stage's progress, which it does not replace (a fit whose model runs are simulations)."""
    if detail and _state["stage"] is not None:
        _state["progress"] = f"{_state['stage']}; its last model run at {text.removeprefix('at ')}"
        return
    _state["progress"] = text
    if _state["stage"] is not None:
        _state["stage"] = text


@contextlib.contextmanager
def stage(text: str):
    """A run made of model runs (a bench-log fit of pump-down simulations): `text` is its progress
    until its own progress() replaces it; a model run's progress(detail=True) is added to it."""
    outer = _state["stage"]
    _state["stage"] = _state["progress"] = text
    try:
        yield
    finally:
        _state["stage"] = outer


def _handler(signum, frame):
    first = _state["signal"] is None
    _state["signal"] = signum
    if first and _state["defer"]:
        return  # inside native code: raised by `deferred` when the call returns
    raise Interrupted(signum)


@contextlib.contextmanager
def deferred():
    """Run a native call (an integrator's) whose callbacks must not see the exception; raise
    Interrupted after it if a signal came meanwhile."""
    _state["defer"] += 1
    try:
        yield
    finally:
        _state["defer"] -= 1
    check()


def _unraisable(u) -> None:
    """The signal's exception raised where Python cannot propagate it (a garbage-collector callback,
    a __del__: Dask's GC diagnosis) is not printed as 'Exception ignored': the signal stays recorded
    and the command reports it once, where it can (pending() after the command)."""
    if isinstance(u.exc_value, KeyboardInterrupt) and _state["signal"] is not None:
        return
    sys.__unraisablehook__(u)


@contextlib.contextmanager
def unsplit():
    """A block a signal must not split (outputs renamed into place together): a signal arriving
    meanwhile is raised after it. One from before -- an interruption's clean-up writing what it
    keeps -- is not raised again."""
    before = _state["signal"]
    _state["defer"] += 1
    try:
        yield
    finally:
        _state["defer"] -= 1
    if before is None and _state["signal"] is not None:
        raise Interrupted(_state["signal"]) from None


def _outside(signum, frame):
    """A signal outside a command's own handling: while the program starts -- nothing written --
    or after the run, its outputs written (a Dask cluster closing). Its status, one line."""
    name = signal.Signals(signum).name
    if _state["ran"]:
        msg = f"interrupted by {name} while exiting; the run had ended, its outputs are written"
    else:
        msg = f"interrupted by {name} while starting; nothing was written"
    print(f"pumpsim: {msg}", file=sys.stderr, flush=True)
    os._exit(128 + signum)


def guard_process() -> None:
    """For the `pumpsim` program's process (not a library caller's): SIGINT and SIGTERM outside a
    command's handling give their status and one line (_outside) instead of the default action, a
    silent kill. Set before the command runs, so that its handling restores it at the end and no
    signal finds the default action in between. A signal ignored at the start stays ignored.
    Once per process (`python -m pumpsim` sets it before the command line imports, then runs the
    console script's entry, which sets it too)."""
    if _state["guarded"]:
        return
    _state["guarded"] = True
    for s in SIGNALS:
        if signal.getsignal(s) is not signal.SIG_IGN:
            signal.signal(s, _outside)
    atexit.register(_ignore_signals_in_teardown)  # registered first: runs after every later atexit function


def _ignore_signals_in_teardown() -> None:
    """The interpreter's last teardown (after the atexit functions) resets the handlers it set to
    the default action, a silent kill -- of the whole process, whichever thread (a Dask loop's,
    still alive) takes the signal -- but leaves an ignored signal ignored: ignore SIGINT and
    SIGTERM from here on. The run has ended and the process exits with its own status."""
    for s in SIGNALS:
        signal.signal(s, signal.SIG_IGN)


@contextlib.contextmanager
def handling():
    """Route SIGINT and SIGTERM to Interrupted for the block (main thread only). A signal that is
    ignored when the run starts (nohup, a background job) stays ignored."""
    _state.update(signal=None, progress=None, defer=0, stage=None, written=[], ran=True)
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    for s in SIGNALS:
        current = signal.getsignal(s)
        if current == signal.SIG_IGN:
            continue
        old[s] = current
        signal.signal(s, _handler)
    hook = sys.unraisablehook
    sys.unraisablehook = _unraisable
    try:
        yield
    finally:
        sys.unraisablehook = hook
        for s, h in old.items():
            signal.signal(s, h)
        _state["signal"] = None  # a run's signal ends with it: a later deferred() outside must not see it
