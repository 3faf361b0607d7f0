"""The documentation's configuration reference (docs/_ext/pumpsim_config_keys.py) covers every key
the config accepts, each with a description, and renders one table row per key."""
import importlib.util
import re

from pumpsim.config import _SCHEMA
from tests.conftest import ROOT


def _extension():
    path = ROOT / "docs" / "_ext" / "pumpsim_config_keys.py"
    spec = importlib.util.spec_from_file_location("pumpsim_config_keys", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _schema_keys(schema, prefix=""):
    for k, v in schema.items():
        if isinstance(v, dict):
            yield from _schema_keys(v, f"{prefix}{k}.")
        elif not k.startswith("__"):
            yield f"{prefix}{k}"


def test_every_config_key_is_documented_once_with_a_description():
    ext = _extension()
    table, missing = ext.rows()
    assert missing == []
    documented = [f"{section}.{key}" if section else key for section, key, *_ in table]
    assert sorted(documented) == sorted(_schema_keys(_SCHEMA))
    assert all(doc.strip() for *_, doc in table)


def test_every_key_appears_in_exactly_one_rendered_table():
    ext = _extension()
    rendered = ext.rst_lines("mechanical") + ext.rst_lines("gas")
    rows = [m.group(1) for line in rendered if (m := re.fullmatch(r"   \* - ``(.+)``", line))]
    table, _ = ext.rows()
    assert len(rows) == len(table)  # no key dropped or shown twice between the two pages' halves


def test_numeric_registry_keys_carry_their_unit_and_limits():
    table, _ = _extension().rows()
    by_key = {f"{s}.{k}": (unit, default, allowed) for s, k, _t, unit, default, allowed, _d in table}
    assert by_key["housing.radius"][0] == "m" and "rotor.radius" in by_key["housing.radius"][2]
    assert by_key["friction.housing.dynamic"][2].startswith("[0, 2]")
    assert by_key["vane.inertia"][1].startswith("``vane.mass")  # a derived default shows its formula
    assert by_key["gas.heat_transfer"][0] == "W/(m² K)"
    assert by_key["vane.mass"][2].endswith("typical 0.1 to 50 g")  # plausibility in engineering units


def test_the_housing_shapes_come_from_their_registry(monkeypatch):
    from pumpsim.model_spec import housings
    from tests.unit.pumpsim.model_spec.test_housings import ROUND

    monkeypatch.setitem(housings.SHAPES, ROUND.name, ROUND)
    table, missing = _extension().rows()
    assert missing == []
    by_key = {f"{s}.{k}": (unit, allowed, doc) for s, k, _t, unit, _d, allowed, doc in table}
    for name in housings.SHAPES:
        assert f'``"{name}"``' in by_key["housing.shape"][2]
    unit, allowed, doc = by_key["housing.diameter"]
    assert unit == "m" and allowed.startswith("> 2 × rotor.radius")  # the semi-axes' bound, doubled
    assert doc == 'Bore diameter; required for ``shape = "round"``.'
