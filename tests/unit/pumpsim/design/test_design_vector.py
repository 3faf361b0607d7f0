"""Designs as parameter vectors (design/vector.py): the rows equal the per-design config path's
bit for bit, and a design the map rejects gets the config's own reason."""
import math

import numpy as np
import pytest

from pumpsim.design import evaluate, vector
from pumpsim.design.study import study_from_dict
from tests.conftest import EXAMPLES

RIG = str(EXAMPLES / "test_rig.toml")
ELLIPSE = str(EXAMPLES / "ellipse_4vanes.toml")


def _study(config, vary, **st):
    return study_from_dict({"study": {"config": config, "sampler": "random", "samples": 8, **st}, "vary": vary})


def _rows(study, X, mapped):
    """evaluate_pump_rows with the DesignMap path, or with every design through its own config."""
    with pytest.MonkeyPatch.context() as mp:
        if not mapped:
            mp.setattr(evaluate, "design_maps", lambda s, X: ([], np.arange(len(X))))
        return evaluate.evaluate_pump_rows(study, X, np.arange(len(X)), 4)


def _same(a, b):
    assert len(a) == len(b)
    for r, s in zip(a, b):
        assert r.keys() == s.keys()
        for k in r:
            x, y = r[k], s[k]
            if isinstance(x, float) and math.isnan(x):
                assert isinstance(y, float) and math.isnan(y), k
            else:
                assert x == y, (k, x, y)


RIG_VARY = {"housing.radius": {"distribution": "normal", "sd": 4e-6},
            "vane.mass": {"distribution": "normal", "sd": 0.02, "relative": True},
            "friction.housing.dynamic": {"distribution": "uniform", "low": 0.1, "high": 0.3},
            "operation.speed": {"values": [400.0, 600.0]}}


def test_the_map_sets_what_the_config_sets():
    s = _study(RIG, RIG_VARY)
    dm = vector.DesignMap(s, {})
    assert dict(dm.sets["housing.radius"]) == {"housing.a": 1.0, "housing.b": 1.0}
    assert [q.name for q in dm.derived] == ["vane.inertia"]  # the rig does not give it
    assert "friction.slot.dynamic" in dict(dm.sets["friction.housing.dynamic"])  # no [friction.slot]
    X = np.array([[0.0226, 1.3e-3, 0.17, 500.0]])
    P, speed, ok = dm.vectors(X)
    assert ok.all() and speed[0] == 500.0
    assert dm.agrees(P[0], speed[0], dict(zip(s.keys, X[0].tolist())))


def test_rows_equal_the_per_design_path_bit_for_bit_with_rejections():
    s = _study(RIG, RIG_VARY)
    X = np.array([[0.0225, 1.2e-3, 0.20, 600.0],
                  [0.02251, 1.25e-3, 0.11, 400.0],
                  [0.0225, -1e-3, 0.20, 600.0],     # a negative mass: the registry's bound
                  [0.0225, 1.2e-3, 2.5, 600.0],     # a COF above its bound
                  [0.0225, 1.2e-3, math.nan, 600.0],  # a non-finite sampled value
                  [0.0225, 1.2e-3, 0.20, -5.0],     # a negative speed
                  [0.0350, 1.2e-3, 0.20, 600.0]])   # the vane no longer reaches the housing
    mapped, alone = _rows(s, X, True), _rows(s, X, False)
    _same(mapped, alone)
    status = [r["status"] for r in mapped]
    assert status[:2] == ["ok", "ok"]
    assert "vane.mass" in status[2] and "friction.housing.dynamic" in status[3]
    assert status[4].startswith("config:") and "operation.speed" in status[5]
    assert status[6].startswith("geometry:")
    res, speeds = {}, {}
    # the rest: per design (the map's rejections, and the geometry screen's for their reason)
    assert evaluate._mapped_results(s, X, res, speeds) == [2, 3, 4, 5, 6]


def test_vane_counts_each_get_their_variant_and_study_speeds_apply():
    s = _study(ELLIPSE, {"housing.b": {"values": [0.0245, 0.0225, 0.0205]}, "rotor.vanes": {"values": [2, 3]}},
               sampler="grid", speeds=[300.0, 500.0])
    from pumpsim.design.execute import study_designs

    X = study_designs(s)
    maps, rest = vector.design_maps(s, X)
    assert len(maps) == 2 and not len(rest)
    _same(_rows(s, X, True), _rows(s, X, False))


@pytest.mark.parametrize("vary,st", [({"rotor.width": {"values": [0.01, 0.012]}}, {}),
                                      ({"vane.mass": {"values": [1e-3, 2e-3]}}, {"model": "contact"})])
def test_what_the_map_does_not_cover_goes_per_design(vary, st):
    s = _study(RIG, vary, sampler="grid", **st)
    X = np.array([[v] for v in next(iter(vary.values()))["values"]])
    maps, rest = vector.design_maps(s, X)
    assert not maps and list(rest) == [0, 1]


def test_mouth_depths_are_the_per_design_formula_bit_for_bit():
    from pumpsim.geometry import mouth_depth

    rng = np.random.default_rng(2)
    keys = ("rotor.slot_radius", "rotor.slot_tilt", "rotor.radius")
    P = np.column_stack([rng.uniform(0.005, 0.01, 500), rng.choice([0.0, 0.1, -0.2617993877991494], 500),
                         rng.uniform(0.018, 0.022, 500)])
    got = vector.mouth_depths({k: i for i, k in enumerate(keys)}, P)
    want = [mouth_depth(dict(zip(keys, row))) for row in P.tolist()]
    assert got.tolist() == want
