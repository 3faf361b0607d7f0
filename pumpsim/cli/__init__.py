"""The `pumpsim` command line: one module per command, `common` for what they share,
`app` for the parser and the exit status (0 ok, 2 bad input, 1 numerical failure or unusable fit,
130/143 interrupted; see pumpsim.cli.app).

A command module registers its parser in `register(sub)` and runs in `run(args)`; it imports
the numerical stack inside `run`, so `pumpsim --help`, `--version` and a bad option start fast.
"""
from .app import build_parser, console, main

__all__ = ["build_parser", "console", "main"]
