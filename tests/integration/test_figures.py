"""Simulation figures an engineer reads at a glance: every legend entry names a visible line,
legends beside the curves, short tick labels on constant signals, config name and speed in the
title, ripple and shaft orders that match the signal."""
import math
import subprocess
import sys

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402

import pumpsim  # noqa: E402
from pumpsim.report.simulation import simulation_figure, torque_orders, vane_groups  # noqa: E402
from tests.conftest import ROOT, make_config  # noqa: E402
from tests.tolerances import AXIS_SPAN_MIN_REL, ORDER_AMPLITUDE_ABS


@pytest.fixture(scope="module")
def ellipse4():
    cfg = make_config("ellipse_4vanes")
    return cfg, pumpsim.simulate(cfg, duration=2.2 * 2 * math.pi / cfg.speed, rate=20000)


def _drawn(ax):
    """(colour, linestyle) of every line on the axes that shows at least two finite points."""
    out = set()
    for ln in ax.lines:
        y = np.asarray(ln.get_ydata(), dtype=float)
        if np.count_nonzero(np.isfinite(y)) >= 2 and ln.get_label().startswith("_"):
            out.add((to_rgba(ln.get_color()), ln.get_linestyle()))
    return out


def _legend_axes(fig):
    return [ax for ax in fig.axes if ax.get_legend() is not None]


def test_every_legend_entry_names_a_visible_distinct_line(ellipse4):
    cfg, res = ellipse4
    fig = simulation_figure(res, name=cfg.name)
    checked = 0
    for ax in _legend_axes(fig):
        handles = ax.get_legend().legend_handles
        keys = [(to_rgba(h.get_color()), h.get_linestyle()) for h in handles]
        assert len(set(keys)) == len(keys), ax.get_ylabel()  # entries distinguishable
        drawn = _drawn(ax)
        for k, h in zip(keys, handles):
            assert k in drawn, f"legend entry '{h.get_label()}' on '{ax.get_ylabel()}' has no line"
        checked += 1
    assert checked >= 4  # s, N, slot forces, torque
    labels = {ax.get_ylabel(): [t.get_text() for t in ax.get_legend().get_texts()] for ax in _legend_axes(fig)}
    s_panel = next(v for k, v in labels.items() if k.startswith("vane extension"))
    # on an ellipse vane i and vane i + 2 see the same housing: one line, said so
    assert s_panel == ["vane 0 = vane 2", "vane 1 = vane 3"]
    slot = next(v for k, v in labels.items() if k.startswith("slot forces"))
    assert len(slot) == 4 and all("F1" in t or "F2" in t for t in slot)
    plt.close(fig)


def test_vanes_that_differ_keep_their_own_lines(tmp_path):
    # an eccentric housing (centre 0.2 mm off) breaks the ellipse's half-turn symmetry
    cfg = make_config("ellipse_4vanes", **{"housing.center": [2e-4, 0.0]})
    res = pumpsim.simulate(cfg, duration=1.1 * 2 * math.pi / cfg.speed, rate=20000)
    fig = simulation_figure(res, name=cfg.name)
    ax = next(a for a in _legend_axes(fig) if a.get_ylabel().startswith("vane extension"))
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [f"vane {i}" for i in range(4)]
    plt.close(fig)
    a = np.sin(np.linspace(0, 6, 50))
    assert vane_groups(np.array([a, a + 1e-3, a.copy(), 2 * a])) == [[0, 2], [1], [3]]


def test_legends_sit_beside_the_axes_not_on_the_curves(ellipse4):
    cfg, res = ellipse4
    fig = simulation_figure(res, name=cfg.name)
    fig.canvas.draw()
    for ax in _legend_axes(fig):
        box, leg = ax.get_window_extent(), ax.get_legend().get_window_extent()
        assert leg.x0 >= box.x1 - 1, ax.get_ylabel()
    plt.close(fig)


def test_constant_signals_get_short_tick_labels_and_no_offset():
    # concentric cylinder at constant speed: s, N, slot forces and torque are constant
    cfg = make_config("test_rig")
    res = pumpsim.simulate(cfg, duration=2.1 * 2 * math.pi / cfg.speed, rate=20000)
    fig = simulation_figure(res, name=cfg.name)
    fig.canvas.draw()
    for ax in fig.axes:
        if not ax.axison:
            continue
        labels = [t.get_text() for t in ax.get_yticklabels() if t.get_text()]
        assert all(len(t) <= 7 for t in labels), (ax.get_ylabel(), labels)
        assert ax.yaxis.get_offset_text().get_text() == "", ax.get_ylabel()
        lo, hi = ax.get_ylim()
        assert hi - lo > AXIS_SPAN_MIN_REL * max(abs(lo), abs(hi), 1e-12), ax.get_ylabel()  # not a zoom into rounding
    text = " ".join(t.get_text() for ax in fig.axes for t in ax.texts)
    assert "no ripple" in text  # the order spectrum of a constant torque is not rounding noise
    plt.close(fig)


def test_title_names_config_and_speed_and_axis_is_rotor_angle(ellipse4):
    cfg, res = ellipse4
    fig = simulation_figure(res, name=cfg.name)
    title = fig._suptitle.get_text()
    assert cfg.name in title and "471 rad/s" in title and "4497.7 rpm" in title and "speed drive" in title
    xlabels = [ax.get_xlabel() for ax in fig.axes if ax.get_xlabel()]
    assert any(x.startswith("rotor angle θ [deg]") for x in xlabels)
    for ax in fig.axes:  # every drawn axis carries a unit in brackets
        if ax.axison and ax.get_ylabel():
            assert "[" in ax.get_ylabel() and "]" in ax.get_ylabel(), ax.get_ylabel()
    plt.close(fig)
    fig = simulation_figure(res, name=cfg.name, x="time")
    assert any(ax.get_xlabel() == "time [s]" for ax in fig.axes)
    plt.close(fig)


def test_python_api_figure_title_names_the_config_without_being_told(ellipse4):
    cfg, res = ellipse4  # res.plot(path) in the README passes no name: the Solution carries it
    assert res.config_name == cfg.name
    fig = simulation_figure(res)
    assert fig._suptitle.get_text().startswith(f"{cfg.name}: ")
    plt.close(fig)


def test_cli_figure_title_and_refused_format(tmp_path):
    svg = tmp_path / "f.svg"
    r = subprocess.run([sys.executable, "-m", "pumpsim", "simulate", "examples/test_rig.toml", "--plot", str(svg)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    text = svg.read_text()
    assert "test-rig" in text and "5800 rpm" in text  # SVG text stays text
    bad, csv = tmp_path / "f.foo", tmp_path / "o.csv"
    r = subprocess.run([sys.executable, "-m", "pumpsim", "simulate", "examples/test_rig.toml", "--plot", str(bad),
                        "--out", str(csv)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2 and "'.foo' is not supported" in r.stderr and "Traceback" not in r.stderr
    assert not bad.exists() and not csv.exists()  # refused before the run: nothing written


@pytest.mark.parametrize("warp", [0.0, 0.3])
def test_ripple_and_orders_are_exact_from_whole_revolutions(warp):
    """Torque 1 + 0.2 cos 4θ + 0.05 sin(8θ + 0.3) over 3.4 revolutions, sampled in time at a speed
    that is constant (warp 0) or varies by ±30 % within each revolution: the angle-domain
    resampling gives the order amplitudes and the peak-to-peak within 1e-4."""
    t = np.linspace(0.0, 1.0, 20001)
    w0 = 3.4 * 2 * math.pi
    theta = 0.7 + w0 * t + warp * np.sin(w0 * t)  # speed w0 (1 + warp cos w0 t)
    tq = 1 + 0.2 * np.cos(4 * theta) + 0.05 * np.sin(8 * theta + 0.3)
    cols = {"angle": theta, "torque": tq}
    res = type("R", (), {"__getitem__": lambda self, k: cols[k]})()
    o = torque_orders(res)
    assert o["whole"] == 3
    amp = dict(zip(o["orders"].tolist(), o["amplitudes"]))
    assert abs(amp[0] - 1.0) < ORDER_AMPLITUDE_ABS and abs(amp[4] - 0.2) < ORDER_AMPLITUDE_ABS
    assert abs(amp[8] - 0.05) < ORDER_AMPLITUDE_ABS
    assert max(abs(amp[k]) for k in amp if k not in (0, 4, 8)) < ORDER_AMPLITUDE_ABS
    phi = np.linspace(0, 2 * math.pi, 200001)
    exact = 0.2 * np.cos(4 * phi) + 0.05 * np.sin(8 * phi + 0.3)
    assert abs(o["ptp"] - np.ptp(exact)) < ORDER_AMPLITUDE_ABS


def test_contact_model_figure_keeps_penetration_and_step_panels():
    cfg = make_config("ellipse_4vanes", **{"contact.housing.stiffness": 1e6, "contact.bottom.stiffness": 1e6})
    res = pumpsim.simulate(cfg, model="contact", duration=0.015, rate=20000, initial="housing")
    fig = simulation_figure(res, name=cfg.name)
    ylabels = [ax.get_ylabel() for ax in fig.axes]
    assert "penetration δ [µm]" in ylabels and "integrator step [s]" in ylabels
    pen = next(ax for ax in fig.axes if ax.get_ylabel() == "penetration δ [µm]")
    assert pen.get_legend() is not None
    plt.close(fig)
