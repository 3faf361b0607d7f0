"""
A first fit: the vane–housing COF of a test rig
================================================

A cylindrical test rig turns a 4-vane rotor at 5800 rpm inside a concentric bore, and an in-line
sensor logs the drive torque. On such a rig the torque is almost all vane-tip friction, so the
record tells the coefficient of friction (COF) between vane and housing. This tutorial fits it.

You need a configuration (the pump, in SI units) and a measurement (time and torque, optionally
speed). pumpsim ships both for this rig; in a shell:

.. code-block:: sh

    pumpsim example test_rig examples

copies ``examples/test_rig.toml`` and ``examples/data/test_rig_measurement.csv`` into the folder
``examples``. The same from Python:
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import pumpsim
from pumpsim.bundled import copy_example

examples = Path(tempfile.mkdtemp()) / "examples"  # any folder you like
for path in copy_example("test_rig", examples):
    print(path.relative_to(examples.parent))

# %%
# The configuration
# -----------------
# The TOML file describes the housing, the rotor, the vanes, the friction laws and the operating
# point. Every value is SI: metres, kilograms, seconds, radians (a speed may be given in rpm).
# :doc:`/reference/config` lists every key with its unit, default and allowed range.
print(open(examples / "test_rig.toml").read())

# %%
# ``load_config`` checks every key (an unknown key, a missing one, a value out of range or a
# geometry where the vanes cannot reach the housing is refused with the key's name) and gives a
# :class:`~pumpsim.PumpConfig`. Simulating it shows what the model expects to see:
cfg = pumpsim.load_config(examples / "test_rig.toml")
sim = pumpsim.simulate(cfg, duration=0.02, rate=20000)
print(sim.summary())

# %%
# The measurement
# ---------------
# A CSV file with a header line and one row per sample. Columns are picked by name; units come
# from the header (``torque [N*mm]``) or are SI. :doc:`/how-to/read-logger-files` covers MATLAB and
# TDMS files, other column names and units.
data = pumpsim.load_data(examples / "data/test_rig_measurement.csv")
print(f"{data.time.size} samples over {data.time[-1] - data.time[0]:.3f} s, "
      f"mean speed {np.mean(data.speed) * 30 / np.pi:.0f} rpm")

fig, ax = plt.subplots(figsize=(8, 3.2))
ax.plot(data.time * 1e3, data.torque * 1e3, lw=0.6, label="measured")
mu0 = cfg.values["friction.housing.dynamic"]
ax.plot(sim.time * 1e3, sim["torque"] * 1e3, lw=1.5, label=f"model, COF {mu0:g}")
ax.set(xlabel="time [ms]", ylabel="drive torque [mN·m]", xlim=(0, 20))
ax.legend(loc="lower right")
fig.tight_layout()

# %%
# On a concentric rig the model's torque is constant (each vane presses on the bore with its
# centrifugal force, and the friction torque does not depend on the angle); the measurement
# scatters around a slightly higher level. The configured COF 0.20 is a guess to be corrected.
#
# The fit
# -------
# :func:`pumpsim.identify` fits the named parameters by Gauss–Newton with exact derivatives of the
# compiled model. ``mu`` is the vane–housing dynamic COF (the static one keeps its configured
# ratio, and the slot COF follows in the configured proportion); ``theta0`` is the rotor angle at
# the first sample. These two are the default.
res = pumpsim.identify(cfg, data, params=["mu", "theta0"])
print(res)

# %%
# Read the result from the bottom up:
#
# * the residual tests (runs test, Ljung–Box) say the residual is white, so the standard errors
#   and 95 % intervals can be taken as they are;
# * the adequacy line says the model describes the data: nothing systematic is left;
# * ``theta0`` has no effect on the torque: a concentric rig's torque does not depend on the
#   angle, so no record can tell it. It gets no number, and the COF's fit is not affected.
#
# ``problems()`` is empty when the answer can be used as it is: converged, no parameter on a
# bound, the model adequate, no two parameters that the data cannot tell apart. The command line
# then exits with status 0; otherwise it exits 1 and still writes every output, listing the
# problems.
mu, se = res.value("mu"), res.estimates["mu"].stderr
print(f"mu = {mu:.4f} ± {se:.4f} (one standard error); problems: {res.problems()}")

# %%
# The record was simulated with a true COF of 0.203: the fit finds it within its standard error.
# Residual against time:
fig, ax = plt.subplots(figsize=(8, 3.2))
ax.plot(res.time * 1e3, res.residual * 1e3, lw=0.5)
ax.axhline(0.0, color="k", lw=0.8)
ax.set(xlabel="time [ms]", ylabel="measured − fitted [mN·m]",
       title=f"residual RMS {res.rms * 1e3:.2f} mN·m")
fig.tight_layout()

# %%
# The command line
# ----------------
# The same fit, with a JSON file of every figure and a self-contained HTML report:
#
# .. code-block:: sh
#
#     pumpsim identify examples/test_rig.toml examples/data/test_rig_measurement.csv \
#         --json fit.json --report fit.html
#
# Next: :doc:`plot_2_diagnosis` asks what to do when the residual is *not* white.
