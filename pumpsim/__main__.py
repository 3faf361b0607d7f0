import sys

from . import interrupt

interrupt.guard_process()  # before the command line imports: a signal then has its status too

from .cli import console  # noqa: E402

sys.exit(console())
