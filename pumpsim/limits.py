"""Specification limits: `[limits.NAME]` tables with `lower` and/or `upper` (spec §9, the study
file's form), read from a study file or, for an identification, from a limits file
(`pumpsim identify CONFIG LOG --limits FILE.toml`) whose names are fitted parameters in SI units:

    [limits."booster.leak"]
    upper = 5.0e-5          # kg/s
    [limits.mu]
    lower = 0.12
    upper = 0.20

and what an estimate with its 95 % interval says against them."""
from __future__ import annotations

import difflib
import math
import tomllib
from pathlib import Path

from .errors import ConfigError

IN = "in specification"
OUT = "out of specification"
UNDECIDED = "undecided"  # the 95 % interval reaches past a limit the estimate is within
NOT_CHECKED = "not identified: not checked"
NOT_JUDGED = "not judged: the fit is not a usable estimate"


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def limits_table(raw, where) -> dict:
    """{name: (lower or None, upper or None)} from a `[where]` table of NAME = {lower, upper};
    every rejection is a ConfigError naming the key."""
    out = {}
    if not isinstance(raw, dict):
        raise ConfigError(f"[{where}] must be a table of NAME = {{lower, upper}}")
    for name, lim in raw.items():
        if not isinstance(lim, dict):
            raise ConfigError(f"{where}.{name} must be a table with lower and/or upper")
        bad = set(lim) - {"lower", "upper"}
        if bad:
            raise ConfigError(f"unknown key '{where}.{name}.{sorted(bad)[0]}' (lower, upper)")
        lo, hi = lim.get("lower"), lim.get("upper")
        for k, v in (("lower", lo), ("upper", hi)):
            if v is not None and not _finite(v):
                raise ConfigError(f"{where}.{name}.{k} must be a finite number, got {v!r}")
        if lo is None and hi is None:
            raise ConfigError(f"{where}.{name} needs lower and/or upper")
        if lo is not None and hi is not None and not lo < hi:
            raise ConfigError(f"{where}.{name}.lower ({lo:g}) must be < upper ({hi:g})")
        out[name] = (None if lo is None else float(lo), None if hi is None else float(hi))
    return out


def read_limits(path, fitted) -> dict:
    """The limits file at `path` (only a [limits] table), every name one of `fitted` (the
    parameters the fit estimates); a ConfigError names the file and the key otherwise."""
    where = f"--limits {path}"
    try:
        raw = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as e:
        raise ConfigError(f"{where}: cannot read the file: {e.strerror}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{where}: not UTF-8 text (a TOML file with [limits.NAME] tables)") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{where}: not valid TOML: {e}") from None
    other = sorted(set(raw) - {"limits"})
    if other:
        raise ConfigError(f"{where}: unknown table '{other[0]}' (the file holds [limits.NAME] tables only)")
    if not raw.get("limits"):
        raise ConfigError(f"{where}: no [limits.NAME] table (e.g. [limits.\"booster.leak\"] upper = 5e-5)")
    try:
        limits = limits_table(raw["limits"], "limits")
    except ConfigError as e:
        raise ConfigError(f"{where}: {e}") from None
    for name in limits:
        if name not in fitted:
            close = difflib.get_close_matches(name, list(fitted), n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ConfigError(f"{where}: limits.\"{name}\" is not a fitted parameter ({', '.join(fitted)}): "
                              f"{hint}add it to --params or drop the limit")
    return limits


def status(value, lower95, upper95, limit) -> str:
    """IN, OUT (the estimate is beyond a limit), UNDECIDED (the estimate is within, its 95 %
    interval reaches past a limit) or NOT_CHECKED (no estimate)."""
    if value is None:
        return NOT_CHECKED
    lo, hi = limit
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        return OUT
    reach_lo = lower95 if lower95 is not None else value
    reach_hi = upper95 if upper95 is not None else value
    if (lo is not None and reach_lo < lo) or (hi is not None and reach_hi > hi):
        return UNDECIDED
    return IN


def statuses(estimates, limits, usable=True) -> dict:
    """{name: status} for every limited name, from Estimate-like objects (value, lower95, upper95);
    NOT_JUDGED for all when the fit is not `usable` (its numbers are not estimates)."""
    if not usable:
        return {name: NOT_JUDGED for name in limits}
    out = {}
    for name, lim in limits.items():
        e = estimates.get(name)
        out[name] = NOT_CHECKED if e is None else status(e.value, e.lower95, e.upper95, lim)
    return out


def to_json(limits, states) -> dict:
    return {n: {"lower": lo, "upper": hi, "status": states[n]} for n, (lo, hi) in limits.items()}
