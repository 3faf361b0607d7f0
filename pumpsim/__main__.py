import os
import signal
import sys

from .cli import main

status = main()


def _exiting(signum, frame):  # a signal while the interpreter shuts down (a Dask cluster closing): its status, one line
    print(f"pumpsim: interrupted by {signal.Signals(signum).name} while exiting; the run had ended, its outputs are "
          "written", file=sys.stderr, flush=True)
    os._exit(128 + signum)


for _s in (signal.SIGINT, signal.SIGTERM):
    if signal.getsignal(_s) is not signal.SIG_IGN:
        signal.signal(_s, _exiting)
sys.stdout.flush()
sys.exit(status)
