"""A batch's table built as columns (design/columns.py) equals the one built from row dicts, for
every kind of result: evaluated as arrays (with a non-finite output and a lift-off), per design
(with a non-finite output), and not evaluated."""
import math

import numpy as np

from pumpsim.design import evaluate
from pumpsim.design.columns import Block, rows, table_columns
from pumpsim.design.outputs import OUTPUTS
from pumpsim.design.store import columns, columns_to_table, rows_to_table
from pumpsim.design.study import study_from_dict
from tests.conftest import EXAMPLES

ELLIPSE = str(EXAMPLES / "ellipse_4vanes.toml")


def _outputs(k):
    out = {o: float(k + i) for i, o in enumerate(OUTPUTS)}
    out.update(lift_off=k == 1, paradox=False, min_normal_force=-1.5 if k == 1 else 2.0)
    out.update({f"friction_power_{i}": 0.1 * i for i in range(4)})
    return out


def _same(a, b):
    """Arrow tables equal in schema and values, NaN equal to NaN (Table.equals has NaN != NaN)."""
    assert a.schema.equals(b.schema)
    for name in a.column_names:
        x, y = a.column(name).to_pylist(), b.column(name).to_pylist()
        assert [("nan" if isinstance(v, float) and math.isnan(v) else v) for v in x] == \
               [("nan" if isinstance(v, float) and math.isnan(v) else v) for v in y], name


def test_columns_equal_rows_for_every_kind_of_result():
    s = study_from_dict({"study": {"config": ELLIPSE, "sampler": "grid", "speeds": [300.0, 500.0]},
                         "vary": {"vane.mass": {"values": [1e-3, 2e-3, 3e-3, 4e-3]}}})
    per = [_outputs(k) for k in range(4)]
    out = {nm: np.array([p[nm] for p in per]) for nm in per[0]}
    out["mean_torque"][2] = math.nan  # design 1's second speed: a non-finite output
    block = Block(out, [300.0, 500.0, 300.0, 500.0], np.isfinite(out["mean_torque"]), 2)
    X = np.array([[1e-3], [2e-3], [3e-3], [4e-3]])
    results = {0: ("ok", block.design(1)), 1: ("config: vane.mass must be > 0", None),
               2: ("ok", [(300.0, None), (500.0, _outputs(3))]), 3: ("ok", block.design(0))}
    speeds = {j: [300.0, 500.0] for j in range(4)}
    ids = np.array([10, 11, 12, 13])
    by_rows = rows_to_table(s, rows(s, X, ids, results, speeds))
    by_columns = columns_to_table(s, table_columns(s, X, ids, results, speeds, columns(s)))
    _same(by_columns, by_rows)
    status = by_columns.column("status").to_pylist()
    assert status[0].startswith("numerical: non-finite") and status[1] == "ok" and status[4] == status[0]
    assert status[2] == status[3] == "config: vane.mass must be > 0" and status[7].startswith("lift_off:")
    assert by_columns.column("lift_off").to_pylist() == [None, False, None, None, None, False, False, True]


def test_a_study_table_equals_its_rows():
    s = study_from_dict({"study": {"config": ELLIPSE, "sampler": "grid"},
                         "vary": {"housing.b": {"values": [0.0215, 0.0203, 0.019]},
                                  "friction.housing.dynamic": {"values": [0.17, 1.0]},
                                  "friction.housing.static": {"values": [1.0]}}})
    from pumpsim.design.execute import study_designs

    X = study_designs(s)
    ids = np.arange(len(X))
    table = evaluate.evaluate_table(s, X, ids)
    _same(table, rows_to_table(s, evaluate.evaluate_pump_rows(s, X, ids, 4)))
    assert {st.split(":")[0] for st in table.column("status").to_pylist()} == {"ok", "lift_off", "geometry", "config"}
