"""
A diagnosis: what the nominal model lacks
==========================================

A fit answers "which value?". When the residual is not noise the next question is "which
effect?": an eccentric rotor, an out-of-round bore, a speed ripple of the drive, a sensor lag,
a vane of another material... ``pumpsim diagnose`` answers it from the torque record: it fits the
nominal model, tests the residual, and adds, one at a time, the effects that explain it
significantly and plausibly. :doc:`/explanation/discrepancy-workflow` explains each step.

The example: a 4-vane pump in an elliptical housing at 471 rad/s, logged with 5 % torque noise.
Two defects were built into the simulated record and are not in its configuration.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import pumpsim
from pumpsim.bundled import copy_example

examples = Path(tempfile.mkdtemp()) / "examples"  # any folder you like
copy_example("ellipse_4vanes", examples)  # pumpsim example ellipse_4vanes examples
cfg = pumpsim.load_config(examples / "ellipse_4vanes.toml")
data = pumpsim.load_data(examples / "data/ellipse_hidden_effects.csv")
# the first 1000 samples (0.1 s, about 7.5 revolutions) keep this page quick; the command line
# at the end runs the whole record
n = 1000
record = {"time": data.time[:n], "torque": data.torque[:n], "speed": data.speed[:n]}

# %%
# First, the plain fit
# --------------------
# The COF and the rotor phase, as in :doc:`plot_1_first_fit`:
fit = pumpsim.identify(cfg, record)
print(fit)

# %%
# The COF comes out, but the residual tests reject whiteness and the adequacy check finds a
# systematic residual well above the noise. The intervals printed are then optimistic, and the
# residual holds something the model lacks. Its spectrum in shaft orders (multiples of the
# rotation frequency) shows where:
n = fit.residual.size
dt = float(np.mean(np.diff(fit.time)))
amp = 2 * np.abs(np.fft.rfft(fit.residual)) / n
order = np.fft.rfftfreq(n, dt) / (fit.speed / (2 * np.pi))
fig, ax = plt.subplots(figsize=(8, 3.2))
ax.plot(order, amp * 1e3, lw=0.8)
ax.set(xlim=(0, 20), xlabel="shaft order", ylabel="residual amplitude [mN·m]",
       title="residual of the nominal fit")
fig.tight_layout()

# %%
# Lines at shaft orders 1 and 4 (and their neighbours) stand out of the noise: something turns with
# the shaft. Several defects make lines there; the diagnosis decides between them.
#
# The diagnosis
# -------------
d = pumpsim.diagnose(cfg, record)
print(d)

# %%
# How to read the step table:
#
# * **baseline**: the nominal model's fit (COF and phase); its RMS is what the effects must reduce;
# * each further row is an effect that was accepted: its parameters with one standard error, the
#   RMS before and after, and the p-value of its likelihood-ratio test. A speed ripple at shaft
#   order 1 is the drive's speed pulsing once a revolution; an out-of-round at order 4 is a bore
#   with four lobes;
# * **verdict**: consistent with noise after these two effects -- nothing else is left to explain;
# * **confounded**: pairs of explanations the data cannot tell apart, such as viscous tip friction
#   and a higher COF at a single speed; a second speed separates them (see
#   :doc:`/how-to/several-speeds`). Confounded pairs are reported, never named as findings.
#
# The record was made with two defects: a speed ripple of 0.2 % at order 1 and a 15 µm lobe at
# order 4 (``examples/make_measurements.py`` in the source tree). Compare them with the table.
#
# The result reads like the JSON (``d.to_json()`` is all of it):
print("effects:", d["effects"])
print("verdict:", d["verdict"])
mu = d["final"]["params"]["mu"]
print(f"final mu (mean over the vanes): {mu['value']:.4f} ± {mu['stderr']:.4f}")

# %%
# The named effects, in the model
# -------------------------------
# The final model's torque against the record over the first revolution, beside the nominal
# model's:
base = d.history[0].result  # the fits behind the steps: first the baseline,
final = d.history[-1].result  # last the fit with every named effect
rev = 2 * np.pi / fit.speed
keep = fit.time - fit.time[0] < rev
fig, ax = plt.subplots(figsize=(8, 3.6))
deg = (fit.time[keep] - fit.time[0]) * fit.speed * 180 / np.pi
ax.plot(deg, fit.measured[keep] * 1e3, ".", ms=3, color="0.6", label="measured")
ax.plot(deg, base.fitted[keep] * 1e3, lw=1.2, label="nominal model")
ax.plot(deg, final.fitted[keep] * 1e3, lw=1.2, label="with the named effects")
ax.set(xlabel="rotor angle, first revolution [deg]", ylabel="drive torque [mN·m]")
ax.legend(loc="upper right", fontsize="small")
fig.tight_layout()

# %%
# The command line writes the same result as JSON and as an HTML report with the residual
# figures and the ranking of every candidate at every step:
#
# .. code-block:: sh
#
#     pumpsim diagnose examples/ellipse_4vanes.toml examples/data/ellipse_hidden_effects.csv \
#         --json diagnosis.json --report diagnosis.html
#
# To carry a named effect into further work, put it into the configuration: an out-of-round as
# ``housing.harmonics``, a speed ripple as ``effects.speed_ripple`` (see :doc:`/reference/config`).
