"""What every command shares: the parser class and option types, the shared option groups, the
output files (declared before any work, written together at the end) and the messages on stderr.

Imports here stay light (argparse and the standard library): building the parser for `--help`,
`--version` or a bad option must not load the numerical stack.
"""
from __future__ import annotations

import argparse
import contextlib
import logging
import os
import re
import sys

LOG = logging.getLogger("pumpsim")  # progress, notes on the data, warnings: stderr, -v/-q
REPORT_SUFFIXES = (".html", ".htm")
FIGURE = object()  # an output whose type the figure writer decides (pumpsim.report.simulation.figure_format)


class Parser(argparse.ArgumentParser):
    def error(self, message):  # bad options are bad input: status 2 with the usage line
        message = re.sub(r"^argument (--[\w-]+): must", r"\1 must", message)
        self.print_usage(sys.stderr)
        print(f"pumpsim: error: {message}", file=sys.stderr)
        sys.exit(2)


class Version(argparse.Action):
    """--version: the installed version, looked up only when asked (importlib.metadata is slow to
    import, and --help or a command does not need it)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None):
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        from .. import __version__

        print(f"pumpsim {__version__}")
        parser.exit()


class Help(argparse.ArgumentDefaultsHelpFormatter):
    """--help shows every default."""


# --- option types ---------------------------------------------------------------------------

def _converted(text, convert, what):
    try:
        return convert(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {what}, got '{text}'") from None


def positive_float(text):
    v = _converted(text, float, "a number")
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"must be > 0 (and finite), got {text}")
    return v


def tolerance(text):
    v = _converted(text, float, "a number")
    if not 0 < v < 1:
        raise argparse.ArgumentTypeError(f"must be in (0, 1), got {text}")
    return v


def in_range(low: float, high: float, low_open: bool = True):
    """An argparse type: a number in (low, high] (low_open) or [low, high]."""
    def checked(text):
        v = _converted(text, float, "a number")
        if not ((low < v if low_open else low <= v) and v <= high):
            raise argparse.ArgumentTypeError(f"must be in {'(' if low_open else '['}{low:g}, {high:g}], got {text}")
        return v
    return checked


def positive_int(text):
    return at_least(1)(text)


def at_least(low: int):
    """An argparse type: an integer >= low."""
    def checked(text):
        v = _converted(text, int, "an integer")
        if v < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {text}")
        return v
    return checked


def rate_or_auto(text):
    return "auto" if text.strip().lower() == "auto" else positive_float(text)


# --- progress and messages on stderr --------------------------------------------------------
# Results go to stdout with print(); what the run says about itself goes through the `pumpsim`
# logger: INFO (notes on the data, progress on a terminal) unless -q, DEBUG with -v. Errors, and
# why a finished fit is unusable, are always printed.

def add_verbosity(p, default=0):
    g = p.add_argument_group("messages")
    g.add_argument("-v", "--verbose", action="count", default=default,
                   help="say more on stderr (timings, the library's debug messages)")
    g.add_argument("-q", "--quiet", action="count", default=default,
                   help="only warnings and errors on stderr, no progress (-qq: errors only)")


class _Stderr(logging.StreamHandler):
    """Writes to the sys.stderr of the moment (a redirected or captured stream included)."""

    def __init__(self):
        super().__init__(sys.stderr)

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, _):
        pass


class _Prefixed(logging.Formatter):
    def format(self, record):
        text = record.getMessage()
        if record.levelno >= logging.ERROR:
            return f"pumpsim: error: {text}"
        if record.levelno >= logging.WARNING:
            return f"pumpsim: warning: {text}"
        return f"pumpsim: {text}"


@contextlib.contextmanager
def messages(verbose: int = 0, quiet: int = 0):
    """The `pumpsim` logger on stderr for one command at the level -v/-q ask for; restored after
    (a command run in-process leaves the caller's logging as it was)."""
    level = min(logging.ERROR, max(logging.DEBUG, logging.INFO + 10 * (quiet - verbose)))
    handler = _Stderr()
    handler.setFormatter(_Prefixed())
    saved = LOG.level, LOG.propagate, LOG.handlers[:]
    LOG.handlers[:] = [handler]
    LOG.setLevel(level)
    LOG.propagate = False
    try:
        yield
    finally:
        LOG.setLevel(saved[0])
        LOG.propagate = saved[1]
        LOG.handlers[:] = saved[2]


def live() -> bool:
    """Progress lines are for a terminal, and not with -q."""
    return sys.stderr.isatty() and LOG.isEnabledFor(logging.INFO)


def progress_printer(total):
    """Simulated-time progress on a terminal; silent in pipes, tests and with -q."""
    if not live():
        return None
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        return None
    bar = tqdm(total=total, unit="s sim", unit_scale=True, leave=False, file=sys.stderr,
               bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s simulated [{elapsed}<{remaining}]")
    state = {"t": 0.0}

    def update(t):
        bar.update(max(0.0, t - state["t"]))
        state["t"] = t
        if t >= total:
            bar.close()

    return update


def fit_log():
    """One line per fit iteration on a terminal (long fits show they are alive)."""
    if not live():
        return None

    def log(entry):
        print(f"\r\033[Kpumpsim: iteration {entry.get('iteration', '')} residual RMS {entry['rms']:.6g} N m",
              end="", file=sys.stderr, flush=True)

    return log


def warn(lines):
    for w in lines:
        LOG.warning("%s", w)


def info(text):
    LOG.info("%s", text)


# --- shared options -------------------------------------------------------------------------

def add_force(p):
    p.add_argument("--force", action="store_true",
                   help="proceed although the unit/plausibility checks suspect a unit mistake")


def add_data_options(p):
    g = p.add_argument_group("data (units from the header, e.g. 'torque [N*mm]', else SI)")
    g.add_argument("--time-column", default="time", help="time column / channel / variable")
    g.add_argument("--torque-column", default="torque", help="torque column")
    g.add_argument("--speed-column", default="speed", help="speed column (used when present)")
    g.add_argument("--angle-column", default="angle", help="angle column (used when present)")
    g.add_argument("--time-unit", help="s, ms or us (default: the header's unit, else s)")
    g.add_argument("--torque-unit", help="N*m, N*mm, mN*m or N*cm (default: the header's unit, else N*m)")
    g.add_argument("--speed-unit", help="rad/s, rpm or rev/s (default: the header's unit, else rad/s)")
    g.add_argument("--resample", type=rate_or_auto, metavar="HZ|auto",
                   help="interpolate onto a uniform grid at this rate [Hz] ('auto': the measured sample "
                        "rate), also across gaps in time, which are refused otherwise")
    g.add_argument("--steady", action="store_true",
                   help="fit only the constant-speed section (needs a speed column)")
    b = p.add_argument_group("bench log (time, voltage, current, booster_pressure[, speed]; units from the header, "
                             "e.g. 'booster_pressure [kPa abs]', else SI)")
    b.add_argument("--voltage-column", default="voltage", help="supply voltage column")
    b.add_argument("--current-column", default="current", help="motor current column")
    b.add_argument("--pressure-column", default="booster_pressure", help="booster pressure column (absolute)")
    b.add_argument("--voltage-unit", help="V or mV (default: the header's unit, else V)")
    b.add_argument("--current-unit", help="A or mA (default: the header's unit, else A)")
    b.add_argument("--pressure-unit", help="Pa, hPa, kPa, MPa, mbar, bar, psi or torr, with 'abs' or 'g' "
                                          "(default: the header's unit, else Pa)")


def add_fit_outputs(p):
    """What identify and diagnose share: JSON, HTML report, data options and --force."""
    p.add_argument("--json", help="write the result as JSON")
    p.add_argument("--report", help="self-contained HTML report (.html)")
    add_force(p)
    add_data_options(p)


# --- inputs ---------------------------------------------------------------------------------

def load_config(a):
    """The command's config, parsed, validated and checked (units, geometry), or exit 2."""
    from ..checks import checked_config

    cfg = checked_config(a.config, force=getattr(a, "force", False))
    LOG.debug("config %s: %s", a.config, cfg.name)
    warn(cfg.warnings)
    return cfg


def read_data(a, path, nominal_speed):
    """load_data with the command's data options; what it did to the data (resampled, time from a
    sample rate, jittered steps) is said on stderr."""
    from ..data import load_data

    ds = load_data(path, data_options(a), nominal_speed=nominal_speed)
    LOG.debug("data %s: %d samples", path, ds.n)
    for note in ds.notes:
        info(f"{ds.name}: {note}")
    return ds


def refuse_torque_only(given: dict, verb: str) -> None:
    """Refuse on a bench log the options only torque data takes (given: flag -> whether given)."""
    from ..errors import ConfigError

    for flag, on in given.items():
        if on:
            raise ConfigError(f"{flag} is for torque data; a bench log is {verb} as logged: drop {flag}")


def refuse_bench_only(a, path) -> None:
    """Refuse on torque data the options only a bench log takes: the file did not read as a bench
    log, most likely because a column is named otherwise than the option says."""
    from ..errors import ConfigError

    defaults = {"voltage_column": "voltage", "current_column": "current", "pressure_column": "booster_pressure",
                "voltage_unit": None, "current_unit": None, "pressure_unit": None}
    given = [option_name(k) for k, d in defaults.items() if getattr(a, k) != d]
    if given:
        raise ConfigError(f"{given[0]} is for a bench log, and '{path}' does not read as one (two or more of "
                          "its voltage, current and booster_pressure columns found, no torque column): check the "
                          "column names against the file's header")


def read_bench(a, path, cfg):
    """A bench log with the command's data options; what the reading did is said on stderr."""
    from ..benchlog import read_bench_log

    log = read_bench_log(path, cfg, data_options(a))
    for note in log.notes:
        info(f"{log.name}: {note}")
    return log


def data_options(a):
    from ..data import DataOptions

    return DataOptions(time=a.time_column, torque=a.torque_column, speed=a.speed_column,
                       angle=a.angle_column, torque_unit=a.torque_unit, speed_unit=a.speed_unit,
                       time_unit=a.time_unit, resample=a.resample, steady=a.steady, voltage=a.voltage_column,
                       current=a.current_column, booster_pressure=a.pressure_column, voltage_unit=a.voltage_unit,
                       current_unit=a.current_unit, pressure_unit=a.pressure_unit)


# --- outputs --------------------------------------------------------------------------------

def option_name(attr: str) -> str:
    return "--" + attr.replace("_", "-")


def outputs(a, inputs, **options):
    """The run's output files: options maps an attribute of `a` to its allowed suffixes (None: any,
    FIGURE: what the figure writer accepts). Checked now, before any work (writable, not a folder,
    not an input, no two the same), held against other runs, written later inside `staged()`."""
    from ..io import Outputs
    from ..locks import hold_files

    outs = Outputs(inputs)
    for attr, suffixes in options.items():
        path = getattr(a, attr, None)
        if suffixes is not FIGURE:
            outs.add(option_name(attr), path, suffixes)
        elif path is not None:  # the figure writer's module loads matplotlib: only for a figure
            from ..report.simulation import figure_format

            outs.add(option_name(attr), path, kind=figure_format)
    outs.check()
    hold_files({option_name(attr): getattr(a, attr, None) for attr in options})
    return outs


@contextlib.contextmanager
def staged(outs):
    """outs.staged() with a file-system fault while writing named: the output, what to do (exit 2)."""
    from .. import fsfaults

    tmps = {}
    try:
        with outs.staged() as tmp:
            tmps.update(tmp)
            yield tmp
    except OSError as e:
        named = os.path.abspath(str(e.filename)) if e.filename is not None else None
        same = [o for o, t in tmps.items() if os.path.abspath(t) == named]
        if same:
            raise fsfaults.error(e, "writing", fsfaults.target_of(tmps[same[0]]), same[0]) from None
        every = ", ".join(f"{o} '{fsfaults.target_of(t)}'" for o, t in tmps.items())
        raise fsfaults.error(e, f"writing {every}" if every else "writing the outputs") from None


def write_fit_outputs(outs, a, document: dict, write_report) -> None:
    """--json (the document) and --report (write_report(path)), renamed into place together."""
    import json

    from ..io import write_text

    with staged(outs) as tmp:
        if a.json:
            write_text(tmp["--json"], json.dumps(document, indent=1))
        if a.report:
            write_report(tmp["--report"])
