"""The slot_friction library effect (F15): the slot COF free where the configured slot/tip
proportion is off. Its absent value is the slot COF every fit of mu alone uses (mu's, in the
configured proportion), its range a COF's (registry), and the independent bench counts it as a
right name for a tip COF rising with slip speed (at one speed the two are one change)."""
import numpy as np
import pytest

import pumpsim
from bench.diagnose_grid import rig
from bench.independent.run import score
from pumpsim.data import Dataset
from pumpsim.diagnosis import candidates, plausible
from pumpsim.diagnosis.state import State
from tests.tolerances import COMPILED_REL

TORQUE_RMS, MEAN_TORQUE = 0.14, 0.13  # N m, the test rig's scale


@pytest.fixture(scope="module")
def cfg():
    return rig("tilted3")


def test_absent_slot_cof_leaves_the_current_model_unchanged(cfg):
    """At a refitted mu (not the configured one) the candidate's start is the tied slot COF, so its
    problem at its start is the current model -- what its score test and one-step fit assume."""
    sim = pumpsim.simulate(cfg, duration=0.01, rate=10000)
    data = Dataset(sim.time, sim.torque)
    mu = 1.3 * cfg.values["friction.housing.dynamic"]
    st = State(cfg, data, ["mu", "theta0"], {"mu": mu, "theta0": cfg.angle})
    cand = next(c for c in candidates(cfg, set()) if c.effect == "slot_friction")
    prob = cand.problem(st)
    base = st.problem()
    tied = mu * cfg.values["friction.slot.dynamic"] / cfg.values["friction.housing.dynamic"]
    assert prob.x0[prob.names.index("mu_slot")] == pytest.approx(tied, rel=COMPILED_REL)
    m0, m1 = base.model(base.x0), prob.model(prob.x0)
    assert np.max(np.abs(m1 - m0)) <= COMPILED_REL * np.max(np.abs(m0))
    # and the slot COF does move the model (the candidate is not blind)
    x = prob.x0.copy()
    x[prob.names.index("mu_slot")] *= 0.7
    assert np.max(np.abs(prob.model(x) - m0)) > 1e3 * COMPILED_REL * np.max(np.abs(m0))


def test_slot_cof_range_is_the_registry_cof_range(cfg):
    assert plausible(cfg, {"mu_slot": 0.5}, TORQUE_RMS, MEAN_TORQUE) == []
    msgs = plausible(cfg, {"mu_slot": 1.2}, TORQUE_RMS, MEAN_TORQUE)
    assert len(msgs) == 1 and "a COF" in msgs[0]


def test_independent_score_takes_slot_friction_for_a_viscous_tip_cof_only():
    absorbed = {"effects": ["viscous_tip_friction"], "absorbed_effects": ["viscous_tip_friction"]}
    named = {"effects": ["slot_friction"], "unexplained": False}
    r = score("viscous_tip_friction", absorbed, named)
    assert r["right"] and not r["false_name"]
    offset = {"effects": ["torque_offset"], "absorbed_effects": []}
    r = score("torque_offset", offset, named)  # a sensor zero is not a slot COF
    assert not r["right"] and r["false_name"]
    required = {"effects": ["viscous_tip_friction"], "absorbed_effects": []}
    assert not score("viscous_tip_friction", required, named)["right"]  # allowed, never required
