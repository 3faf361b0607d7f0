"""The pump-down figure's torque split adds up: shaft torque = gas + friction + inertia (the
vanes' kinetic energy and the rotor's acceleration) at every angle of the plotted revolution."""
import numpy as np

from pumpsim.pneumatics import pumpdown as pdm
from pumpsim.pneumatics.figures import _figure
from tests.pneumatic_helpers import evp_config
from tests.tolerances import ROUNDING_REL


def test_torque_split_panel_adds_up_to_the_shaft_torque():
    cfg = evp_config()
    res = pdm.pumpdown(cfg, duration=0.002)
    maps = pdm.pump_maps(cfg, [5e4, 1e5])
    fig, plt = _figure(res, maps, cfg)
    try:
        panel = next(a for a in fig.axes if a.get_title().startswith("Torque split"))
        lines = {ln.get_label(): np.asarray(ln.get_ydata()) for ln in panel.get_lines()}
    finally:
        plt.close(fig)
    parts = lines["gas torque"] + lines["friction torque"] + lines["inertia (the rest)"]
    scale = np.max(np.abs(lines["shaft torque"]))
    np.testing.assert_allclose(parts, lines["shaft torque"], rtol=0, atol=ROUNDING_REL * scale)
