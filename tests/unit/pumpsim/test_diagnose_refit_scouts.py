"""A geometric refit's scouting of its polar starts: every start scouted in full unless the caller
says which fits could still matter; then only the finalists by a quick look first, the rest only
where the finalists' fit could still matter, and then the same winner as scouting all."""
from dataclasses import dataclass

from pumpsim.diagnosis import refit
from pumpsim.diagnosis.options import OPTIONS
from pumpsim.identification import SMOOTH_COLUMNS


@dataclass
class Fit:
    rms: float
    start: int
    steps: int
    polished: bool
    converged: bool = True
    message: str = "residual no longer decreases"  # a scout a stop rule ended at its minimum


class Scouts:
    """scout_fit over starts 0..n-1: a quick look's cost `quick[i]`, a full scout's `full[i]`;
    records every call."""

    def __init__(self, quick, full):
        self.quick, self.full, self.calls = quick, full, []

    def __call__(self, init, max_iter, polish=True, final_jacobian=True, interval=True):
        assert final_jacobian or not polish  # only a quick look goes without its end's Jacobian
        assert (interval == SMOOTH_COLUMNS) == (not polish)  # ... and without the sub-sample runs
        self.calls.append((init, max_iter, polish, final_jacobian))
        cost = self.full[init] if polish else self.quick[init]
        return Fit(cost, init, max_iter, polish)


def finish(r, settle=True):
    return Fit(r.rms, r.start, -1 if settle else 1, True)  # "fitted to convergence" (or one step) from that scout


# the best full scout (start 5) is not among the three best quick looks (0, 1, 2)
QUICK = [1.0, 1.1, 1.2, 5.0, 6.0, 7.0, 8.0]
FULL = [0.9, 0.95, 0.97, 4.0, 3.0, 0.5, 2.0]


def test_without_needed_every_start_is_scouted_in_full_the_first_best_wins():
    sc = Scouts(QUICK, FULL + [0.5])  # a tie: the first best start wins, as min() over the starts
    res, settled = refit._scouted(list(range(8)), sc, finish, OPTIONS)
    assert (res.start, res.rms) == (5, 0.5)
    assert [c[0] for c in sc.calls] == list(range(8))
    assert all(c[1] == OPTIONS.refit_scout_steps and c[2] for c in sc.calls)


def test_a_fit_that_cannot_matter_is_scouted_from_the_finalists_only():
    sc = Scouts(QUICK, FULL)
    res, settled = refit._scouted(list(range(7)), sc, finish, OPTIONS, needed=lambda r: False)
    quick = [c for c in sc.calls if not c[2]]
    full = [c[0] for c in sc.calls if c[2]]
    assert len(quick) == 7 and all(c[1] == OPTIONS.refit_quick_steps and not c[3] for c in quick)
    assert full == [0, 1, 2]  # the three lowest quick looks, in their order
    assert (res.start, res.rms, settled) == (0, 0.9, True)


def test_a_finalists_scout_that_trails_is_not_finished_and_nothing_else_is_scouted():
    sc = Scouts(QUICK, FULL)
    asked = []
    res, settled = refit._scouted(list(range(7)), sc, finish, OPTIONS, needed=lambda r: asked.append(r) or True,
                                  behind=lambda r: r.rms > 0.8)
    assert [c[0] for c in sc.calls if c[2]] == [0, 1, 2]  # the finalists only
    assert (res.start, res.steps, settled) == (0, 1, False) and not asked  # one step from the best scout
    res, settled = refit._scouted(list(range(7)), Scouts(QUICK, FULL), finish, OPTIONS, needed=lambda r: True,
                                  behind=lambda r: r.rms > 0.95)  # it does not trail: as without `behind`
    assert (res.start, res.rms, settled) == (5, 0.5, True)


def test_a_fit_that_could_matter_gets_every_start_and_the_same_winner_as_all():
    sc = Scouts(QUICK, FULL)
    seen = []
    res, settled = refit._scouted(list(range(7)), sc, finish, OPTIONS, needed=lambda r: seen.append(r.start) or True)
    assert seen == [0]  # asked once, about the finalists' fit
    assert sorted(c[0] for c in sc.calls if c[2]) == list(range(7))  # each start scouted in full once
    assert (res.start, res.rms) == (5, 0.5)
    ref, _ = refit._scouted(list(range(7)), Scouts(QUICK, FULL), finish, OPTIONS)
    assert (ref.start, ref.rms) == (res.start, res.rms)


def test_few_starts_are_all_finalists_without_a_quick_look():
    sc = Scouts(QUICK[:2], FULL[:2])
    res, settled = refit._scouted([0, 1], sc, finish, OPTIONS, needed=lambda r: True)
    assert all(c[2] for c in sc.calls) and (res.start, res.rms) == (0, 0.9)


def test_incomplete_contenders_are_completed_and_sorted_again_only_past_the_judged_ones():
    """A contender cut short trails the first by more than completing it can gain: it is completed
    (as the full refit would have made it) only when the judging goes past the first."""
    def made(label, bic, complete=None):
        return refit.Contender(label, None, None, None, bic, complete)
    done = []

    def completes(label, bic):
        return lambda: done.append(label) or made(label, bic)
    fits = [made("lead", 1.0), made("smooth", 5.0), made("oval2", 9.0, completes("oval2", 3.0)),
            made("offset", 7.0, completes("offset", 6.0))]
    assert not done
    refit.completed_contenders(fits, 1)
    assert sorted(done) == ["offset", "oval2"]
    assert [(f.cand, f.bic_screen, f.complete) for f in fits] == [
        ("lead", 1.0, None), ("oval2", 3.0, None), ("smooth", 5.0, None), ("offset", 6.0, None)]
    refit.completed_contenders(fits, 2)  # all complete: nothing more
    assert sorted(done) == ["offset", "oval2"]


@dataclass
class Stalled:
    rms: float
    converged: bool
    points_to: dict | None
    init: dict


def test_a_refit_stalled_on_a_step_is_fitted_again_from_where_its_slope_points():
    """A refit no step left from a start that is not a minimum goes on from the point its
    Gauss-Newton step names (the other values kept), the better by RMS kept; a converged fit, or
    one stalled at a minimum (no point named), is left as it is."""
    calls = []

    def fit(init, rms=0.8):
        calls.append(init)
        return Stalled(rms, True, None, init)
    stalled = Stalled(1.0, False, {"b": 2.5}, {"a": 1.0, "b": 2.0})
    again = refit._past_stall(fit, stalled.init, stalled)
    assert calls == [{"a": 1.0, "b": 2.5}] and again.rms == 0.8
    assert refit._past_stall(lambda init: fit(init, rms=1.2), stalled.init, stalled) is stalled  # worse: kept
    calls.clear()
    for res in (Stalled(1.0, True, None, {}), Stalled(1.0, False, None, {})):
        assert refit._past_stall(fit, {}, res) is res
    assert not calls


def test_a_scout_ended_by_its_iteration_limit_is_finished_even_if_its_flag_says_converged():
    from types import SimpleNamespace as NS

    from pumpsim.identification.optimiser import MAX_ITER, NO_DECREASE, STEP_BELOW_SE
    below = STEP_BELOW_SE.format(lim=0.2, se=0.01, name="mu")
    assert refit._stopped_at_minimum(NS(converged=True, message=NO_DECREASE))
    assert not refit._stopped_at_minimum(NS(converged=True, message=below))  # converged by the s.e. bar
    assert not refit._stopped_at_minimum(NS(converged=False, message=MAX_ITER))


def test_the_one_step_start_is_finished_where_its_scout_still_descends():
    """The one-step start (0) trails every scout after a few steps but its scout stopped at its
    iteration limit, still descending: it is fitted to convergence too, and its fit kept where it
    ends lower (a 10 um oval on the eccentric 5-vane circle: 2.95e-4 after 4 steps, 1.17e-4 at
    convergence, against the best scout's 1.45e-4). A scout stopped at its minimum is not."""
    from pumpsim.identification.optimiser import MAX_ITER

    deeper = {0: 0.4}

    class Descending(Scouts):
        def __call__(self, init, max_iter, polish=True, final_jacobian=True, interval=True):
            r = super().__call__(init, max_iter, polish, final_jacobian, interval)
            return Fit(r.rms, r.start, r.steps, r.polished, init != 0, "" if init else MAX_ITER)

    def finish_deeper(r, settle=True):
        return Fit(deeper.get(r.start, r.rms), r.start, -1, True)

    full = [3.0, 0.95, 0.97, 4.0, 3.0, 0.5, 2.0]
    res, settled = refit._scouted(list(range(7)), Descending(QUICK, full), finish_deeper, OPTIONS)
    assert (res.start, res.rms, settled) == (0, 0.4, True)
    deeper[0] = 0.6  # its fit ends higher than the best scout's: that one stands
    res, _ = refit._scouted(list(range(7)), Descending(QUICK, full), finish_deeper, OPTIONS)
    assert (res.start, res.rms) == (5, 0.5)
    # the same where the caller says the fit could still matter (the finalists first)
    deeper[0] = 0.4
    res, _ = refit._scouted(list(range(7)), Descending(QUICK, full), finish_deeper, OPTIONS, needed=lambda r: False)
    assert (res.start, res.rms) == (0, 0.4)
    # stopped at its minimum: not finished again
    res, _ = refit._scouted(list(range(7)), Scouts(QUICK, full), finish_deeper, OPTIONS)
    assert (res.start, res.rms) == (5, 0.5)


def test_a_one_start_contender_far_behind_on_its_quick_look_is_not_scouted():
    """The quick look decides only where it trails by more than a scout could gain over it
    (OPTIONS.quick_look_gain in RMS) beyond behind's own margin; else the scout runs as before."""
    lead = 1.0

    def behind(r, allowance=1.0):  # trails the lead's RMS by more than 10 %, times the allowance
        return r.rms > 1.1 * allowance * lead
    far = 1.1 * OPTIONS.quick_look_gain * lead * 1.01
    for quick, scouted in ((far, False), (0.99 * far, True), (1.05, True)):
        sc = Scouts([quick], [0.9 * quick])
        got = refit._scout_unless_far_behind(lambda **kw: sc(0, **kw), behind, OPTIONS)
        kinds = [c[2] for c in sc.calls]  # polish: a full scout
        assert kinds == ([False, True] if scouted else [False])
        assert got.rms == (0.9 * quick if scouted else quick)


def test_trailing_by_rss_on_the_common_samples_with_an_allowance():
    import numpy as np

    @dataclass
    class Res:
        residual: np.ndarray
        keep: object = None
    lead = Res(np.ones(100))
    bar = (1 + OPTIONS.refit_gain) ** 2  # in RMS
    assert refit._trails(Res(np.full(100, 1.01 * bar)), lead, OPTIONS)
    assert not refit._trails(Res(np.full(100, 0.99 * bar)), lead, OPTIONS)
    assert not refit._trails(Res(np.full(100, 2.9 * bar)), lead, OPTIONS, allowance=3.0)
    assert refit._trails(Res(np.full(100, 3.1 * bar)), lead, OPTIONS, allowance=3.0)
    assert not refit._trails(Res(np.full(100, 9.0)), Res(np.ones(50)), OPTIONS)  # a lead on fewer samples: never
