"""Measurement records from the independent rig model: effects as physics, disturbances, noise.

Each effect is implemented in this generator's own form (not pumpsim's parametrisation):
* rotor_eccentricity - the housing centre moved by e (0.05-0.15 mm) in any direction beta
  (equivalently the rotor centre moved by -e); every vane's s(theta) is re-solved on the moved curve.
* housing_out_of_round - an extra harmonic [k, A, gamma] of the housing's polar radius, k = 2..6.
* speed_ripple - omega = w0 (1 + eps cos(k w0 t + phase)), k = 1..3, eps 0.2-3 %; the inverse
  dynamics carries omega' (rotor and vane inertia) as well as the changed kinematics.
* torque_offset - a constant added to the sensor signal (zero drift of the torque cell).
* sensor_lag - the sensor as a first-order low-pass (time constant T, exact first-order-hold
  discretisation on a 64x finer grid after a pre-roll of 12 T: the Coulomb reversals fall between
  samples, and the filter sees the continuous torque; 8x left 0.07 noise sigma at SNR 5, 64x 0.009) or a pure delay d (the torque of
  t - d written at t).
* vane_friction_spread - one vane of another material: its tip AND slot COFs (static and dynamic)
  scaled by one factor (0.6-0.75 or 1.3-1.5).
* viscous_tip_friction - a lubricated tip: the tip COF rises with slip speed, mu_h(v) + c v
  (c in s/m); a load-dependent form, unlike a load-independent shear force.
Out of the library (nothing a pump effect would make): mains hum (a sinusoid at 50 Hz or at an
arbitrary non-shaft frequency), a slow drift (a ramp plus a sinusoid slower than the record), a
train of short pulses at a non-shaft frequency, and coloured AR(1) sensor noise on a clean record.
Two library effects at once ('two_effects', a pair drawn from PAIRS; each at the record's SNR).
No effect: the nominal rig ('none'), the nominal rig run 0.3-1.5 % off its configured speed
('off_speed'; the file's speed column, if any, shows the true speed), or a motor whose speed drifts
slowly by 0.3-1 % over the record ('speed_drift', a battery sagging; always written with the measured
speed column, which shows the drift).
Noise: Gaussian, white unless 'ar1'; its RMS is the effect's contribution RMS / SNR (for no effect:
the torque ripple RMS / SNR, with 1 % of the mean torque as the floor for a flat torque).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import lfilter

from . import artefacts
from .rig import RIGS, drive_torque, motion

LIBRARY = ("rotor_eccentricity", "housing_out_of_round", "speed_ripple", "torque_offset",
           "sensor_lag", "vane_friction_spread", "viscous_tip_friction")
# a heavier vane (one vane 10-20 % heavier: a different part, a broken-in carbon vane that soaked oil)
# is a pump effect outside pumpsim's library; appended last to EFFECTS so the older cases keep their seeds
OUT_OF_LIBRARY = ("hum", "drift", "impulse", "ar1_noise", "heavy_vane")
# no effect, but the rig runs 0.3-1.5 % off the configured (nominal) speed, as a real motor does
NO_EFFECT = ("none", "off_speed", "speed_drift")
# pairs a pump can show together (a shaft pressed off-centre with a drifting zero, a lobed bore with a
# motor ripple, ...); 'two_effects' draws one
PAIRS = (("rotor_eccentricity", "torque_offset"), ("housing_out_of_round", "speed_ripple"),
         ("vane_friction_spread", "rotor_eccentricity"), ("speed_ripple", "torque_offset"),
         ("viscous_tip_friction", "housing_out_of_round"), ("sensor_lag", "rotor_eccentricity"))
COMBINED = ("two_effects",)
EFFECTS = (("none",) + LIBRARY + OUT_OF_LIBRARY[:4] + ("off_speed",) + COMBINED + ("speed_drift",)
           + OUT_OF_LIBRARY[4:])


@dataclass
class Record:
    rig: str
    effect: str
    snr: float
    seed: int
    rate: float
    duration: float
    t: np.ndarray
    torque: np.ndarray          # measured (with effect, disturbance and noise), N m
    theta: np.ndarray
    omega: np.ndarray
    truth: dict                 # effect parameters, contribution RMS, observable share
    noise_rms: float


def _sample_effect(effect, rig, rng):
    """Draw the hidden effect's parameters for this rig."""
    if effect == "rotor_eccentricity":
        return dict(e=rng.uniform(0.05e-3, 0.15e-3), beta=rng.uniform(0, 2 * np.pi))
    if effect == "housing_out_of_round":
        return dict(k=int(rng.integers(2, 7)), A=rng.uniform(6e-6, 15e-6), gamma=rng.uniform(0, np.pi))
    if effect == "speed_ripple":
        return dict(k=int(rng.integers(1, 4)), eps=rng.uniform(0.002, 0.03), phase=rng.uniform(0, 2 * np.pi))
    if effect == "torque_offset":
        return dict(offset=float(rng.choice([-1, 1]) * rng.uniform(0.02, 0.06)))   # x mean torque
    if effect == "sensor_lag":
        return dict(kind=str(rng.choice(["lowpass", "delay"])), frac=rng.uniform(0.15, 0.6))  # x 1/(N w)
    if effect == "vane_friction_spread":
        f = rng.uniform(1.3, 1.5) if rng.random() < 0.5 else rng.uniform(0.6, 0.75)
        return dict(vane=int(rng.integers(0, rig.vanes)), factor=f)
    if effect == "viscous_tip_friction":
        return dict(c=rng.uniform(1.0e-3, 3.0e-3))
    if effect == "hum":
        shaft = rig.speed / (2 * np.pi)
        f = 50.0 if rng.random() < 0.5 else shaft * rng.choice([0.37, 1.41, 2.63, 0.71])
        return dict(f=float(f), phase=rng.uniform(0, 2 * np.pi))
    if effect == "drift":
        return dict(slope_sign=float(rng.choice([-1, 1])), phase=rng.uniform(0, 2 * np.pi))
    if effect == "impulse":
        return dict(f=rig.speed / (2 * np.pi) * rng.choice([0.43, 0.61, 1.27]), width=rng.uniform(1e-4, 3e-4),
                    phase=rng.uniform(0, 1))
    if effect == "off_speed":
        return dict(factor=1 + float(rng.choice([-1, 1])) * rng.uniform(0.003, 0.015))
    if effect == "ar1_noise":
        return dict(phi=rng.uniform(0.8, 0.95))
    if effect == "speed_drift":
        return dict(d=float(rng.choice([-1, 1])) * rng.uniform(0.003, 0.01))   # relative change over the record
    if effect == "heavy_vane":
        return dict(vane=int(rng.integers(0, rig.vanes)), factor=rng.uniform(1.1, 1.2))
    if effect == "two_effects":
        pair = PAIRS[int(rng.integers(len(PAIRS)))]
        return dict(effects=list(pair), **{e: _sample_effect(e, rig, rng) for e in pair})
    return {}


def components(effect, p):
    """The pump and sensor effects (name, params) a record carries."""
    if effect in COMBINED:
        return [(e, p[e]) for e in p["effects"]]
    return [(effect, p)] if effect in LIBRARY or effect in ("speed_drift", "heavy_vane") else []


def _shaft(rig, comps, theta0, span):
    """The shaft torque (and the motion) as a function of time with the pump effects of comps;
    sensor effects act later, on its output."""
    ripple = drift = factors = None
    viscous = 0.0
    for e, p in comps:
        if e == "rotor_eccentricity":   # the housing centre moved by e (= the rotor by -e)
            rig = replace(rig, center=(rig.center[0] + p["e"] * np.cos(p["beta"]),
                                       rig.center[1] + p["e"] * np.sin(p["beta"])))
        elif e == "housing_out_of_round":
            rig = replace(rig, harmonics=tuple(rig.harmonics) + ((p["k"], p["A"], p["gamma"]),))
        elif e == "speed_ripple":
            ripple = (p["k"], p["eps"], p["phase"])
        elif e == "speed_drift":
            drift = (p["d"], 0.5 * span, span)
        elif e == "vane_friction_spread":
            factors = [(1.0, 1.0)] * rig.vanes
            factors[p["vane"]] = (p["factor"], p["factor"])
        elif e == "viscous_tip_friction":
            viscous = p["c"]
        elif e == "heavy_vane":
            factors = list(factors or [(1.0, 1.0)] * rig.vanes)
            factors[p["vane"]] = tuple(factors[p["vane"]][:2]) + (p["factor"],)

    def torque(t):
        th, om, dom = motion(t, rig.speed, theta0, ripple, drift)
        return drive_torque(rig, th, om, dom, factors=factors, tip_viscous=viscous), th, om
    return torque


def _measured(rig, comps, t, theta0, nominal_mean):
    """The sensor's signal without noise (shaft torque, then lag, then zero offset) and the motion."""
    shaft = _shaft(rig, comps, theta0, t[-1] - t[0])
    tau, th, om = shaft(t)
    for e, p in comps:
        if e == "sensor_lag":
            tau = _lagged(shaft, p["kind"], p["frac"] / (rig.vanes * rig.speed), t)
    for e, p in comps:
        if e == "torque_offset":
            tau = tau + p["offset"] * nominal_mean
    return tau, th, om


# an effect is scored 'absorbed' (nothing to name; naming it is no error) when the part of its
# contribution no change of mu or theta0 can mimic is below ABSORBED_Z noise sigmas over the whole
# record, or below ABSORBED_SIZE sigma RMS per sample: a change smaller than a quarter of the noise is
# what diagnose declares it will not name (pumpsim/diagnosis/options.py named_size), and at one speed it is, for a pump
# engineer, a COF change (e.g. lubricated tips on a near-constant slip speed)
ABSORBED_Z = 5.0
ABSORBED_SIZE = 0.25
LAG_OVERSAMPLING = 64   # sub-steps per sample of the continuous low-pass (error ~ 1 / LAG_OVERSAMPLING)


def _lagged(shaft, kind, T, t):
    """A pure delay T, or a first-order low-pass (time constant T) of the continuous shaft torque."""
    if kind == "delay":
        return shaft(t - T)[0]
    over = LAG_OVERSAMPLING
    dt = (t[1] - t[0]) / over
    pre = int(np.ceil(12 * T / dt))
    u = shaft(t[0] + dt * np.arange(-pre, over * (len(t) - 1) + 1))[0]
    a = np.exp(-dt / T)
    c = T / dt * (1 - a)
    # first-order hold, exact for u linear between sub-steps: y[n] = a y[n-1] + (1 - c) u[n] + (c - a) u[n-1],
    # started in steady state (y[0] = u[0])
    y = lfilter([1 - c, c - a], [1, -a], u, zi=[c * u[0]])[0]
    return y[pre::over][: len(t)]


def _disturbance(effect, p, t, rng):
    """Unit-RMS waveform of an out-of-library disturbance."""
    if effect == "hum":
        return np.sqrt(2) * np.sin(2 * np.pi * p["f"] * t + p["phase"])
    if effect == "drift":
        x = (t - t[0]) / (t[-1] - t[0])
        d = p["slope_sign"] * (x - 0.5) + 0.5 * np.sin(2 * np.pi * 0.4 * x + p["phase"])
        d = d - d.mean()
        return d / np.sqrt(np.mean(d ** 2))
    if effect == "impulse":
        period = 1 / p["f"]
        ph = np.mod(t / period + p["phase"], 1.0) - 0.5
        d = np.exp(-0.5 * (ph * period / p["width"]) ** 2)
        return d / np.sqrt(np.mean(d ** 2))
    return np.zeros_like(t)


def _noise(rng, n, sigma, phi=None):
    e = rng.standard_normal(n)
    if phi is None:
        return sigma * e
    x = np.empty(n)
    x[0] = e[0]
    for i in range(1, n):
        x[i] = phi * x[i - 1] + np.sqrt(1 - phi * phi) * e[i]
    return sigma * x


SHARE_WINDOW = 2000   # samples the observable share is computed on (>= 6 revolutions at 25 kHz; it is per sample)
PHASE_COARSE = np.linspace(-0.06, 0.06, 25)   # rad; then +-1 coarse step around the best by a tenth of it


def _unmimicked(rig, t, theta, target, mu_column=None):
    """Residual of target - model(theta) after mu (column mu_column, default at theta) and a small
    phase change are fitted linearly."""
    base = _nominal(rig, t, theta)
    d = 1e-4
    if mu_column is None:
        mu_rig = replace(rig, tip=rig.tip.scaled(1 + d), slot=rig.slot_friction.scaled(1 + d))
        mu_column = (_nominal(mu_rig, t, theta) - base) / d
    X = np.column_stack([mu_column, (_nominal(rig, t, theta + d) - base) / d])
    rest = target - base
    return rest - X @ np.linalg.lstsq(X, rest, rcond=None)[0], mu_column


def _nominal(rig, t, theta0):
    return drive_torque(rig, *motion(t, rig.speed, theta0))


def observable_share(rig, t, theta0, contribution):
    """RMS share of an effect's contribution that no change of mu and of the phase theta0 explains:
    the phase moved by finite steps too (a moved centre of an eccentric circle turns the housing about
    the rotor axis, exactly a phase shift, but one beyond the linear range of a torque with friction
    reversals), each with mu and the remaining phase fitted linearly; on the first SHARE_WINDOW
    samples. ~0 means the effect is unobservable."""
    t, contribution = t[:SHARE_WINDOW], contribution[:SHARE_WINDOW]
    rms = np.sqrt(np.mean(contribution ** 2))
    if rms == 0:
        return 0.0
    target = _nominal(rig, t, theta0) + contribution
    mu_column = _unmimicked(rig, t, theta0, target)[1]
    cost = lambda dl: float(np.sum(_unmimicked(rig, t, theta0 + dl, target, mu_column)[0] ** 2))  # noqa: E731
    step = PHASE_COARSE[1] - PHASE_COARSE[0]
    best = min(PHASE_COARSE, key=cost)
    best = min(best + step * np.linspace(-1, 1, 21), key=cost)
    rest = _unmimicked(rig, t, theta0 + best, target)[0]   # mu's column at the best phase
    return float(min(np.sqrt(np.mean(rest ** 2)), np.sqrt(np.mean(_unmimicked(rig, t, theta0, target)[0] ** 2))) / rms)


def _library_truth(rig, comps, t, theta0, nominal, clean, snr, truth):
    """Each library effect's own contribution (RMS, share no mu/theta0 change can mimic, absorbed
    against the noise over the record); returns the noise sigma: the smallest contribution / SNR."""
    rms, absorbed, observable = {}, [], {}
    for e, p in comps:
        alone = clean if len(comps) == 1 else _measured(rig, [(e, p)], t, theta0, nominal.mean())[0]
        contribution = alone - nominal
        rms[e] = float(np.sqrt(np.mean(contribution ** 2)))
        share = observable_share(rig, t, theta0, contribution) if rms[e] > 0 else 0.0
        if e == "sensor_lag" and p["kind"] == "delay":
            share = 0.0   # at constant speed a pure delay IS a theta0 shift (exactly, not to first order)
        observable[e] = share
    sigma = min(rms.values()) / snr
    for e in rms:   # the mimic-free part: undetectable over the record, or too small to claim per sample
        free = observable[e] * rms[e] / sigma
        if free * len(t) ** 0.5 < ABSORBED_Z or free < ABSORBED_SIZE:
            absorbed.append(e)
    truth.update(effects=[e for e, _ in comps], absorbed_effects=absorbed, contribution_rms=sum(rms.values()),
                 observable=observable[comps[0][0]] if len(comps) == 1 else observable)
    return sigma


def _plain(v):
    return float(v) if isinstance(v, (float, np.floating)) else (
        {k: _plain(x) for k, x in v.items()} if isinstance(v, dict) else v)


def _absorbed(rig, t, theta0, contribution, sigma):
    """The records' absorbed rule for one contribution against noise sigma (see ABSORBED_Z)."""
    rms = float(np.sqrt(np.mean(contribution ** 2)))
    free = observable_share(rig, t, theta0, contribution) * rms / sigma if rms > 0 else 0.0
    return free * len(t) ** 0.5 < ABSORBED_Z or free < ABSORBED_SIZE


def artefact_record(rig_name, effect, snr, seed, rate, duration):
    """A record of a sensor, logger or operating artefact (bench/independent/artefacts.py), its
    right answer in truth['expected']. Noise sigma: the torque ripple RMS / SNR, as for no effect."""
    rig = RIGS[rig_name]
    rng = np.random.default_rng(seed)
    p = artefacts.sample(effect, rig, rng)
    theta0 = rng.uniform(0, 2 * np.pi)
    t, keep = artefacts.instants(effect, p, int(round(rate * duration)), rate, rng)
    th, om, clean = artefacts.shaft_torque(effect, p, rig, t, theta0)
    ripple = clean - clean.mean()
    sigma = max(np.sqrt(np.mean(ripple ** 2)), 0.01 * abs(clean.mean())) / snr
    expected = artefacts.EXPECTED[effect]
    if expected == "absorbed_or_unexplained":
        expected = "quiet" if _absorbed(rig, t, theta0, p["gain"] * clean, sigma) else "unexplained"
    y = artefacts.measured(effect, p, clean, sigma, t, rng)
    truth = dict(params=_plain(p), theta0=float(theta0), mu=rig.tip.dynamic, effects=[], absorbed_effects=[],
                 expected=expected, contribution_rms=0.0, samples_dropped=int((~keep).sum()))
    return Record(rig_name, effect, snr, seed, rate, duration, t[keep], y[keep], th[keep], om[keep], truth,
                  float(sigma))


def make_record(rig_name, effect, snr, seed, rate=10000.0, duration=0.5):
    if effect in artefacts.ARTEFACTS:
        return artefact_record(rig_name, effect, snr, seed, rate, duration)
    rig = RIGS[rig_name]
    rng = np.random.default_rng(seed)
    p = _sample_effect(effect, rig, rng)
    if effect == "off_speed":
        rig = replace(rig, speed=rig.speed * p["factor"])
    theta0 = rng.uniform(0, 2 * np.pi)
    t = np.arange(int(round(rate * duration))) / rate
    nominal = _shaft(rig, [], theta0, t[-1] - t[0])(t)[0]
    comps = components(effect, p)
    clean, th, om = _measured(rig, comps, t, theta0, nominal.mean())
    ripple = nominal - nominal.mean()
    ref = max(np.sqrt(np.mean(ripple ** 2)), 0.01 * abs(nominal.mean()))
    truth = dict(params=_plain(p), theta0=float(theta0), mu=rig.tip.dynamic, effects=[], absorbed_effects=[])
    if effect in LIBRARY or effect in COMBINED:
        sigma = _library_truth(rig, comps, t, theta0, nominal, clean, snr, truth)
    elif effect in ("hum", "drift", "impulse"):
        sigma = ref / 3.0                           # disturbance RMS = SNR x noise RMS
        clean = clean + snr * sigma * _disturbance(effect, p, t, rng)
        truth["contribution_rms"] = snr * sigma
    elif effect == "heavy_vane":                    # a pump effect out of the library: SNR = its RMS / noise
        truth["contribution_rms"] = float(np.sqrt(np.mean((clean - nominal) ** 2)))
        sigma = truth["contribution_rms"] / snr
        # on a concentric rig a heavier vane only raises the mean torque: a mu change (quiet is right)
        truth["expected"] = "quiet" if _absorbed(rig, t, theta0, clean - nominal, sigma) else "no_name"
    else:                                           # none, off_speed, speed_drift, ar1_noise
        sigma = ref / snr
        truth["contribution_rms"] = 0.0
    noise = _noise(rng, len(t), sigma, p.get("phi"))
    return Record(rig_name, effect, snr, seed, rate, duration, t, clean + noise, th, om, truth, float(sigma))
