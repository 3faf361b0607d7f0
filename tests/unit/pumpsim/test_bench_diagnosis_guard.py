"""The bench-log diagnosis's misspecification guard (pump_guard) on linear stand-ins for a fit: a
model that describes the data holds the guard's level; one that describes it on average only (the
truth has a time dependence the model's columns lack) is caught, with the parameter and the parts
where it disagrees. The guard on real twin logs: test_bench_diagnose."""
import numpy as np
import pytest

from pumpsim.diagnosis.options import OPTIONS
from pumpsim.diagnosis.pump_guard import GUARD_PARTS, NAMED_SHARE, Inconsistent, consistency, part_labels


def pumpdown(n=150):
    """Two channels over a 0.5 s pump-down (pressure, current samples) and a falling pressure."""
    tp = np.linspace(0.0, 0.5, n)
    tc = np.linspace(0.002, 0.5, n - 20)  # another channel, another sampling
    t = np.concatenate([tp, tc])
    # smooth, partly correlated columns, as a vane COF and a leak act on a pump-down
    J = np.column_stack([np.exp(-4 * t) + 0.3, np.concatenate([1 - np.exp(-6 * tp), 0.5 * np.exp(-3 * tc)])])
    return [tp, tc], t, J, (tp, 1e5 * np.exp(-2 * tp))


def fitted(J, y):
    b = np.linalg.lstsq(J, y, rcond=None)[0]
    return y - J @ b, b


def test_part_labels_cut_the_log_into_time_thirds_across_channels():
    times = [np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5]), np.array([0.0, 0.2, 0.49])]
    lab = part_labels(times)
    assert lab.tolist() == [0, 0, 1, 1, 2, 2, 0, 1, 2]
    assert set(part_labels(times, 2)) == {0, 1}


def test_guard_holds_its_level_on_a_model_that_describes_the_data():
    """White noise around the model: the statistic is chi-square on (parts - 1) x 2 dof; the guard
    fires on ~its level (0.25 %) of 3000 draws -- at most 1 % (binomial: 7.5 expected, 30 is 8 sd off)."""
    times, t, J, pressure = pumpdown()
    rng = np.random.default_rng(5)
    names, values = ["mu", "booster.leak"], {"mu": 0.17, "booster.leak": 4e-5}
    out = [consistency(names, values, fitted(J, J @ [0.3, -0.2] + rng.standard_normal(t.size))[0], J, times, pressure)
           for _ in range(3000)]
    assert all(g["dof"] == (GUARD_PARTS - 1) * 2 for g in out)
    assert np.mean([g["fires"] for g in out]) <= 0.01
    assert np.mean([g["statistic"] for g in out]) == pytest.approx(4.0, abs=0.3)  # chi2 on 4 dof: mean 4, se 0.05


def test_guard_fires_on_a_model_that_describes_the_data_on_average_only():
    """The truth carries a slope in time the model has no column for (a larger booster read as
    leaks): the least-squares fit leaves a remainder of ~1.5 noise sigmas, and the parts ask for
    different values; the worst parameter is reported with its value on each part and the pressures there."""
    times, t, J, pressure = pumpdown()
    rng = np.random.default_rng(2)
    r, b = fitted(J, J @ [0.3, -0.2] + 6.0 * (t - 0.25) ** 2 / 0.0625 + rng.standard_normal(t.size))
    g = consistency(["mu", "booster.leak"], {"mu": 0.17, "booster.leak": 4e-5}, r, J, times, pressure)
    assert g["fires"] and g["p_value"] < OPTIONS.stationary_alpha
    w = g["worst"]
    assert w["name"] in ("mu", "booster.leak") and len(w["parts"]) == GUARD_PARTS
    vals = [p["value"] for p in w["parts"]]
    assert max(vals) - min(vals) > 3 * max(p["stderr"] for p in w["parts"])
    first, last = w["parts"][0], w["parts"][-1]
    assert first["time"][0] == 0.0 and last["time"][1] == pytest.approx(0.5)
    assert first["pressure"][0] == pytest.approx(1e5) and last["pressure"][1] < first["pressure"][1]
    note = Inconsistent(("mu", "booster.leak"), ("booster_leak",), g["statistic"], g["dof"], g["p_value"],
                        g["alpha"], w).text()
    assert note.startswith("model inadequate") and "(booster_leak) are withdrawn" in note and w["name"] in note


def test_zero_rows_left_out_of_the_fit_carry_nothing():
    """A value the fit leaves out (the switch-on current block: weight 0, its Jacobian row 0) does
    not count: the statistic is the same without it."""
    times, t, J, pressure = pumpdown()
    rng = np.random.default_rng(9)
    r = fitted(J, rng.standard_normal(t.size))[0]
    J0, r0 = J.copy(), r.copy()
    J0[150], r0[150] = 0.0, 0.0
    a = consistency(["a", "b"], {"a": 0.0, "b": 0.0}, r0, J0, times, pressure)
    keep = np.arange(t.size) != 150
    b = consistency(["a", "b"], {"a": 0.0, "b": 0.0}, r0[keep], J[keep],
                    [times[0], times[1][1:]], pressure)
    assert a["statistic"] == pytest.approx(b["statistic"], rel=1e-9)


def test_a_significant_but_irrelevant_disagreement_does_not_fire():
    """A long log makes a tiny disagreement significant: the guard claims it only once letting the
    parameters differ between the parts would change the model by the naming size (a quarter noise
    sigma RMS), as a named effect must."""
    times, t, J, pressure = pumpdown(n=20000)
    rng = np.random.default_rng(4)
    r = fitted(J, J @ [0.3, -0.2] + 0.6 * (t - 0.25) ** 2 / 0.0625 + rng.standard_normal(t.size))[0]
    g = consistency(["a", "b"], {"a": 0.0, "b": 0.0}, r, J, times, pressure)
    assert g["p_value"] < 1e-6 and g["size"] < OPTIONS.named_size and not g["fires"], g
    big = fitted(J, J @ [0.3, -0.2] + 6.0 * (t - 0.25) ** 2 / 0.0625 + rng.standard_normal(t.size))[0]
    assert consistency(["a", "b"], {"a": 0.0, "b": 0.0}, big, J, times, pressure)["fires"]


def test_a_disagreement_the_size_of_what_the_named_effect_explains_fires():
    """A gap of the model's form in one time part is diluted by every sample of a long log, below the
    naming size; the named effect (column b, a trade with a) took up part of it. Relevance is then
    measured against what the named effect explains: a disagreement worth a tenth of that fires, the
    same disagreement beside a clear effect (which explains far more) does not, and a model that
    describes the data still holds the level."""
    times, t, J, pressure = pumpdown(n=6000)
    rng = np.random.default_rng(3)
    gap = 0.5 * (t < 0.17)  # the first third only, half a noise sigma
    noise = rng.standard_normal(t.size)

    def named(coef):
        y = J @ [0.3, coef] + gap + noise
        r_base = fitted(J[:, :1], y)[0]
        r, _ = fitted(J, y)
        explained = float(r_base @ r_base - r @ r)
        return r, explained

    r, explained = named(0.0)  # the effect is absent: what it explains is the gap's share
    g = consistency(["a", "b"], {"a": 0.0, "b": 0.0}, r, J, times, pressure, explained=explained)
    assert g["size"] < OPTIONS.named_size and g["p_value"] < OPTIONS.stationary_alpha, g
    assert g["excess"] >= NAMED_SHARE * explained and g["fires"], g
    assert not consistency(["a", "b"], {"a": 0.0, "b": 0.0}, r, J, times, pressure)["fires"]  # the old measure
    r, explained = named(-3.0)  # a clear effect: the same remainder is small beside it
    g = consistency(["a", "b"], {"a": 0.0, "b": 0.0}, r, J, times, pressure, explained=explained)
    assert g["p_value"] < OPTIONS.stationary_alpha and not g["fires"], g
    white = [consistency(["a", "b"], {"a": 0.0, "b": 0.0}, fitted(J, rng.standard_normal(t.size))[0], J, times,
                         pressure, explained=1.0)["fires"] for _ in range(400)]
    assert np.mean(white) <= 0.02  # the level (0.25 %) holds: relevance never replaces significance
