"""The reduced robustness grid of bench/diagnose_grid.py (4 rig families x every library effect,
no effect and three out-of-library disturbances x SNR 5 and 10, with and without a speed column):
the issue's bar for the rates."""
import pytest

from bench.diagnose_grid import REDUCED, run, summarise


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="open (issue 11): the k = 2 oval is not named right (concentric4 + "
                   "ellipse4 at SNR 5, 42 cases: named right 80 % of 20, false names 4.5 % of 22, false "
                   "unexplained 0 % of 24; the other rigs not run); strict, so this turns into a failure "
                   "the day the rates are met and the mark must go")
def test_reduced_grid_rates():
    s = summarise(run(REDUCED, log=lambda msg: None))
    assert s["named_right_rate_snr_ge_5"] >= 0.90, s
    assert s["false_name_rate"] <= 0.05, s
    assert s["false_unexplained_rate"] <= 0.05, s
