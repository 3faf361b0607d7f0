"""Exception classes: every user-facing failure is one of these, never a bare traceback."""


class PumpsimError(Exception):
    """Base class. `exit_status` is what the command line returns."""

    exit_status = 1


class ConfigError(PumpsimError):
    """Bad configuration file or option (names the key and the limit)."""

    exit_status = 2


class StartError(ConfigError):
    """The model is not finite at a fit's start: a start outside the pump's geometry or physics
    (names the start values)."""


class DataError(PumpsimError):
    """Bad measured data (names the row or the column)."""

    exit_status = 2


class CodegenError(PumpsimError):
    """Generating or compiling a kernel failed, or a compiled kernel is stale."""

    exit_status = 1


class KernelCacheError(CodegenError):
    """The kernel folder cannot be written (read-only, no permission): the user moves it."""

    exit_status = 2


class SolverError(PumpsimError):
    """A numerical failure; the message names the time and state where it happened."""

    exit_status = 1

    def __init__(self, message, partial=None):
        super().__init__(message)
        self.partial = partial  # whatever was computed up to the failure


class IdentificationError(PumpsimError):
    exit_status = 1


class OutputError(PumpsimError):
    """A file-system fault on an output the user can fix: a read-only, missing or full place, no
    permission, or an output another run is writing (names the path, the operation, the remedy)."""

    exit_status = 2
