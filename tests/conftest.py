import math
import os
import shutil
import signal
import tempfile
from pathlib import Path

import numpy as np
import pytest

import pumpsim
from pumpsim.bundled import example_table, with_changes
from pumpsim.config import as_array, config_from_dict
from pumpsim.geometry import check_geometry
from pumpsim.kernels import load_kernels
from tests.tolerances import TRUTH_ATOL, TRUTH_RTOL

# A run started in the background of a non-interactive shell inherits SIGINT ignored, and so
# would every process the interruption tests start (exec keeps an ignored signal ignored): they
# send it on purpose.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
_SESSION_CACHE = "PUMPSIM_TEST_SESSION_CACHE"  # the kernel cache the controller made, for its workers


def pytest_configure(config):
    """Tests never write into the repository's generated/: every variant a test needs is loaded
    from, or built into, a temporary cache (set here, before collection, so a module-level config
    load cannot miss it). It starts as a copy of the libraries `make codegen` built and of those
    earlier test sessions built (kept in pytest's cache folder, .pytest_cache, between sessions)."""
    from pumpsim.model_spec import manifest as mf

    if os.environ.get("PYTEST_XDIST_WORKER") and os.environ.get(_SESSION_CACHE):
        # a worker of `pytest -n`: the controller's cache (builds are installed atomically, so
        # two workers building one variant is harmless); the controller keeps it and cleans up
        os.environ["PUMPSIM_GENERATED"] = os.environ[_SESSION_CACHE]
        return
    cache = Path(tempfile.mkdtemp(prefix="pumpsim-generated-"))
    kept = config.cache.mkdir("pumpsim-generated") if getattr(config, "cache", None) else None
    for origin in (ROOT / "generated", kept):
        for folder in (origin.glob("*-*") if origin else ()):
            if folder.is_dir() and mf.read_manifest(folder) is not None and not (cache / folder.name).exists():
                shutil.copytree(folder, cache / folder.name)
    config._pumpsim_cache = (cache, kept, os.environ.get("PUMPSIM_GENERATED"))
    os.environ["PUMPSIM_GENERATED"] = os.environ[_SESSION_CACHE] = str(cache)


def pytest_unconfigure(config):
    cache, kept, before = getattr(config, "_pumpsim_cache", (None, None, None))
    if cache is None:
        return
    os.environ.pop(_SESSION_CACHE, None)
    if before is None:
        os.environ.pop("PUMPSIM_GENERATED", None)
    else:
        os.environ["PUMPSIM_GENERATED"] = before
    if kept is not None:  # keep this session's builds for the next one (never in generated/)
        for folder in cache.glob("*-*"):
            if not folder.is_dir() or (ROOT / "generated" / folder.name).exists():
                continue
            if (kept / folder.name).exists():  # the fingerprints it now lists (a driver has no manifest)
                if not (folder / "manifest.json").exists():
                    continue
                shutil.copy2(folder / "manifest.json", kept / folder.name / "manifest.json")
            else:
                shutil.copytree(folder, kept / folder.name)
    shutil.rmtree(cache, ignore_errors=True)


@pytest.fixture(scope="session")
def kernel_cache():
    """The session's temporary kernel cache (see pytest_configure)."""
    return Path(os.environ["PUMPSIM_GENERATED"])


def example_dict(name="test_rig"):
    return example_table(name)


def apply_changes(d, changes):
    """A copy of the config dict d with dotted-key changes applied (None removes the key)."""
    return with_changes(d, changes)


def toml_value(v):
    """A Python value as TOML (floats nan/inf included, inline tables for nested dicts in lists)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else ("-inf" if v == -math.inf else repr(v)))
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    return repr(v)


def toml_text(d) -> str:
    """A config dict as TOML text (tables for nested dicts)."""
    lines = []

    def emit(prefix, table):
        if prefix:
            lines.append(f"[{prefix}]")
        lines.extend(f"{k} = {toml_value(v)}" for k, v in table.items() if not isinstance(v, dict))
        for k, v in table.items():
            if isinstance(v, dict):
                emit(f"{prefix}.{k}" if prefix else k, v)

    emit("", d)
    return "\n".join(lines) + "\n"


def make_config(base="test_rig", **changes):
    """Config from an example with dotted-key changes, e.g. make_config(**{"rotor.vanes": 1})."""
    cfg = config_from_dict(apply_changes(example_dict(base), changes))
    check_geometry(cfg)
    return cfg


def kernel_and_p(cfg, model="constrained"):
    pv = cfg.parameters(model)
    return load_kernels(pv.structure), as_array(pv), pv


def one_revolution(n=2048):
    return np.linspace(0.0, 2 * math.pi, n, endpoint=False)


@pytest.fixture
def cfg_factory():
    return make_config


@pytest.fixture(scope="session")
def transient_run():
    """A torque-driven run of the ellipse pump (mu = 0.17, 0.03 N m from 150 rad/s, 40 samples):
    the data of the transient identification tests."""
    import dataclasses

    truth = make_config("ellipse_4vanes", **{"friction.housing.dynamic": 0.17, "friction.housing.static": 0.18})
    return pumpsim.simulate(dataclasses.replace(truth, mode="torque", torque=0.03, speed=150.0, angle=0.2),
                            duration=0.02, rate=2000, rtol=TRUTH_RTOL, atol=TRUTH_ATOL)


def transient_start_config():
    """The transient tests' start: mu = 0.1 with the truth's static/dynamic ratio."""
    return make_config("ellipse_4vanes", **{"friction.housing.dynamic": 0.1,
                                            "friction.housing.static": 0.18 * 0.1 / 0.17})


__all__ = ["make_config", "kernel_and_p", "one_revolution", "transient_start_config", "pumpsim"]
