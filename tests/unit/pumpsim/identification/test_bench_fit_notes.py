"""The bench-log fit's notes (pumpdown_fit.separation_notes) and the fast model's leak law
(bench_fast.leak_flows) against the runtime's: no simulation."""
import numpy as np

from pumpsim.config import load_config
from pumpsim.identification.bench_fast import leak_flows, maps_change
from pumpsim.identification.pumpdown_fit import separation_notes
from pumpsim.pneumatics.pumpdown import leak_flow
from tests.conftest import EXAMPLES


def test_notes_name_correlated_and_weak_estimates_with_the_experiment():
    names = ["mu", "motor.friction", "booster.leak", "motor.resistance"]
    corr = np.eye(4)
    corr[0, 1] = corr[1, 0] = 0.97
    rel = {"mu": 0.01, "motor.friction": 0.05, "booster.leak": 0.25, "motor.resistance": 0.003}
    notes = " | ".join(separation_notes(names, [], corr, names, rel))
    assert "mu and motor.friction are correlated +0.970" in notes
    assert "booster.leak to 25 %" in notes and "hold test" in notes
    assert "inlet closed" in notes
    assert "motor.resistance" not in notes  # determined to 0.3 %, in no pair: nothing to say
    # nothing weak, nothing correlated, nothing unidentifiable: no note
    assert separation_notes(names, [], np.eye(4), names, {n: 0.01 for n in names}) == []
    # unidentifiable: named, with the experiment
    notes = " | ".join(separation_notes(["leak.tip_gap", "leak.end_gap"], ["leak.tip_gap", "leak.end_gap"], None, []))
    assert "cannot separate leak.tip_gap, leak.end_gap" in notes and "inlet closed" in notes


def test_fast_leak_law_is_the_runtime_one():
    cfg = load_config(EXAMPLES / "evp_booster.toml")
    v = dict(cfg.pneumatic.values)
    p = np.array([1e3, 3e4, 6e4, 1.0e5, 101e3, v["gas.atmosphere"]])
    np.testing.assert_allclose(v["booster.leak"] * leak_flows(v, p), [leak_flow(v, x) for x in p], rtol=1e-12,
                               atol=1e-18)
    assert maps_change("mu") and maps_change("leak.tip_gap") and maps_change("valve.cracking")
    assert not maps_change("booster.leak") and not maps_change("motor.resistance")
