"""The contract between codegen and the runtime, and nothing else.

Both sides import this package; neither imports the other. It holds the parameter registry
(`parameters`), the structure that selects a compiled variant (`parameters.Structure`), the
friction and contact laws (`laws`), the names, units and shapes of every exported kernel output
(`outputs`) and the cache key and manifest rules (`manifest`). It imports NumPy and the standard
library only (and `pumpsim.errors`, a leaf module): importing it loads neither the simulator nor
SymPy nor CasADi.
"""
from .parameters import CONTACT_LAWS, MODELS, Parameter, ParameterVector, Structure, layout

__all__ = ["CONTACT_LAWS", "MODELS", "Parameter", "ParameterVector", "Structure", "layout"]
