"""Design studies: sweeps, tolerance Monte Carlo, global sensitivity and optimisation.

    from pumpsim import design
    study = design.load_study("examples/studies/test_rig_tolerances.toml")
    df, stats = design.sweep(study, out="out/rig_mc")        # pandas DataFrame, one row per design/speed
    df = design.read_results("out/rig_mc")                   # the same table read back
    s = design.sensitivity(study)                            # Sobol S1/ST with intervals (SALib)
    r = design.optimize(study)                               # SLSQP with exact kernel gradients
"""
import importlib

from .study import Study, load_study, study_from_dict

# loaded on first use (pandas, pyarrow, dask): reading and checking a study needs none of them
_LAZY = {"run_study": ".execute", "read_manifest": ".store", "read_results": ".store"}


def __getattr__(name):
    if name not in _LAZY:
        raise AttributeError(f"module 'pumpsim.design' has no attribute '{name}'")
    value = getattr(importlib.import_module(_LAZY[name], __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted([*globals(), *_LAZY])


def _study(study):
    return load_study(study) if isinstance(study, (str, bytes)) or hasattr(study, "__fspath__") else study


def sweep(study, out=None, **kw):
    """Run every design of a study; returns (DataFrame, RunStats). See execute.run_study."""
    from .execute import run_study

    return run_study(_study(study), out=out, **kw)


def sensitivity(study, **kw):
    """Sobol' (S1, ST with 95 % bootstrap intervals) or Morris indices of every output for every varied
    key: {"indices": {output: {key: {"S1", "S1_conf", "ST", "ST_conf"}}}, ...}. Keywords: method
    ("sobol" or "morris"), samples (base samples N; Sobol' evaluates N(D + 2) designs), seed,
    resamples, and those of `sweep` (workers, scheduler, out, progress)."""
    from .indices import sensitivity as _s

    return _s(_study(study), **kw)


def optimize(study, **kw):
    """Minimise the study's [objective] under its [constraints] over the varied keys' bounds (SLSQP
    or trust-constr with exact kernel gradients; NSGA-II for several objectives). Returns the design
    found, the objective and constraint values and the iterations."""
    from .optimiser import optimize as _o

    return _o(_study(study), **kw)


__all__ = ["Study", "load_study", "study_from_dict", "sweep", "read_results", "read_manifest",
           "sensitivity", "optimize", "run_study"]
