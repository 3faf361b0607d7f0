"""How far an interrupted bench-log fit got: the fit, with its last pump-down run as a detail."""
from pumpsim import interrupt
from pumpsim.identification.pumpdown_fit import fitting


def _said():
    return interrupt.Interrupted().message()


def test_a_model_run_inside_a_fit_is_said_as_a_detail_of_the_fit():
    with interrupt.handling():
        with fitting(["mu", "booster.leak"]):
            # the pump-down model's last progress before the signal: its run had ended
            interrupt.progress("at simulated t = 0.04 s of 0.04 s (booster 56760 Pa)", detail=True)
            said = _said()
            assert said.startswith("interrupted by SIGINT in a fit of mu, booster.leak before its first "
                                   "iteration ended; its last model run at simulated t = 0.04 s of 0.04 s"), said
            interrupt.progress("in a fit of mu, booster.leak after 2 iterations (residual RMS 1.3 N m)")
            interrupt.progress("at simulated t = 0.01 s of 0.04 s (booster 9e4 Pa)", detail=True)
            assert "after 2 iterations (residual RMS 1.3 N m); its last model run at simulated t = 0.01 s" in _said()
        # outside a fit a simulation's progress is the run's own
        interrupt.progress("at simulated t = 0.02 s of 0.04 s (booster 8e4 Pa)", detail=True)
        assert _said().startswith("interrupted by SIGINT at simulated t = 0.02 s of 0.04 s")
