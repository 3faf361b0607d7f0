"""The design reports' rules that need no simulation: engineering units, in-spec shares without the
failed designs, constant outputs, Sobol' rounding and clipping, grid curves with their failures
marked, scatter axes without offsets, a convergence panel per variable."""
import numpy as np
import pandas as pd
import pytest

from pumpsim.report import design_figures as fg
from pumpsim.report.design import _index_text
from pumpsim.design.study import study_from_dict
from pumpsim.design.summary import output_table, summary_text
from pumpsim.presentation import command_line, engineering_scale
from tests.conftest import EXAMPLES

ELLIPSE = str(EXAMPLES / "ellipse_4vanes.toml")


@pytest.mark.parametrize("unit, values, expect", [
    ("m", [0.0245], (1e3, "mm")), ("m", [4e-6, -2e-6], (1e6, "µm")), ("kg", [0.0012], (1e3, "g")),
    ("N·m", [0.0646], (1e3, "mN·m")), ("N·m", [0.13], (1.0, "N·m")), ("Pa·m/s", [3.3e6], (1e-6, "MPa·m/s")),
    ("W", [6e-27, 1e-3], (1e3, "mW")), ("N", [7.3], (1.0, "N")), ("m", [np.nan], (1e6, "µm"))])
def test_engineering_scale(unit, values, expect):
    assert engineering_scale(unit, values) == expect


def test_command_line_reads_as_typed():
    assert command_line(["/venv/bin/pumpsim", "sweep", "a b.toml"]) == "pumpsim sweep 'a b.toml'"
    assert command_line(["/x/pumpsim/__main__.py", "optimize", "s.toml"]) == "pumpsim optimize s.toml"
    assert command_line(["/x/pytest/__main__.py", "-q"]) == "python -m pytest -q"


def _grid_table():
    """Six designs of a grid, two not evaluated (geometry), one lifting off."""
    b = [0.0245, 0.0235, 0.0225, 0.0215, 0.0210, 0.0205]
    ptp = [1e-13, 0.01, 0.02, 0.04, np.nan, np.nan]
    status = ["ok", "ok", "ok", "lift_off: N < 0", "geometry: too long", "geometry: too long"]
    return pd.DataFrame({"design": range(6), "speed": 471.0, "housing.b": b, "ptp_torque": ptp,
                         "max_extension": [0.0045, 0.0045 + 1e-18, 0.0045, 0.0045, np.nan, np.nan],
                         "status": status})


def test_in_spec_share_leaves_failed_designs_out_and_a_grid_has_no_cpk():
    df = _grid_table()
    r = {x["output"]: x for x in output_table(df, ["ptp_torque", "max_extension"], {"ptp_torque": (None, 0.03)},
                                              sample=False)}
    p = r["ptp_torque"]
    assert (p["n_within"], p["n_evaluated"], p["n_failed"]) == (3, 4, 2)
    assert p["within"] == pytest.approx(0.75) and "cpk" not in p
    assert p["min"] == 0.0  # 1e-13 N·m is below the solver's resolution: shown as 0
    assert r["max_extension"]["constant"] and r["max_extension"]["sd"] == 0.0
    text = summary_text(df, ["ptp_torque"], {"ptp_torque": (None, 0.03)}, {"sampler": "grid", "designs": 6})
    assert "yield (" not in text and "4 evaluated rows (2 not evaluated)" in text
    assert "within every limit: 3 of the 4 evaluated rows" in text
    # the command's own table of a grid run without a results folder (no manifest): the study's
    # sampler says it is a grid, so no spread either
    alone = summary_text(df, ["ptp_torque"], {"ptp_torque": (None, 0.03)}, None, sampler="grid")
    assert "yield (" not in alone and "within every limit: 3 of the 4" in alone
    row = next(line for line in alone.splitlines() if line.startswith("ptp_torque"))
    assert row.split()[4] == "—"  # the sd column
    assert "cpk" in output_table(df, ["ptp_torque"], {"ptp_torque": (None, 0.03)})[0]


def _capture(monkeypatch):
    figs = []
    monkeypatch.setattr(fg, "figure_html", lambda fig, tight=True: figs.append(fig) or "<img>")
    return figs


def test_grid_curves_over_the_ratio_with_failed_designs_marked(monkeypatch):
    st = study_from_dict({"study": {"config": ELLIPSE, "sampler": "grid", "outputs": ["ptp_torque"]},
                          "vary": {"housing.b": {"values": list(_grid_table()["housing.b"])}},
                          "limits": {"ptp_torque": {"upper": 0.03}}})
    df = _grid_table()
    x, label = fg.quantity(df, st, "housing.b")
    np.testing.assert_allclose(x, 0.0245 / df["housing.b"].to_numpy())
    assert label.startswith("ellipse ratio a/b")
    figs = _capture(monkeypatch)
    fg.grid_plots(df, st)
    ax = figs[0].axes[0]
    crosses = [ln for ln in ax.get_lines() if ln.get_marker() == "x"]
    assert sum(len(ln.get_xdata()) for ln in crosses) == 2  # both failed designs drawn
    np.testing.assert_allclose(sorted(np.concatenate([ln.get_xdata() for ln in crosses])),
                               sorted(0.0245 / np.array([0.0210, 0.0205])))
    assert ax.get_xlabel() == "ellipse ratio a/b" and ax.get_title() == "ptp_torque [mN·m]"
    both = study_from_dict({"study": {"config": ELLIPSE, "sampler": "grid"}, "vary": {
        "housing.a": {"values": [0.0245, 0.025]}, "housing.b": {"values": [0.022, 0.023]}}})
    x, label = fg.quantity(df, both, "housing.b")  # both semi-axes vary: b itself, in mm
    assert label == "housing.b [mm]" and x[0] == pytest.approx(24.5)


def test_scatter_axes_in_engineering_units_without_offset(monkeypatch):
    rng = np.random.default_rng(0)
    n = 40
    r = 0.0225 + 4e-6 * rng.standard_normal(n)
    df = pd.DataFrame({"design": range(n), "speed": 607.0, "housing.radius": r,
                       "min_extension": 0.0025 + (r - 0.0225), "status": "ok"})
    st = study_from_dict({"study": {"config": str(EXAMPLES / "test_rig.toml"), "outputs": ["min_extension"]},
                          "vary": {"housing.radius": {"distribution": "normal", "sd": 4e-6}}})
    figs = _capture(monkeypatch)
    fg.scatter_matrix(df, st)
    ax = figs[0].axes[0]
    figs[0].canvas.draw()
    assert ax.get_xlabel() == "housing.radius [mm]" and ax.get_ylabel() == "min_extension [mm]"
    assert ax.xaxis.get_major_formatter().get_offset() == "" and ax.yaxis.get_major_formatter().get_offset() == ""


def test_sobol_values_rounded_to_their_interval_and_clipped():
    assert _index_text(0.963038, 0.38522) == ("0.96", "0.58 … 1.00")
    assert _index_text(6.6e-28, 6.1e-28) == ("0.000", "0.000 … 0.000")
    assert _index_text(-1.5e-12, 2.9e-12) == ("0.000", "0.000 … 0.000")
    assert _index_text(0.100329, 0.0702133) == ("0.100", "0.030 … 0.171")


def test_distinct_results_group_identical_indices():
    same = {"k1": {"S1": 0.9, "S1_conf": 0.1, "ST": 0.95, "ST_conf": 0.1},
            "k2": {"S1": 0.05, "S1_conf": 0.02, "ST": 0.06, "ST_conf": 0.02}}
    other = {"k1": {"S1": 0.2, "S1_conf": 0.1, "ST": 0.3, "ST_conf": 0.1},
             "k2": {"S1": 0.7, "S1_conf": 0.1, "ST": 0.8, "ST_conf": 0.1}}
    res = {"method": "sobol", "keys": ["k1", "k2"], "indices": {"a": same, "b": dict(same), "c": other}}
    assert [g for g, _ in fg.distinct_results(res)] == [["a", "b"], ["c"]]


def test_convergence_draws_every_variable_with_its_bounds(monkeypatch):
    keys = ["vane.mass", "vane.length", "rotor.slot_radius", "housing.b"]
    bounds = {"vane.mass": [6e-4, 1.6e-3], "vane.length": [0.0115, 0.0125],
              "rotor.slot_radius": [0.0085, 0.0095], "housing.b": [0.0211, 0.0233]}
    its = [{"objective": 30 - i, "violation": 0.0, "design": {k: bounds[k][0] + i * 1e-5 for k in keys}}
           for i in range(4)]
    res = {"iterations": its, "design": its[-1]["design"], "bounds": bounds,
           "objective": {"minimize": "friction_power"}}
    figs = _capture(monkeypatch)
    fg.convergence_figure(res, None)
    titles = [a.get_title() for a in figs[0].axes if a.axison]
    assert titles[2:] == ["vane.mass [g]", "vane.length [mm]", "rotor.slot_radius [mm]", "housing.b [mm]"]


def test_the_tornado_says_why_it_is_not_drawn():
    """Five designs cannot fit five keys plus a mean; a key that never varies has no influence:
    each is said in words, not a blank figure; enough designs draw it."""
    study = study_from_dict({"study": {"config": str(EXAMPLES / "test_rig.toml"), "sampler": "random",
                                       "samples": 5, "seed": 1},
                             "vary": {k: {"distribution": "normal", "sd": 1e-6}
                                      for k in ("housing.radius", "vane.length", "vane.mass",
                                                "vane.thickness", "rotor.radius")}})
    rng = np.random.default_rng(0)
    df = pd.DataFrame({k: rng.normal(size=5) for k in study.keys})
    df["mean_torque"], df["status"] = rng.normal(size=5), "ok"
    assert "Too few evaluated designs (5)" in fg.tornado(df, study) and "at least 7" in fg.tornado_gap(df, study)
    flat = df.assign(**{k: 1.0 for k in study.keys})
    assert fg.tornado_gap(flat, study).startswith("No key varies")
    more = pd.DataFrame({k: rng.normal(size=40) for k in study.keys})
    more["mean_torque"], more["status"] = rng.normal(size=40), "ok"
    assert fg.tornado_gap(more, study) is None
