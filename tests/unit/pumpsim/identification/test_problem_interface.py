"""The identification package: one Problem interface (constant speed, joint, transient) with start
values and bounds from one place, one Optimiser interface, one result."""
import numpy as np
import pytest

from pumpsim.data import Dataset
from pumpsim.errors import ConfigError
from pumpsim.identification import (ConstantSpeedProblem, FitOutcome, JointProblem, Optimiser, Problem,
                                    TransientProblem, identify, identify_transient, make_problem)
from tests.conftest import transient_start_config as _start
from tests.tolerances import METHODS_AGREE_REL


@pytest.fixture
def run(transient_run):
    return transient_run


def test_every_kind_of_problem_is_one_interface_with_shared_starts_and_bounds(run):
    ds = Dataset(run.time, run.torque, run.speed)
    names = ["mu", "vane.mass", "theta0"]
    const = make_problem(_start(), ds, names, initial={"vane.mass": 0.004})
    joint = make_problem(_start(), [ds, ds], names, initial={"vane.mass": 0.004})
    trans = make_problem(_start(), ds, names, initial={"vane.mass": 0.004}, transient=True)
    assert (type(const), type(joint), type(trans)) == (ConstantSpeedProblem, JointProblem, TransientProblem)
    for prob in (const, joint, trans):
        assert isinstance(prob, Problem)
        for attr in ("model", "model_and_jacobian", "residual", "time_axis", "speed_of", "angle", "start"):
            assert callable(getattr(prob, attr)), (type(prob).__name__, attr)
    # the shared names start and are bounded alike in every problem (one function, the registries)
    for n in ("mu", "vane.mass"):
        got = {(float(p.x0[p.names.index(n)]), float(p.lower[p.names.index(n)]), float(p.upper[p.names.index(n)]))
               for p in (const, joint, trans)}
        assert len(got) == 1, (n, got)
    assert const.x0[const.names.index("mu")] == 0.1 and const.x0[const.names.index("vane.mass")] == 0.004
    # theta0 starts at the measurement's angle when the data has one, else the config's
    assert trans.x0[trans.names.index("theta0")] == const.x0[const.names.index("theta0")] == _start().angle


def test_names_are_checked_alike_and_the_transient_specials_are_its_own(run):
    ds = Dataset(run.time, run.torque, run.speed)
    for transient in (False, True):
        with pytest.raises(ConfigError, match="unknown parameter 'vane.mas'.*did you mean vane.mass"):
            make_problem(_start(), ds, ["vane.mas"], transient=transient)
        with pytest.raises(ConfigError, match="names a parameter twice"):
            make_problem(_start(), ds, ["mu", "mu"], transient=transient)
    with pytest.raises(ConfigError, match="unknown parameter 'speed0'"):  # a transient's only
        make_problem(_start(), ds, ["speed0"])
    with pytest.raises(ConfigError, match="transient identification fits one measurement"):
        make_problem(_start(), [ds, ds], ["mu"], transient=True)


def test_optimiser_checks_its_settings_once():
    with pytest.raises(ConfigError, match="method must be one of"):
        Optimiser("newton")
    with pytest.raises(ConfigError, match=r"relaxation must be in \(0, 1\]"):
        Optimiser(relaxation=1.5)
    assert Optimiser("levenberg-marquardt", 0.5).method == "levenberg-marquardt"


def test_transient_fit_runs_through_the_same_optimisers(run):
    """Gauss-Newton and Levenberg-Marquardt on the same transient problem reach one minimum; the
    outcome is a named object; IPOPT is refused with the reason (CVODES adjoints inside it)."""
    ds = Dataset(run.time, run.torque, run.speed + np.random.default_rng(1).normal(0, 0.01, run.time.size))
    prob = make_problem(_start(), ds, ["mu", "speed0"], transient=True)
    gn, lm = (Optimiser(m).fit(prob, prob.x0) for m in ("gauss-newton", "levenberg-marquardt"))
    assert isinstance(gn, FitOutcome) and gn.converged and lm.converged
    assert lm.x == pytest.approx(gn.x, rel=METHODS_AGREE_REL)
    res = identify(_start(), ds, ["mu", "speed0"], method="levenberg-marquardt", transient=True)
    assert res.method == "levenberg-marquardt/transient" and res.value("mu") == pytest.approx(gn.x[0],
                                                                                             rel=METHODS_AGREE_REL)
    with pytest.raises(ConfigError, match="'ipopt' fits constant-speed data"):
        identify_transient(_start(), ds, ["mu"], method="ipopt")
