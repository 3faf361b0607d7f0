"""pumpsim: dynamic model and identification tools for rotary vane vacuum pumps.

    import pumpsim
    res = pumpsim.identify("examples/test_rig.toml", "examples/data/test_rig_measurement.csv")
    print(res)

The public names load on first use (PEP 562), so `import pumpsim.model_spec` -- the contract
codegen imports -- does not load the simulator.
"""
import importlib
import importlib.abc
import importlib.util
import sys
import types
from pathlib import Path

_HERE = Path(__file__).resolve().parent
# A source checkout keeps the model generator in codegen/ beside this package; a wheel installs it
# inside, as pumpsim.codegen (pyproject.toml's package-dir). CHECKOUT is the checkout's root, or
# None for an installed package.
CHECKOUT = (_HERE.parent if not (_HERE / "codegen").is_dir()
            and (_HERE.parent / "codegen" / "__init__.py").is_file() else None)


class _CheckoutCodegen(importlib.abc.MetaPathFinder):
    """In a checkout, pumpsim.codegen is that checkout's codegen/ -- also when the checkout is only
    on PYTHONPATH, or another checkout's editable install maps the name to its own folder."""

    def __init__(self, folder: Path):
        self.folder = folder

    def find_spec(self, fullname, path=None, target=None):
        if fullname != "pumpsim.codegen":
            return None
        return importlib.util.spec_from_file_location(
            fullname, self.folder / "__init__.py", submodule_search_locations=[str(self.folder)])


if CHECKOUT is not None:
    sys.meta_path[:] = [f for f in sys.meta_path if not isinstance(f, _CheckoutCodegen)]
    sys.meta_path.insert(0, _CheckoutCodegen(CHECKOUT / "codegen"))

# name -> module (or "module:attribute" where the public name is another function's)
_EXPORTS = {
    "load_config": ".checks:checked_config", "PumpConfig": ".config", "simulate": ".simulate",
    "SimulationResult": ".result", "PumpsimError": ".errors", "ConfigError": ".errors",
    "DataError": ".errors", "CodegenError": ".errors", "SolverError": ".errors",
    "IdentificationError": ".errors",
    "identify": ".api", "diagnose": ".api", "Diagnosis": ".diagnosis", "DiagnosisResult": ".diagnosis",
    "load_data": ".data", "Dataset": ".data", "DataOptions": ".data",
    "IdentificationResult": ".identification",
}
__all__ = list(_EXPORTS)


def _version() -> str:
    """The installed distribution's version (pyproject.toml is its one source)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("pumpsim")
    except PackageNotFoundError:  # a checkout on PYTHONPATH, never installed
        import tomllib

        try:
            return tomllib.loads((_HERE.parent / "pyproject.toml").read_text())["project"]["version"]
        except (OSError, ValueError, KeyError):
            return "unknown"


def __getattr__(name):
    if name == "__version__":
        globals()[name] = _version()
        return globals()[name]
    target = _EXPORTS.get(name)
    if target is None:
        raise AttributeError(f"module 'pumpsim' has no attribute '{name}'")
    module, _, attribute = target.partition(":")
    value = getattr(importlib.import_module(module, __name__), attribute or name)
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
