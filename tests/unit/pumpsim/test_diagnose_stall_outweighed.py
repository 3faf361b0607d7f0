"""A torque diagnosis whose baseline fit did not converge, but whose named effects each gain far
more BIC than the baseline's remaining step is worth (result.stall_outweighed): the verdict does
not rest on the stall -- no exit 1, no 'provisional', the baseline's note says why. Where a named
step's gain is within STALL_MARGIN times that worth, or nothing is named, the stall still counts."""
from dataclasses import dataclass
from types import SimpleNamespace

import pytest

from pumpsim.diagnosis.log import NotConverged
from pumpsim.diagnosis.options import OPTIONS
from pumpsim.diagnosis.result import STALL_MARGIN, NamedSteps, stall_outweighed


@dataclass
class Step:
    delta_bic: float


def base(converged=False, left=65.5):
    return SimpleNamespace(converged=converged, left_chi2=left)


@pytest.mark.parametrize("left,gains,expected", [
    (65.5, [7055.0], True),  # the bench record's 20 um oval
    (65.5, [7055.0, 300.0], False),  # a second effect within 10 x 65.5 + 10 of it
    (65.5, [], False),  # nothing named: the baseline is the final model
    (None, [7055.0], False),  # its worth unknown
    (float("inf"), [7055.0], False),  # noise-free data
])
def test_a_stall_is_outweighed_only_by_every_named_steps_gain(left, gains, expected):
    steps = [Step(-g) for g in gains]
    assert stall_outweighed(base(left=left), steps, OPTIONS) is expected
    assert not stall_outweighed(base(converged=True), steps, OPTIONS)


def test_the_margin_is_ten_times_the_worth_plus_the_decisive_bic():
    edge = STALL_MARGIN * 65.5 + OPTIONS.bic_decisive
    assert stall_outweighed(base(), [Step(-(edge + 1e-6))], OPTIONS)
    assert not stall_outweighed(base(), [Step(-edge)], OPTIONS)


class Result(NamedSteps):
    def __init__(self, baseline, steps):
        self.baseline, self.final, self.steps, self.log = baseline, {"converged": True}, steps, ()
        self.history = (None,) * (1 + len(steps))


def test_an_outweighed_stall_is_no_reason_to_exit_1():
    assert Result({"converged": False, "stall_outweighed": True}, [Step(-7055.0)]).unconverged() == []
    assert Result({"converged": False, "stall_outweighed": False}, [Step(-7055.0)]).unconverged() == \
        ["the baseline fit is NOT converged"]


def test_the_baseline_note_says_why_the_verdict_stands():
    note = NotConverged("baseline", "no step from the start lowered the residual", "measurement",
                        outweighed_by=(65.5, 7055.0))
    text = note.text()
    assert "NOT converged" in text and "~65.5 noise variances" in text and "at least 7055" in text
    assert "does not rest on it" in text and "may be wrong" not in text
    assert "may be wrong" in NotConverged("baseline", "why", "measurement").text()
