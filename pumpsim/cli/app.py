"""The `pumpsim` parser and the run of one command, with its exit status.

Exit status: 0 success; 2 bad input (config, data, options, unit mistakes, output paths: the
message names the key, row, file or option and the limit; nothing is written) or a file-system
fault the user can fix (read-only, missing, full, no permission, an output another run holds: the
path, the operation and what to do); 1 a numerical failure (the message names the time and
state) or a fit whose answer must not be used as is (not converged, ended on a parameter bound,
or a named parameter not identifiable from the data: the outputs are still written, complete, and
say so); 130 / 143 interrupted by SIGINT / SIGTERM (one line: how far the run got, what is kept;
no partial file); 141 the reader of the output went away.
"""
from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time

from . import design, diagnose, example, identify, kernels, pumpdown, simulate, study
from .common import LOG, Parser, Version, add_verbosity, messages

# One module per command: its `register(sub)` adds the parser and sets `func`. New commands append here.
COMMANDS = [simulate, identify, diagnose, study, design, pumpdown, kernels, example]


def build_parser():
    ap = Parser(prog="pumpsim", description="Rotary vane vacuum pump simulation and identification. "
                "Config values are SI (m, kg, s, rad, N); exit status 0 ok, 2 bad input, 1 numerical "
                "failure or unusable fit.")
    ap.add_argument("--version", action=Version, help="show program's version number and exit")
    add_verbosity(ap)
    sub = ap.add_subparsers(dest="command", required=True, parser_class=Parser)
    for command in COMMANDS:
        command.register(sub)
    for p in sub.choices.values():  # -v / -q also after the command's name
        add_verbosity(p, default=argparse.SUPPRESS)
    return ap


def console() -> int:
    """The `pumpsim` program (its console script; `python -m pumpsim`): main() with a status for a
    signal outside the command's own handling too (interrupt.guard_process), stdout flushed."""
    from .. import interrupt

    interrupt.guard_process()
    status = main()
    sys.stdout.flush()
    return status


def main(argv=None) -> int:
    """Run the command line with `argv` (default sys.argv[1:]); returns the exit status."""
    from .. import interrupt
    from ..blas import one_blas_thread

    one_blas_thread()
    try:
        with interrupt.handling():  # from the start: a signal while the command imports is handled too
            return _main(argv)
    except KeyboardInterrupt as e:  # Interrupted, or SIGINT outside the handler's scope
        return report_interrupt(e if isinstance(e, interrupt.Interrupted) else interrupt.Interrupted())


class _PipeSafeStdout:
    """sys.stdout whose reader may leave (`pumpsim ... | head -1`): from then on the printed text
    goes to /dev/null and the command goes on, so the files it was asked to write are written."""

    def __init__(self, stream):
        self._stream = stream

    def _gone(self):
        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), self._stream.fileno())

    def write(self, text):
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._gone()
            return len(text)

    def flush(self):
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._gone()

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _main(argv) -> int:
    if not isinstance(sys.stdout, _PipeSafeStdout) and sys.stdout is not None:
        sys.stdout = _PipeSafeStdout(sys.stdout)
    ap = build_parser()
    try:
        a = ap.parse_args(argv)
    except SystemExit as e:  # --help, --version, bad options (status 2, message printed)
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
    from .. import interrupt, locks

    try:
        with messages(a.verbose, a.quiet), locks.session():
            start = time.perf_counter()
            status = a.func(a)
            LOG.debug("%s took %.2f s (exit status %d)", a.command, time.perf_counter() - start, status)
            if interrupt.pending():  # a signal some native code took for its own failure, then went on
                late = interrupt.Interrupted()
                if not interrupt.written_outputs():  # (else the message names them as written and complete)
                    late.notes.append("the run had ended: its outputs are written, complete")
                raise late
            return status
    except BrokenPipeError:  # the reader of our output went away (`| head`): stop quietly
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except Exception as e:
        if interrupt.pending():  # the failure is the signal's doing (a solver callback's, say)
            return report_interrupt(interrupt.Interrupted())
        return report_failure(e)


def report_failure(e: Exception) -> int:
    """One line on stderr for an exception that ended a command, and the exit status it maps to."""
    from .. import fsfaults
    from ..errors import PumpsimError

    if isinstance(e, PumpsimError):
        print(f"pumpsim: error: {e}", file=sys.stderr)
        return e.exit_status
    if isinstance(e, OSError):  # a file-system fault no guard named: say what the OS said
        err = fsfaults.error(e)
        print(f"pumpsim: error: {err}", file=sys.stderr)
        return err.exit_status
    if isinstance(e, MemoryError):
        print("pumpsim: error: out of memory (shorten the data, --resample, or a shorter --duration)",
              file=sys.stderr)
        return 1
    if os.environ.get("PUMPSIM_DEBUG"):  # a bug, not a user error: one line unless debugging
        raise e
    print(f"pumpsim: internal error (please report; PUMPSIM_DEBUG=1 shows the traceback): "
          f"{type(e).__name__}: {e}", file=sys.stderr)
    return 1


def report_interrupt(e) -> int:
    print(f"pumpsim: {e.message()}", file=sys.stderr)
    return e.exit_status
