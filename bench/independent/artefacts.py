"""Records of kinds a test rig produces that are neither a pump effect of the library nor a disturbance
the first grids tried: sensor, logger and operating artefacts. Each kind states its right answer
(`EXPECTED`, in the record's truth as `expected`) and why:

* gain_error - the torque cell's gain 2-5 % off (a calibration). mu absorbs the friction part (mu
  comes out off by the gain); what no mu/theta0 change mimics is the gain times the inertial torque.
  Right: nothing named; `unexplained` only when that unmimicked part is observable (the record's
  absorbed rule of records.py: at least ABSORBED_Z sigma over the record and ABSORBED_SIZE per sample);
  no library effect is a gain.
* quantised - the torque ADC's LSB is 0.5-2 noise sigmas (noise added before the converter, so the
  quantisation error is nearly uniform and white, variance LSB^2 / 12). Right: nothing, consistent.
* dropped - 0.5-2 % of the samples missing in bursts of 1-5 (a logger's buffer overruns); the time
  column keeps the true instants. Right: nothing, consistent (the model is evaluated at the times).
* jitter - a software-timed logger: each sample taken up to 0.4 sample intervals off the nominal grid
  (Gaussian, 0.15 dt), the time column holds the true instants. Right: nothing, consistent.
* offset_step - the torque zero jumps once (an amplifier range switch) at 30-70 % of the record.
  Right: nothing named (a constant offset is not it: it is not stationary), `unexplained`.
* cogging - the motor's cogging at an integer shaft order 6, 8 or 12: an in-line torque sensor sees a
  torque ripple only by accelerating the pump side, so it is a speed ripple of that order (made as
  one, 0.2-1 %). Right: speed_ripple named.
* gear_ripple - the same through a belt or gearbox: a speed ripple at a NON-integer shaft order
  (ratio 1.37-3.61). Not shaft-synchronous, not a pump effect. Right: nothing named, `unexplained`.
* clipped - the torque cell's range cuts the top 0.5-3 % of the samples (they read the range's end
  value). The other samples are a clean record. Right: nothing named, consistent (the clipped samples
  carry only 'at least this', so they are left out, with a note).
* runup - the record starts while the motor still runs up: speed 85-95 % of the final one at the
  start, reaching it (smoothly) after 15-30 % of the record; written with the measured speed column.
  Right: nothing named and consistent -- the measured speed column shows what happened, and the
  spec's model with that speed explains the torque.
* pink_noise - 1/f sensor noise (no white floor). band_noise - white noise plus a sensor resonance
  (a second-order resonator at 0.25-0.4 x the sample rate, Q 5). Coloured noise is not a pump effect:
  the rule is that NO effect is named; `unexplained` is right (reported, not required) when the
  detectors find the residual not white with a relevant systematic part, because the white-noise
  assumption of every test fails, and the notes say where.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from .rig import drive_torque, motion

ARTEFACTS = ("gain_error", "quantised", "dropped", "jitter", "offset_step", "cogging", "gear_ripple",
             "clipped", "runup", "pink_noise", "band_noise")
# the right answer: "quiet" (nothing named, no `unexplained`), "unexplained" (nothing named,
# `unexplained`), "no_name" (nothing named; `unexplained` either way), or the effects to name;
# "absorbed_or_unexplained": quiet when the unmimicked part is absorbed, else unexplained
EXPECTED = {"gain_error": "absorbed_or_unexplained", "quantised": "quiet", "dropped": "quiet", "jitter": "quiet",
            "offset_step": "unexplained", "cogging": ["speed_ripple"], "gear_ripple": "unexplained",
            "clipped": "quiet", "runup": "quiet", "pink_noise": "no_name", "band_noise": "no_name"}
MEASURED_SPEED = ("runup",)   # kinds written only with the measured speed column


def sample(effect, rig, rng):
    """The artefact's parameters for this rig."""
    if effect == "gain_error":
        return dict(gain=float(rng.choice([-1, 1]) * rng.uniform(0.02, 0.05)))
    if effect == "quantised":
        return dict(lsb=rng.uniform(0.5, 2.0))                   # x noise sigma
    if effect == "dropped":
        return dict(fraction=rng.uniform(0.005, 0.02))
    if effect == "jitter":
        return dict(sd=0.15)                                     # x sample interval
    if effect == "offset_step":
        return dict(at=rng.uniform(0.3, 0.7), sign=float(rng.choice([-1, 1])))
    if effect == "cogging":
        return dict(k=int(rng.choice([6, 8, 12])), eps=rng.uniform(0.002, 0.01), phase=rng.uniform(0, 2 * np.pi))
    if effect == "gear_ripple":
        return dict(k=float(rng.choice([1.37, 2.29, 3.61])), eps=rng.uniform(0.005, 0.02),
                    phase=rng.uniform(0, 2 * np.pi))
    if effect == "clipped":
        return dict(fraction=rng.uniform(0.005, 0.03))
    if effect == "runup":
        return dict(start=rng.uniform(0.05, 0.15), until=rng.uniform(0.15, 0.3))   # speed deficit, x record
    if effect == "band_noise":
        return dict(f=rng.uniform(0.25, 0.4), q=5.0)             # x sample rate
    return {}


def instants(effect, p, n, rate, rng):
    """The true sampling instants (the time column writes them) and the samples kept."""
    t = np.arange(n) / rate
    keep = np.ones(n, bool)
    if effect == "jitter":
        t = t + np.clip(p["sd"] * rng.standard_normal(n), -0.4, 0.4) / rate
        t -= t[0]
    if effect == "dropped":
        for start in rng.choice(n - 8, size=max(1, int(p["fraction"] * n / 3)), replace=False):
            keep[start + 1: start + 1 + int(rng.integers(1, 6))] = False
    return t, keep


def runup_motion(t, speed, theta0, start, until):
    """omega = w (1 - a (1 - t/T)^2) for t < T, then w: smooth (omega' continuous) at T."""
    T = until * (t[-1] - t[0])
    x = np.clip((t - t[0]) / T, 0.0, 1.0)
    omega = speed * (1 - start * (1 - x) ** 2)
    theta = theta0 + speed * (t - t[0]) - speed * start * T * (1 - (1 - x) ** 3) / 3
    domega = np.where(x < 1, 2 * speed * start * (1 - x) / T, 0.0)
    return theta, omega, domega


def shaft_torque(effect, p, rig, t, theta0):
    """The pump's torque along the artefact's motion (theta, omega, torque)."""
    if effect in ("cogging", "gear_ripple"):
        th, om, dom = motion(t, rig.speed, theta0, (p["k"], p["eps"], p["phase"]))
    elif effect == "runup":
        th, om, dom = runup_motion(t, rig.speed, theta0, p["start"], p["until"])
    else:
        th, om, dom = motion(t, rig.speed, theta0)
    return th, om, drive_torque(rig, th, om, dom)


def coloured(effect, p, n, rng):
    """Unit-RMS coloured noise."""
    if effect == "pink_noise":
        spec = np.fft.rfft(rng.standard_normal(n))
        f = np.arange(spec.size, dtype=float)
        f[0] = 1.0
        x = np.fft.irfft(spec / np.sqrt(f), n)
    else:
        w0 = 2 * np.pi * p["f"]
        r = np.exp(-w0 / (2 * p["q"]))
        x = lfilter([1.0], [1.0, -2 * r * np.cos(w0), r * r], rng.standard_normal(n))
        x = x / np.std(x) + rng.standard_normal(n)
    x = x - x.mean()
    return x / np.sqrt(np.mean(x ** 2))


def measured(effect, p, clean, sigma, t, rng):
    """The logged torque: the sensor's artefact applied to the clean torque with the noise."""
    n = clean.size
    if effect in ("pink_noise", "band_noise"):
        return clean + sigma * coloured(effect, p, n, rng)
    y = clean * (1 + p.get("gain", 0.0)) + sigma * rng.standard_normal(n)
    if effect == "quantised":
        lsb = p["lsb"] * sigma
        y = lsb * np.round(y / lsb)
    elif effect == "offset_step":
        f = p["at"]
        height = 3.0 * sigma / np.sqrt(f * (1 - f))     # the step's RMS about its mean: 3 sigma
        y = y + p["sign"] * height * (t >= t[0] + f * (t[-1] - t[0]))
    elif effect == "clipped":
        y = np.minimum(y, np.quantile(y, 1 - p["fraction"]))
    return y
