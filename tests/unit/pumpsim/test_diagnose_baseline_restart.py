"""The torque diagnosis's baseline fit that stalls at its start, which the start test finds NOT a
minimum (IdentificationResult.points_to set): fitted once more from where its Gauss-Newton step
points, the better by RMS kept with its own converged flag, and a note says so. A converged fit,
or a stall at a start that is a minimum (points_to None), is not fitted again."""
from dataclasses import dataclass, field
from types import SimpleNamespace

import pytest

from pumpsim.diagnosis import workflow
from pumpsim.diagnosis.log import BaselineRestarted


@dataclass
class Est:
    value: float


@dataclass
class Res:
    rms: float
    converged: bool
    points_to: dict | None = None
    estimates: dict = field(default_factory=lambda: {"mu": Est(0.17), "theta0": Est(0.4)})


def _run():
    return SimpleNamespace(cfg=None, full_data="record", screen_data="record", say=lambda msg: None, log=[])


def _fits(monkeypatch, results):
    calls = []

    def fit(cfg, data, names, values, ripple, screen, multistart=True, screen_hold=(), adequacy=False):
        calls.append((dict(values), multistart))
        return results[len(calls) - 1]

    monkeypatch.setattr(workflow, "_fit", fit)
    return calls


@pytest.mark.parametrize("first", [Res(1.0, True), Res(1.0, False), Res(1.0, True, {"theta0": 0.5})])
def test_a_converged_fit_or_one_without_a_slope_to_follow_is_not_fitted_again(monkeypatch, first):
    calls = _fits(monkeypatch, [first])
    run = _run()
    assert workflow._baseline_fit(run, ["mu", "theta0"], {"speed": 470.0}, []) is first
    assert len(calls) == 1 and not run.log


def test_a_start_that_is_not_a_minimum_is_fitted_again_from_where_its_slope_points(monkeypatch):
    stalled = Res(0.00043224, False, {"mu": 0.1701, "theta0": 0.7701})
    again = Res(0.00043065, True)
    calls = _fits(monkeypatch, [stalled, again])
    run = _run()
    assert workflow._baseline_fit(run, ["mu", "theta0"], {"speed": 470.0}, []) is again
    # the second fit starts where the slope pointed (held values kept), without a phase scan
    assert calls[1] == ({"speed": 470.0, "mu": 0.1701, "theta0": 0.7701}, False)
    assert run.log == [BaselineRestarted(0.00043224, 0.00043065, True)]
    assert "that fit is the baseline" in run.log[0].text()


def test_a_second_fit_that_is_not_better_leaves_the_first(monkeypatch):
    stalled = Res(1.0, False, {"theta0": 0.5})
    calls = _fits(monkeypatch, [stalled, Res(1.0, True)])  # equal RMS: not better
    run = _run()
    assert workflow._baseline_fit(run, ["mu", "theta0"], {}, []) is stalled
    assert len(calls) == 2 and run.log == [BaselineRestarted(1.0, 1.0, False)]
    assert "the first fit kept" in run.log[0].text()


def test_a_slope_pointing_out_of_the_pumps_geometry_is_not_followed(monkeypatch):
    """A stall whose Gauss-Newton step points where the model is not finite (a housing centre
    beyond the clearance: the identification raises StartError there) keeps the first fit, and
    the note says why, with no traceback."""
    from pumpsim.errors import StartError

    stalled = Res(0.00043224, False, {"housing.center.1": 0.19})
    calls = []

    def fit(cfg, data, names, values, ripple, screen, multistart=True, screen_hold=(), adequacy=False):
        calls.append(dict(values))
        if len(calls) > 1:
            raise StartError("the model is not finite at the fit's start")
        return stalled

    monkeypatch.setattr(workflow, "_fit", fit)
    run = _run()
    assert workflow._baseline_fit(run, ["mu", "theta0"], {"speed": 470.0}, []) is stalled
    assert len(calls) == 2 and run.log == [BaselineRestarted(0.00043224, None, False)]
    assert "not finite" in run.log[0].text() and "first fit kept" in run.log[0].text()
