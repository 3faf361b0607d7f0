"""pumpsim: dynamic model and identification tools for rotary vane vacuum pumps.

    import pumpsim
    res = pumpsim.identify("examples/test_rig.toml", "examples/data/test_rig_measurement.csv")
    print(res)

The public names load on first use (PEP 562), so `import pumpsim.model_spec` -- the contract
codegen imports -- does not load the simulator.
"""
import importlib
import sys
import types

_EXPORTS = {
    "load_config": ".config", "PumpConfig": ".config", "simulate": ".simulate",
    "SimulationResult": ".result", "PumpsimError": ".errors", "ConfigError": ".errors",
    "DataError": ".errors", "CodegenError": ".errors", "SolverError": ".errors",
    "IdentificationError": ".errors",
    "identify": ".api", "diagnose": ".api", "Diagnosis": ".api",
    "load_data": ".data", "Dataset": ".data", "DataOptions": ".data",
    "IdentificationResult": ".identification",
}
__all__ = list(_EXPORTS)
__version__ = "0.1.0"


def __getattr__(name):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'pumpsim' has no attribute '{name}'")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted([*globals(), *_EXPORTS])


class _Package(types.ModuleType):
    def __setattr__(self, name, value):
        # importing the submodule pumpsim.simulate sets the attribute `simulate` to it; the public
        # name is the function (as it was with eager imports)
        if name in _EXPORTS and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
