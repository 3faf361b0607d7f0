"""Property tests (hypothesis) for `pumpsim pumpdown` (spec §8): whatever option values or gas-table
values a user gives, exit 0, 1 or 2, no traceback, no partial output (the contract of
test_no_traceback.run_cli). Runs are 2 ms of pump-down so even accepted inputs stay cheap; keys
that change the compiled structure (vane count, housing shape, contact laws) are left out.

Before: --duration inf or --rate inf ended in an internal error (OverflowError), and a
--duration x --rate of 1e9 samples was accepted (the run never ended)."""
import json
import math
import tomllib

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from tests.conftest import EXAMPLES, toml_text  # noqa: E402
from tests.property.test_no_traceback import NUMBERS, SETTINGS, run_cli  # noqa: E402

EVP_DICT = tomllib.loads((EXAMPLES / "evp_booster.toml").read_text())
BAD_NUMBERS = st.sampled_from([0.0, -1.0, math.inf, -math.inf, math.nan, 1e12])
OPTIONS = ("--duration", "--rate", "--rtol", "--atol", "--until")
GAS_KEYS = [f"{t}.{k}" for t in ("gas", "ports", "valve", "leak", "booster", "motor")
            for k in EVP_DICT.get(t, {})] + ["rotor.width", "vane.slot_pressure", "operation.mode"]


@SETTINGS
@given(st.sampled_from(OPTIONS), BAD_NUMBERS)
def test_bad_pumpdown_option_values_exit_2(tmp_path_factory, option, value):
    d = tmp_path_factory.mktemp("pd")
    js = d / "pd.json"
    args = ["pumpdown", EXAMPLES / "evp_booster.toml", "--json", js]
    if option != "--duration":
        args += ["--duration", "0.002"]
    code, msg = run_cli(args + [option, repr(value)], [js])
    assert code == 2 and option.lstrip("-") in msg, msg  # the option named (by its keyword)


# slow: in a full session (after test_any_identify_options) the 25 examples spend 116-120 s inside
# CVODES (cProfile: casadi Function_call), 0.3 s when the file runs alone -- cause not found (the
# pump-down after each identify option alone stays at 20 ms); `make test-all` runs it, and
# `make test` stays within its ~10 min
@pytest.mark.slow
@SETTINGS
@given(st.lists(st.tuples(st.sampled_from(GAS_KEYS), NUMBERS), min_size=1, max_size=2))
def test_any_gas_table_values(tmp_path_factory, changes):
    d = tmp_path_factory.mktemp("pd")
    cfg = json.loads(json.dumps(EVP_DICT))
    for path, value in changes:
        table, key = path.split(".")
        cfg[table][key] = value
    config = d / "evp.toml"
    config.write_text(toml_text(cfg))
    out, js = d / "pd.csv", d / "pd.json"
    run_cli(["pumpdown", config, "--duration", "0.002", "--out", out, "--json", js], [out, js])
