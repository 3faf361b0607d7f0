"""The pneumatic model's compiled kernel (a gas variant of spec §8) and parameter vector for a
configuration."""
from __future__ import annotations

import numpy as np

from ..config import PumpConfig
from ..errors import ConfigError
from ..model_spec.parameters import PneumaticStructure, pneumatic_layout
from .scalar import load_kernels


def structure_of(cfg: PumpConfig, model: str = "constrained") -> PneumaticStructure:
    """The gas variant with Model 2 mechanics ("constrained") or Model 1's ("contact")."""
    if model == "contact":
        return PneumaticStructure(cfg.vanes, len(cfg.harmonics), "pneumatic-contact",
                                  cfg.contact_laws["housing"], cfg.contact_laws["bottom"])
    return PneumaticStructure(cfg.vanes, len(cfg.harmonics))


def parameter_vector(cfg: PumpConfig, model: str = "constrained", **overrides) -> np.ndarray:
    """Stacked parameters (registry order); `overrides` by registry name with '.' as '__'."""
    if cfg.pneumatic is None:
        raise ConfigError(f"{cfg.path or cfg.name}: the gas model needs [ports] and [booster] "
                          "(spec §8)")
    st = structure_of(cfg, model)
    mech = cfg.parameters(model).values
    values = {**mech, **cfg.pneumatic.values}
    values.update({k.replace("__", "."): v for k, v in overrides.items()})
    names = [q.name for q in pneumatic_layout(st)]
    missing = [n for n in names if n not in values]
    if missing:
        raise ConfigError(f"parameters without a value: {', '.join(missing)}")
    return np.array([float(values[n]) for n in names])


def parameter_index(cfg_or_structure, name: str) -> int:
    st = cfg_or_structure if isinstance(cfg_or_structure, PneumaticStructure) else structure_of(cfg_or_structure)
    return [q.name for q in pneumatic_layout(st)].index(name)


def kernels(cfg: PumpConfig, model: str = "constrained"):
    return load_kernels(structure_of(cfg, model))
