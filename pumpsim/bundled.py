"""The examples shipped with pumpsim: the repository's examples/ folder, installed as
pumpsim/examples/. `pumpsim example NAME DIR` copies one configuration with its measurements (in
DIR/data/) and the studies of it (in DIR/studies/, whose `config = "../NAME.toml"` then resolves),
so the documentation's paths `examples/...` work after `pumpsim example NAME examples`.
"""
from __future__ import annotations

import copy
import filecmp
import itertools
import shutil
from pathlib import Path

import tomllib

from .errors import ConfigError

# the simulated measurements made for a configuration (examples/make_measurements.py)
MEASUREMENTS = {"test_rig": ["test_rig_measurement.csv"], "ellipse_4vanes": ["ellipse_hidden_effects.csv"]}


def examples_dir() -> Path:
    from . import CHECKOUT

    return CHECKOUT / "examples" if CHECKOUT is not None else Path(__file__).resolve().parent / "examples"


def names() -> list[str]:
    """The bundled examples' names (`pumpsim example --list`)."""
    return sorted(p.stem for p in examples_dir().glob("*.toml"))


def description(name: str) -> str:
    """The first sentence of the configuration's opening comment."""
    lines = (examples_dir() / f"{name}.toml").read_text(encoding="utf-8").splitlines()
    text = " ".join(line.lstrip("# ").strip() for line in itertools.takewhile(lambda s: s.startswith("#"), lines))
    return text.split(". ")[0].rstrip(".") + "."


def files(name: str) -> list[str]:
    """The example's files, relative to the examples folder: the config, its data, its studies."""
    root = examples_dir()
    if not (root / f"{name}.toml").is_file():
        raise ConfigError(f"no bundled example '{name}'; `pumpsim example --list` shows them: "
                          f"{', '.join(names())}")
    studies = []
    for study in sorted((root / "studies").glob("*.toml")):
        config = tomllib.loads(study.read_text(encoding="utf-8")).get("study", {}).get("config")
        if config and (study.parent / config).resolve() == (root / f"{name}.toml").resolve():
            studies.append(f"studies/{study.name}")
    return [f"{name}.toml", *(f"data/{d}" for d in MEASUREMENTS.get(name, [])), *studies]


def copy_example(name: str, dest) -> list[Path]:
    """Copy the example's files into dest (created if missing); an existing different file is
    not overwritten (ConfigError naming it), an identical one is left as it is."""
    root, dest = examples_dir(), Path(dest)
    todo = files(name)
    for rel in todo:
        target = dest / rel
        if target.exists() and not (target.is_file() and filecmp.cmp(root / rel, target, shallow=False)):
            raise ConfigError(f"{target} exists and differs from the bundled {rel}; remove it or "
                              "choose another folder")
    out = []
    for rel in todo:
        target = dest / rel
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            if not target.exists():
                shutil.copyfile(root / rel, target)
        except OSError as e:
            raise ConfigError(f"cannot write {target} ({e.strerror or e}); choose a writable folder") from None
        out.append(target)
    return out


def example_table(name: str) -> dict:
    """The bundled configuration `name` as its TOML table (to edit before config_from_dict)."""
    return tomllib.loads((examples_dir() / f"{name}.toml").read_text(encoding="utf-8"))


def with_changes(table: dict, changes: dict) -> dict:
    """A copy of a config table with dotted-key changes applied ({"rotor.vanes": 5}; None removes
    the key): the rigs of the benchmarks and tests, each a bundled example with a few keys changed."""
    out = copy.deepcopy(table)
    for key, val in changes.items():
        *parents, leaf = key.split(".")
        node = out
        for p in parents:
            node = node.setdefault(p, {})
        if val is None:
            node.pop(leaf, None)
        else:
            node[leaf] = val
    return out
