"""
A pump-down: evacuating a brake booster
=======================================

In an electric or hybrid car no engine vacuum feeds the brake booster: an electric vacuum pump
(EVP) does. The questions a vehicle engineer asks of it are how long it takes to bring the booster
from atmosphere to its working vacuum, what current it draws on the way (the inrush at start-up
above all) and where the energy goes.

With the gas tables in its configuration (``[ports]``, ``[booster]``, and ``[motor]`` for a motor
drive) a pumpsim model becomes that vacuum pump: a gas cell between each pair of vanes, an inlet
window fed from the booster through a hose and a check valve, an exhaust window under a valve,
leaks past the vane tips and end faces, and a brushed DC motor on the shaft.
:doc:`/explanation/model` describes the physics.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import pumpsim
from pumpsim.bundled import copy_example
from pumpsim.pneumatics.pumpdown import fast_pumpdown, pump_maps, pumpdown

examples = Path(tempfile.mkdtemp()) / "examples"  # any folder you like
copy_example("evp_booster", examples)  # shell: pumpsim example evp_booster examples
cfg = pumpsim.load_config(examples / "evp_booster.toml")
p = cfg.pneumatic
volume = p.values["booster.volume"]
print(f"{cfg.name}: {cfg.vanes} vanes, booster {volume * 1e3:g} L from "
      f"{p.booster_start / 1e3:.1f} kPa to {p.booster_target / 1e3:.1f} kPa, "
      f"supply {p.values['motor.voltage']:g} V")

# %%
# The example is a 4-vane pump of about 18 cm³ per revolution in an eccentric bore, carbon vanes
# with round tips, a 12 V brushed motor (at 13.5 V here), and a 4 L booster to be brought from
# 101.3 kPa to 30 kPa absolute: the sizes of a passenger-car EVP, not of one product.
#
# The start: the full model
# -------------------------
# The full model integrates the rotor, the motor current and every cell's gas together, with
# the valves' opening and closing located in time. The first 0.3 s show the motor's inrush and
# the run-up to speed:
start = pumpdown(cfg, duration=0.3)
c = start.columns
fig, ax = plt.subplots(figsize=(8, 3.4))
ax.plot(c["time"] * 1e3, c["current"], color="C3", label="motor current")
ax.set(xlabel="time [ms]", ylabel="current [A]")
ax2 = ax.twinx()
ax2.plot(c["time"] * 1e3, c["speed"] * 30 / np.pi, color="C0", label="speed")
ax2.set_ylabel("speed [rpm]")
fig.legend(loc="center right", bbox_to_anchor=(0.88, 0.5), fontsize="small")
fig.tight_layout()
print(f"peak current {start.summary['peak_current']:.1f} A; speed after 0.3 s "
      f"{c['speed'][-1] * 30 / np.pi:.0f} rpm")

# %%
# The current peaks near the stall current V/R (13.5 V over 0.25 Ω) and falls as the back-EMF
# builds with the speed, to the running current of a pump at speed.
#
# The whole pump-down: the fast path
# ----------------------------------
# A full pump-down of this pump is about 5 s of simulated time and some 140,000 integrator
# steps. The *fast path* needs a few seconds once, for its maps, and then milliseconds per
# pump-down: at ten booster pressures the full model runs with the booster held until motor and
# cells are periodic, and averages the gas drawn, the current and the speed over four revolutions. The booster pressure then follows
# V_b/(R T) dp/dt = leak − ṁ(p) with those maps interpolated. It agrees with the full model within
# 2 % in time to target and mean current (the tests hold it to that).
pressures = np.geomspace(0.05 * p.booster_start, p.booster_start, 10)
maps = pump_maps(cfg, pressures)
fast = fast_pumpdown(cfg, maps)
print(f"time to {p.booster_target / 1e3:.0f} kPa: {fast['time_to_target']:.2f} s, "
      f"mean current {fast['mean_current']:.1f} A, energy {fast['energy']:.0f} J "
      f"(maps {maps.wall_time:.1f} s, pump-down {fast['wall_time'] * 1e3:.1f} ms)")

# %%
fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.6))
a1.plot(fast["time"], np.array(fast["booster_pressure"]) / 1e3, color="C0")
a1.axhline(p.booster_target / 1e3, color="k", ls="--", lw=0.8)
a1.annotate("target", (0.02, p.booster_target / 1e3), xytext=(0, 4),
            xycoords=("axes fraction", "data"), textcoords="offset points", fontsize="small")
a1.set(xlabel="time [s]", ylabel="booster pressure [kPa abs.]", title="pump-down")
a2.plot(maps.pressure / 1e3, maps.pumping_speed * 6e4, "o-", color="C2", ms=4)
a2.set(xlabel="booster pressure [kPa abs.]", ylabel="pumping speed [L/min]",
       title="pumping speed S(p)")
fig.tight_layout()

# %%
# The pumping speed falls towards low booster pressures: the gas left in the smallest cell at the
# end of the exhaust (the dead volume) re-expands into the next suction stroke, and the tip and
# end-face leaks carry gas back. Where S(p) reaches zero lies the pump's ultimate pressure.
#
# The command line runs the full model to the target and, with ``--report``, adds the maps, the
# energy split and the p–V diagram of a cell:
#
# .. code-block:: sh
#
#     pumpsim pumpdown examples/evp_booster.toml --out pumpdown.csv --json pumpdown.json \
#         --report pumpdown.html
#
# ``--fast`` prints the fast path beside the full result; ``--until PA`` sets another target.
