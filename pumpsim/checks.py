"""The checks a configuration passes before any work: no magnitude that looks like a unit mistake
(a length in mm, a mass in g, a speed in rpm) and an admissible geometry (every vane reaches the
housing with its bottom end in the slot at every rotor angle).

`pumpsim.config.load_config` only parses the file and validates it against the parameter
registry; the geometry check needs the compiled kernels, so it runs here, above them. The Python
API (`pumpsim.load_config` is `checked_config`) and the command line load configurations through
`checked_config`.
"""
from __future__ import annotations

from pathlib import Path

from .config import PumpConfig, load_config
from .errors import ConfigError
from .geometry import check_geometry
from .plausibility import check_config


def checked_config(config, force: bool = False, geometry: bool = True) -> PumpConfig:
    """A configuration read (from a TOML path) or given (a `PumpConfig`), refused with a
    `ConfigError` naming the key and the limit unless it passes the checks before any work.

    config: a path to a .toml file (UTF-8, a BOM allowed) or a `PumpConfig`; values are SI (m, kg,
    s, rad, N). force: accept magnitudes that look like a unit mistake (a length in mm, a mass in
    g, a speed in rpm under operation.speed) with a warning in `cfg.warnings` instead of refusing.
    geometry: refuse vanes that cannot reach or fit the housing (the check loads, and if needed
    builds, the configuration's compiled kernel).

    Example::

        cfg = pumpsim.load_config("examples/test_rig.toml")
        cfg.speed          # rad/s (operation.speed, or operation.speed_rpm converted)
    """
    if isinstance(config, (str, Path)):
        cfg = load_config(config)
    elif isinstance(config, PumpConfig):
        cfg = config
    else:
        raise ConfigError(f"config must be a PumpConfig or a path to a TOML file, got {type(config).__name__}")
    cfg.warnings = check_config(cfg, force)
    if geometry:
        check_geometry(cfg)
    return cfg
