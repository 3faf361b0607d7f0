"""HTML reports: provenance with the right SHA-256, "±" meaning the same on the terminal and in the
HTML, units on every parameter, the optimistic-interval warning exactly when the residual is not
white, amplitude/phase instead of raw harmonic coefficients, the candidate ranking, the result's own
BIC figures, integer iteration ticks, self-contained pages."""
import dataclasses
import hashlib
import html
import re
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import pumpsim
from pumpsim.diagnosis import candidates, diagnose
from pumpsim.presentation import OPTIMISTIC, PLUS_MINUS, describe
from pumpsim.report.diagnosis import diagnosis_report
from tests.conftest import ROOT, make_config
from tests.integration.test_diagnose_effects import measurement
from tests.tolerances import DISPLAY_SE_REL, DISPLAY_VALUE_SE, EFFECT_PARAM_REL, OPTIMISTIC_FACTOR_MIN

RIG = ["examples/test_rig.toml", "examples/data/test_rig_measurement.csv"]
HIDDEN = ["examples/ellipse_4vanes.toml", "examples/data/ellipse_hidden_effects.csv"]


def _identify(tmp_path, files, params):
    rep = tmp_path / "fit.html"
    r = subprocess.run([sys.executable, "-m", "pumpsim", "identify", *files, "--params", params,
                        "--report", str(rep)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    return r.stdout, html.unescape(rep.read_text())


def _text(page):
    return re.sub(r"<[^>]+>", " ", page)


def test_identify_report_provenance_units_and_interval_meaning(tmp_path):
    stdout, page = _identify(tmp_path, RIG, "mu,theta0")
    sha = hashlib.sha256((ROOT / RIG[1]).read_bytes()).hexdigest()
    cfg_sha = hashlib.sha256((ROOT / RIG[0]).read_bytes()).hexdigest()
    text = _text(page)
    assert sha in text and cfg_sha in text and "test_rig_measurement.csv" in text
    assert f"pumpsim version {pumpsim.__version__}" in re.sub(r"\s+", " ", text)
    assert re.search(r"compiled kernel\s+constrained-n4-h0-[0-9a-f]{8,}", text)
    assert re.search(r"date \(UTC\)\s+\d{4}-\d\d-\d\d \d\d:\d\d:\d\d", text)
    # "±" is explained by the same sentence on the terminal and in the HTML
    assert PLUS_MINUS in stdout and PLUS_MINUS in text
    # every parameter row names its unit
    rows = re.findall(r"<tr><td class=t>(\w+)</td><td class=t>[^<]*</td><td class=t>([^<]*)</td>", page)
    assert {n for n, _ in rows} >= {"mu", "theta0"} and all(u for _, u in rows)
    assert dict(rows)["theta0"] == "rad" and dict(rows)["mu"] == "–"
    # a white residual on the rig: no optimistic-interval warning anywhere
    assert OPTIMISTIC not in stdout and "Intervals are optimistic" not in text
    assert page.count("data:image/png;base64,") >= 3
    assert not re.search(r"<(img|script|link)[^>]+(src|href)=\"(http|/|\.)", page)


def test_identify_widens_the_intervals_when_the_residual_is_not_white(tmp_path):
    stdout, page = _identify(tmp_path, HIDDEN, "mu,theta0")  # two hidden effects: residual not white
    # the intervals are already the residual-aware ones: no "optimistic" warning, the widening stated
    assert OPTIMISTIC not in stdout and "Intervals are optimistic" not in page
    assert "Intervals widened" in page and "Newey-West" in stdout and "lag-1 autocorrelation" in stdout
    f = float(re.search(r"up to ([0-9.]+)x wider", stdout).group(1))
    assert f > OPTIMISTIC_FACTOR_MIN and f"up to {f:.2g}x wider" in page


def test_parameter_units_come_from_the_registry():
    assert describe("housing.harmonics.5.amplitude", [[2, 0, 0]] * 4 + [[4, 0, 0], [4, 0, 0.39]])[1] == "m"
    assert "k = 4" in describe("housing.harmonics.5.amplitude", [[2, 0, 0]] * 4 + [[4, 0, 0], [4, 0, 0.39]])[0]
    assert describe("vane.mass") == ("vane.mass", "kg")
    assert describe("theta0@1")[0].endswith("(measurement 2)")
    assert describe("effects.viscous_tip_friction")[1] == "N s/m"


@pytest.fixture(scope="module")
def out_of_round_diagnosis():
    nominal = make_config("ellipse_4vanes")
    truth = dataclasses.replace(nominal, angle=0.4).with_harmonics([[4, 2e-5, 0.3]])
    ds, _ = measurement(nominal, truth)
    return nominal, ds, diagnose(nominal, ds)


def test_diagnosis_report_reads_like_an_engineers_table(tmp_path, out_of_round_diagnosis):
    cfg, ds, out = out_of_round_diagnosis
    assert out["effects"][:1] == ["housing_out_of_round"]
    rep = tmp_path / "d.html"
    diagnosis_report(out, rep, title=f"pumpsim diagnosis: {cfg.name}", cfg=cfg, data=ds)
    page = html.unescape(rep.read_text())
    text = re.sub(r"\s+", " ", _text(page))
    # no raw coefficient names; amplitude in µm and phase in rad with the standard error
    assert "housing.harmonics" not in text
    assert re.search(r"radial amplitude [0-9.]+ ± [0-9.]+ µm", text)
    amp = float(re.search(r"radial amplitude ([0-9.]+) ±", text).group(1))
    assert abs(amp - 20.0) < EFFECT_PARAM_REL * 20.0  # the truth: 20 µm
    assert PLUS_MINUS in text and PLUS_MINUS in out.summary()
    # the candidate ranking: every library candidate of the first screen, the chosen one marked
    assert "Candidate ranking" in text and "<tr class=chosen>" in page
    first = out["screens"][0]
    assert len(first["candidates"]) == len(candidates(cfg, set()))
    assert first["chosen"] == "housing_out_of_round(k=4)"
    ps = [c["p_value"] for c in first["candidates"]]
    assert ps == sorted(ps)
    for c in first["candidates"]:
        assert c["candidate"] in text
    # numbers never wrap: every numeric cell is nowrap, parameter lists are nowrap spans
    assert "td.n{text-align:right;white-space:nowrap" in page and "<span class=nb>" in page
    # a Dataset made in memory says so and is identified by the hash of its samples
    assert "(arrays passed in memory)" in text
    h = hashlib.sha256(np.ascontiguousarray(ds.time, dtype=float).tobytes()
                       + np.ascontiguousarray(ds.torque, dtype=float).tobytes()).hexdigest()
    assert f"{h} (of the samples)" in text


def test_diagnosis_report_shows_the_results_own_bic(tmp_path, out_of_round_diagnosis):
    """One definition of BIC on the page: the steps table shows each step's BIC before and after
    and their difference exactly as the result carries them (the acceptance test's), and an
    accepted step lowers it."""
    cfg, ds, out = out_of_round_diagnosis
    rep = tmp_path / "d.html"
    diagnosis_report(out, rep, cfg=cfg, data=ds)
    page = html.unescape(rep.read_text())
    for s in out.steps:
        assert s.bic_after < s.bic_before
        row = re.search(rf"<td class=t>{s.effect.name}</td>(.*?)</tr>", page).group(1)
        cells = re.findall(r"<td class=n>([^<]*)</td>", row)
        assert f"{s.bic_before:.1f}" in cells and f"{s.bic_after:.1f}" in cells
        assert f"{s.bic_after - s.bic_before:+.1f}" in cells
    assert out["steps"][0]["bic_before"] == out.steps[0].bic_before  # the JSON carries the same figures


def test_iteration_axes_have_integer_ticks_and_labels_are_not_clipped(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pumpsim.report import identification as report

    cfg = make_config("test_rig")
    res = pumpsim.simulate(cfg, duration=0.02, rate=10000)
    y = res.torque + np.random.default_rng(0).normal(0, 1e-3, res.torque.size)
    from pumpsim.data import Dataset
    from pumpsim.identification import identify

    fit = identify(cfg, Dataset(res.time, y), ["mu"], initial={"mu": 0.1})
    captured = []
    real = report.figure_html

    def grab(fig):
        fig.canvas.draw()
        captured.append(fig)
        return real(fig)

    report.figure_html = grab
    try:
        report.identification_report(fit, tmp_path / "r.html", cfg=cfg)
    finally:
        report.figure_html = real
    it_fig = next(f for f in captured if any(a.get_xlabel() == "iteration" for a in f.axes))
    for ax in it_fig.axes:
        ticks = ax.get_xticks()
        lo, hi = ax.get_xlim()
        shown = [t for t in ticks if lo <= t <= hi]
        assert all(float(t).is_integer() for t in shown), shown
    plt.close("all")


@pytest.mark.parametrize("value,stderr", [(0.20294549, 9.14e-5), (149.99999891, 2.9e-7), (15.6, 0.95),
                                          (-3.25e-5, 4.1e-7), (0.17000000012, 8.2e-9), (0.2, 1.05e10)])
def test_estimates_are_rounded_to_their_standard_error(value, stderr):
    """The shown value differs from the estimate by less than a tenth of the standard error, and
    the standard error keeps two significant digits (a rounded estimate never hides its ±)."""
    from pumpsim.presentation import fmt_estimate, fmt_interval

    v, e = fmt_estimate(value, stderr).split(" ± ")
    assert abs(float(v) - value) <= DISPLAY_VALUE_SE * stderr and abs(float(e) / stderr - 1) < DISPLAY_SE_REL
    lo, hi = fmt_interval(value - 2 * stderr, value + 2 * stderr, stderr).split(" … ")
    assert abs(float(lo) - (value - 2 * stderr)) <= DISPLAY_VALUE_SE * stderr
    assert abs(float(hi) - (value + 2 * stderr)) <= DISPLAY_VALUE_SE * stderr


def test_provenance_falls_back_on_the_results_own_record():
    from pumpsim.report.html import provenance_of

    own = {"config": "examples/test_rig.toml", "data": [{"name": "a.csv", "sha256": "ab" * 32}],
           "kernel_key": "constrained-n4-h0-123"}
    rows = dict(provenance_of(SimpleNamespace(provenance=own)))
    assert rows["data file"] == "a.csv" and rows["data file SHA-256"] == "ab" * 32
    assert rows["compiled kernel"] == "constrained-n4-h0-123" and rows["config"] == "examples/test_rig.toml"
    assert rows["pumpsim version"] == pumpsim.__version__


@pytest.mark.parametrize("runs_p,lb_p,consistent,says", [
    (0.40, 0.30, True, "white at 5 %"),
    (0.40, 3e-19, True, "not white at 5 %"),  # a remainder below the relevance bar: consistent, not white
    (0.01, 0.30, False, "not white at 5 %"),
])
def test_diagnosis_banner_says_what_the_whiteness_tests_say(tmp_path, out_of_round_diagnosis, runs_p, lb_p,
                                                            consistent, says):
    cfg, ds, out = out_of_round_diagnosis
    final = {**out.final, "runs_p_value": runs_p, "ljung_box_p_value": lb_p, "residual_white": consistent}
    changed = dataclasses.replace(out, final=final)
    # the terminal summary flags the intervals on the same test result as the page
    assert (OPTIMISTIC in changed.summary()) == (min(runs_p, lb_p) < 0.05)
    rep = tmp_path / "d.html"
    diagnosis_report(changed, rep, cfg=cfg, data=ds)
    banner = re.sub(r"\s+", " ", _text(html.unescape(rep.read_text()).split("<h2>")[0]))
    assert f"{says} (runs p = {runs_p:.3g}, Ljung–Box p = {lb_p:.3g})" in banner
    assert ("below the relevance bar" in banner) == (consistent and min(runs_p, lb_p) < 0.05)
    assert ("Intervals are optimistic" in banner) == (min(runs_p, lb_p) < 0.05)
