"""Design reports a review can trust: provenance on every page; a grid without the statistics of
a sample, its failed designs counted apart and marked; a tolerance study's constant output shown
as constant; sensitivity with one block per distinct result and intervals within [0, 1];
optimisation with active bounds and constraints flagged and every variable's convergence."""
import html
import re

import numpy as np

from pumpsim import design
from pumpsim.report.design_figures import distinct_results
from pumpsim.report.design import optimize_report, sensitivity_report, sweep_report
from pumpsim.presentation import sha256
from tests.conftest import EXAMPLES

RIG = EXAMPLES / "test_rig.toml"
ELLIPSE = EXAMPLES / "ellipse_4vanes.toml"


def _load(tmp_path, text):
    path = tmp_path / "study.toml"
    path.write_text(text)
    return design.load_study(path), path


def _assert_provenance(page, study_path, config_path, kernels):
    assert "<h2>Provenance</h2>" in page
    for item in ("study file SHA-256", "base config SHA-256", "compiled kernel", "pumpsim version",
                 "date (UTC)", "command"):
        assert f"<td class=t>{item}</td>" in page, item
    assert sha256(study_path) in page and sha256(config_path) in page
    for k in kernels:
        assert re.search(rf"{k}\d+-[0-9a-f]{{8,}}", page), k


def _read(path):
    """The page without its embedded images (base64 could spell any word)."""
    return re.sub(r"<img[^>]*>", "<img>", path.read_text())


def _row(page, output):
    m = re.search(rf"<tr[^>]*><td class=t>{output}</td>(.*?)</tr>", page)
    return html.unescape(re.sub(r"<[^>]+>", "|", m.group(1)))


def test_grid_report_shows_no_sample_statistics_and_counts_failed_designs_apart(tmp_path):
    # a/b = 1.0, 1.1, 1.2: the last is out of reach of the vanes (a geometry failure)
    st, path = _load(tmp_path, f'[study]\nconfig = "{ELLIPSE}"\nsampler = "grid"\n'
                     '[vary."housing.b"]\nvalues = [0.0245, 0.022273, 0.020417]\n'
                     '[vary."rotor.vanes"]\nvalues = [2, 4]\n[limits.ptp_torque]\nupper = 0.03\n')
    df, _ = design.sweep(st, workers=0)
    failed = int((df["status"].str.split(":").str[0] == "geometry").sum())
    assert failed == 2
    sweep_report(df, st, tmp_path / "grid.html")
    page = _read(tmp_path / "grid.html")
    _assert_provenance(page, path, ELLIPSE, ["constrained-n2-h", "constrained-n4-h"])
    for word in ("Cpk", "Histogram", "Yield", "sd</th>"):
        assert word not in page, word
    inside = int(((df["status"] == "ok") & (df["ptp_torque"] <= 0.03)).sum())
    assert f"Within every limit: {inside} of the {len(df) - failed} evaluated designs" in page
    assert f"{failed} design(s) not evaluated (geometry {failed})" in page
    assert "x axis: ellipse ratio a/b" in page


def test_tolerance_report_shows_a_constant_output_as_constant(tmp_path):
    # a concentric rig: the torque is constant over the revolution, ptp_torque is rounding noise
    st, path = _load(tmp_path, f'[study]\nconfig = "{RIG}"\nsampler = "sobol"\nsamples = 16\nseed = 3\n'
                     '[vary."housing.radius"]\ndistribution = "normal"\nsd = 4e-6\n'
                     '[vary."vane.mass"]\ndistribution = "normal"\nsd = 0.02\nrelative = true\n'
                     '[limits.mean_torque]\nupper = 0.15\n')
    df, _ = design.sweep(st, workers=0)
    assert 0 < df["ptp_torque"].abs().max() < 1e-9  # the noise the report must not show as data
    sweep_report(df, st, tmp_path / "mc.html")
    page = _read(tmp_path / "mc.html")
    _assert_provenance(page, path, RIG, ["constrained-n4-h"])
    row = _row(page, "ptp_torque")
    assert "constant" in row and "e-" not in row, row
    assert "Cpk" in page and "Yield" in page  # a sample: its statistics belong here


def test_sensitivity_report_one_block_per_distinct_result_and_intervals_in_0_1(tmp_path):
    st, path = _load(tmp_path, f'[study]\nconfig = "{RIG}"\nseed = 1\n'
                     '[vary."vane.mass"]\ndistribution = "normal"\nsd = 0.05\nrelative = true\n'
                     '[vary."friction.housing.dynamic"]\ndistribution = "uniform"\nlow = 0.15\nhigh = 0.25\n'
                     '[sensitivity]\nsamples = 16\nresamples = 200\n')
    res = design.sensitivity(st, workers=0)
    groups = [set(g) for g, _ in distinct_results(res)]
    # at one speed the friction power is the mean torque times the speed: one result, drawn once
    assert any({"mean_torque", "friction_power"} <= g for g in groups)
    assert len(groups) < len(res["indices"])
    sensitivity_report(res, st, tmp_path / "s.html")
    page = _read(tmp_path / "s.html")
    _assert_provenance(page, path, RIG, ["constrained-n4-h"])
    ends = [float(x) for pair in re.findall(r"(-?[\d.]+) … (-?[\d.]+)", page) for x in pair]
    assert ends and min(ends) >= 0.0 and max(ends) <= 1.0
    raw = [v for per in res["indices"].values() for r in per.values() for v in
           (r["S1"] - r["S1_conf"], r["ST"] + r["ST_conf"])]
    assert min(raw) < 0 or max(raw) > 1  # the unclipped intervals do cross the bounds
    assert "e-" not in re.sub(r"SHA-256.*", "", page.split("<h2>Sobol")[1].split("<h2>The designs")[0])


def test_optimisation_report_flags_active_constraints_and_draws_every_variable(tmp_path):
    st, path = _load(tmp_path, f'[study]\nconfig = "{RIG}"\n[vary."vane.mass"]\nbounds = [0.0005, 0.002]\n'
                     '[vary."friction.housing.dynamic"]\nbounds = [0.15, 0.25]\n'
                     '[objective]\nminimize = "friction_power"\n[constraints.min_normal_force]\nlower = 5.0\n')
    res = design.optimize(st)
    optimize_report(res, st, tmp_path / "o.html")
    page = _read(tmp_path / "o.html")
    _assert_provenance(page, path, RIG, ["constrained-n4-h"])
    assert "active (lower)" in _row(page, "min_normal_force")  # the optimum presses at 5 N
    fric = _row(page, "friction.housing.dynamic")
    assert "at lower bound" in fric and "|–|" in fric  # least friction: the lowest COF
    assert "<td class=t>g</td>" in page  # vane mass in g, not kg
    n_images = page.split("<h2>Convergence</h2>")[1].count("<img")
    assert n_images >= 1 and np.isfinite(res["objective"]["value"])
