"""A grid record (bench/diagnose_grid.py: the 4-vane ellipse with an eccentric rotor, a speed
column, SNR 10, seed 1) whose baseline fit no step leaves from its phase-scan start, though the
slope there points 4.1 standard errors away (the start test's p = 0.0002): before, the diagnosis
reported its baseline NOT converged (the command exits 1). Fitted again from where the slope
points, the baseline converges with a lower RMS, and so does the final fit."""
import pytest

from bench.diagnose_grid import make_case
from pumpsim.diagnosis import diagnose


@pytest.fixture(scope="module")
def diagnosed():
    nominal, ds, info = make_case("ellipse4", "rotor_eccentricity", 10.0, 1, True)
    return diagnose(nominal, ds), info


def test_a_baseline_stalled_off_its_minimum_is_fitted_again_and_converges(diagnosed):
    out, info = diagnosed
    note = next(n for n in out.notes if n.startswith("baseline: no step left its start"))
    assert note.endswith("that fit is the baseline")
    before, after = (float(v) for v in note.split("(RMS ")[1].split(")")[0].split(" -> "))
    assert after < before and out.baseline["rms"] == pytest.approx(after, rel=1e-5)
    assert out.baseline["converged"] is True and out.final["converged"] is True
    assert not out.unconverged()
    assert out.effects == ["rotor_eccentricity"]
