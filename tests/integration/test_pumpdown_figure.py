"""The pump-down figure's torque split adds up: shaft torque = gas + friction + inertia (the
vanes' kinetic energy and the rotor's acceleration) at every angle of the plotted revolution."""
import re

import numpy as np

from pumpsim.pneumatics import pumpdown as pdm
from pumpsim.report.pumpdown import pumpdown_panels
from tests.pneumatic_helpers import evp_config
from tests.tolerances import ROUNDING_REL


def test_torque_split_panel_adds_up_to_the_shaft_torque():
    cfg = evp_config()
    res = pdm.pumpdown(cfg, duration=0.002)
    maps = pdm.pump_maps(cfg, [5e4, 1e5])
    fig, plt = pumpdown_panels(res, maps, cfg)
    try:
        panel = next(a for a in fig.axes if a.get_title().startswith("Torque split"))
        lines = {ln.get_label(): np.asarray(ln.get_ydata()) for ln in panel.get_lines()}
    finally:
        plt.close(fig)
    parts = lines["gas torque"] + lines["friction torque"] + lines["inertia (the rest)"]
    scale = np.max(np.abs(lines["shaft torque"]))
    np.testing.assert_allclose(parts, lines["shaft torque"], rtol=0, atol=ROUNDING_REL * scale)


def test_report_carries_operating_conditions_provenance_and_legends_off_the_curves(tmp_path):
    from pumpsim.config import load_config
    from pumpsim.report.pumpdown import pumpdown_report
    from tests.conftest import EXAMPLES

    cfg = load_config(EXAMPLES / "evp_booster.toml")  # from its file: the config's SHA-256 is known
    res = pdm.pumpdown(cfg, duration=0.002, until=9e4)
    maps = pdm.pump_maps(cfg, [5e4, 1e5])
    pumpdown_report(res, maps, cfg, tmp_path / "pd.html")
    page = re.sub(r"<img[^>]*>", "<img>", (tmp_path / "pd.html").read_text())
    assert "<td class=t>supply voltage</td><td class=t>13.5 V</td>" in page
    assert "<td class=t>booster volume</td><td class=t>4 L</td>" in page
    for item in ("config SHA-256", "compiled kernel", "pumpsim version", "date (UTC)", "command"):
        assert f"<td class=t>{item}</td>" in page, item
    assert re.search(r"pneumatic-n4-h\d+-[0-9a-f]{8,}", page)
    fig, plt = pumpdown_panels(res, maps, cfg)
    try:
        fig.canvas.draw()
        drawn = [a for a in fig.axes if a.get_lines() and a.get_legend() is not None]
        twins = [a for a in fig.axes if a.get_lines() and a.get_legend() is None]
        # every panel with curves has a legend (a twin axis shares its partner's) ...
        assert len(drawn) == 5 and all(any(b.bbox.bounds == a.bbox.bounds for b in drawn) for a in twins)
        for a in drawn:  # ... below its axes, off the curves
            assert a.get_legend().get_window_extent().y1 <= a.get_window_extent().y0 + 1
        labels = [t.get_text() for a in drawn for t in a.get_legend().get_texts()]
        assert "target 90 kPa" in labels and any(t.startswith("atmosphere") for t in labels)
        assert any(t.startswith("ultimate pressure") for t in labels)
    finally:
        plt.close(fig)
