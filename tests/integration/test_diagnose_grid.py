"""The reduced robustness grid of bench/diagnose_grid.py (4 rig families x every library effect,
no effect and three out-of-library disturbances x SNR 5 and 10, with and without a speed column):
the issue's bar for the rates."""
import pytest

from bench.diagnose_grid import REDUCED, run, summarise


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="open (issue 11): with the interval Jacobian and polar starts (h11-diag) "
                   "the whole reduced grid gave named right 90.8 % of 87 on main 0a735d3 + them, but 87.4 % "
                   "of 87 after rebasing onto d676e4b, 88.5 % with the probe window for the polar starts' scouting "
                   "(false names 1.3 % of 77, false unexplained 0.0 % of 97; "
                   "README, discrepancy workflow); strict, so this turns into a failure the day the rates "
                   "are met and the mark must go")
def test_reduced_grid_rates():
    s = summarise(run(REDUCED, log=lambda msg: None))
    assert s["named_right_rate_snr_ge_5"] >= 0.90, s
    assert s["false_name_rate"] <= 0.05, s
    assert s["false_unexplained_rate"] <= 0.05, s
