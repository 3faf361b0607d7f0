"""The reduced robustness grid of bench/diagnose_grid.py (4 rig families x every library effect,
no effect and three out-of-library disturbances x SNR 5 and 10, with and without a speed column):
the issue's bar for the rates."""
import pytest

from bench.diagnose_grid import REDUCED, run, summarise


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="open (issue 11): on main 862469f the whole reduced grid (168 cases) "
                   "named right 73.6 % of 87, false names 1.3 % of 77, false unexplained 1.2 % of 83; the "
                   "k = 2 oval is right in 2 of 16 (README, discrepancy workflow); strict, so this turns "
                   "into a failure the day the rates are met and the mark must go")
def test_reduced_grid_rates():
    s = summarise(run(REDUCED, log=lambda msg: None))
    assert s["named_right_rate_snr_ge_5"] >= 0.90, s
    assert s["false_name_rate"] <= 0.05, s
    assert s["false_unexplained_rate"] <= 0.05, s
