"""pumpsim: dynamic model and identification tools for rotary vane vacuum pumps."""
from .config import PumpConfig, load_config
from .errors import (CodegenError, ConfigError, DataError, IdentificationError, PumpsimError,
                     SolverError)
from .result import SimulationResult
from .simulate import simulate

__all__ = ["load_config", "simulate", "PumpConfig", "SimulationResult", "PumpsimError",
           "ConfigError", "DataError", "CodegenError", "SolverError", "IdentificationError"]
__version__ = "0.1.0"
