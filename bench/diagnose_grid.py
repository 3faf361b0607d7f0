"""Robustness benchmark of the discrepancy workflow (`make bench-diagnose`): measurements made on
the fly with fixed seeds -- every library effect x rig family x SNR x noise seed, plus no-effect
records and out-of-library disturbances, with and without a speed column -- diagnosed with the
nominal config that lacks the effect. Prints the confusion matrix (true effect x verdict) and the
rates; writes them (and every case) to JSON.

SNR = effect RMS (against the nominal simulation at the same angle) / noise sigma. No-effect and
disturbed records: sigma = 2 % of the nominal torque's standard deviation (0.5 % of the mean
torque on the concentric rig, whose nominal torque is constant), a disturbance RMS = SNR x sigma.
Without a speed column the pump runs 0.3 % above its nominal speed (motor slip); with one, the
column holds the true instantaneous speed (a speed ripple shows in it).

Every case draws its own noise (seed from the case's key): with one realisation shared by all
cases, one unusual draw (a 1 % tail event for the detector family) would repeat as a "rate".
An effect whose torque change is below the simulator's precision on a rig (a sensor lag on a
concentric rig's constant torque) is `unobservable` there and left out of the rates; one that the
baseline fit (mu, theta0, speed) absorbs on noise-free data to below a quarter of the noise sigma
is `absorbed` (not identifiable from one measurement: a vane spread on a concentric rig is a
change of mean mu): there the right answer is nothing named and no unexplained remainder
(`confounded` naming it allowed), and it is counted with the no-effect records.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
import zlib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import pumpsim  # noqa: E402
from pumpsim.bundled import example_table, with_changes  # noqa: E402
from pumpsim.config import config_from_dict  # noqa: E402
from pumpsim.data import Dataset  # noqa: E402
from pumpsim.diagnosis import diagnose  # noqa: E402
from pumpsim.geometry import check_geometry  # noqa: E402
from pumpsim.identification import identify  # noqa: E402
from pumpsim.sensor import measured_torque  # noqa: E402

RIGS = {  # family -> (example, dotted-key changes)
    "concentric4": ("test_rig", {}),
    "eccentric5": ("test_rig", {"rotor.vanes": 5, "housing.center": [1.0e-3, 0.0]}),
    "ellipse1": ("ellipse_4vanes", {"rotor.vanes": 1}),
    "ellipse3": ("ellipse_4vanes", {"rotor.vanes": 3}),
    "ellipse4": ("ellipse_4vanes", {}),
    "tilted3": ("ellipse_4vanes", {"rotor.vanes": 3, "rotor.slot_tilt": 0.15}),
}
EFFECTS = ("rotor_eccentricity", "housing_out_of_round", "speed_ripple", "torque_offset", "sensor_lag",
           "vane_friction_spread", "viscous_tip_friction")
DISTURBANCES = ("non_shaft_lines", "slow_drift", "non_shaft_impulses")
# what a rig shows beyond the reduced grid (--grid rig): two library effects at once (an eccentric
# rotor on a motor whose speed ripples), a gear mesh line at a non-integer order (out of the library),
# every COF rising 7 % over the record (a pump warming up: a drift to be named, nothing else)
RIG_TRUTHS = ("two_effects", "gear_line", "drifting_cof")
TWO_EFFECTS = ("rotor_eccentricity", "speed_ripple")
DRIFT_RISE, DRIFT_LEVELS, DRIFT_DURATION = 0.07, 15, 0.4
# effects that one speed cannot tell from a fitted parameter on some rigs: `confounded` naming the
# true effect is a right answer there
CONFOUNDABLE = ("torque_offset", "viscous_tip_friction")


def rig(family):
    base, changes = RIGS[family]
    cfg = config_from_dict(with_changes(example_table(base), changes))
    check_geometry(cfg)
    return cfg


def _with(cfg, **values):
    return dataclasses.replace(cfg, values={**cfg.values, **values})


def truth_of(nominal, effect, dt):
    """The true pump (config), sensor lag and offset for `effect` (sizes a pump engineer meets)."""
    lag, offset = 0.0, 0.0
    v = nominal.values
    if effect == "rotor_eccentricity":
        truth = _with(nominal, **{"housing.center.0": v["housing.center.0"] + 1.5e-4 * math.cos(0.7),
                                  "housing.center.1": v["housing.center.1"] + 1.5e-4 * math.sin(0.7)})
    elif effect == "housing_out_of_round":
        truth = nominal.with_harmonics(nominal.harmonics + [[2, 1.5e-5, 0.3]])
    elif effect == "speed_ripple":
        truth = dataclasses.replace(nominal, speed_ripple=(1, 0.005, 0.5))
    elif effect == "torque_offset":
        truth, offset = nominal, 0.003
    elif effect == "sensor_lag":
        truth, lag = nominal, 2 * dt
    elif effect == "vane_friction_spread":
        truth = _with(nominal, **{"effects.vane_friction_factor.1": 1.3})
    elif effect == "viscous_tip_friction":
        truth = _with(nominal, **{"effects.viscous_tip_friction": 0.004})
    elif effect == "two_effects":
        truth, _, _ = truth_of(nominal, "rotor_eccentricity", dt)
        truth = dataclasses.replace(truth, speed_ripple=(1, 0.005, 0.5))
    else:
        truth = nominal
    return truth, lag, offset


def disturbance(kind, t, speed, rms):
    shaft_hz = speed / (2 * math.pi)
    if kind == "non_shaft_lines":  # mains hum and a line at 1.5 shaft orders
        d = np.sin(2 * math.pi * 50.0 * t + 0.2) + 0.7 * np.sin(2 * math.pi * 1.5 * shaft_hz * t + 1.0)
    elif kind == "slow_drift":  # a thermal drift of the sensor zero over the record
        d = (t - t.mean()) / (t.max() - t.min())
    elif kind == "non_shaft_impulses":  # a 3-sample impulse every 1/(1.37 shaft) s
        period = 1 / (1.37 * shaft_hz)
        d = (np.mod(t, period) < 3 * (t[1] - t[0])).astype(float)
        d = d - d.mean()
    elif kind == "gear_line":  # a gear mesh at 7.3 x the shaft frequency
        d = np.sin(2 * math.pi * 7.3 * shaft_hz * t + 0.3)
    else:
        return np.zeros_like(t)
    return rms * d / math.sqrt(np.mean(d**2))


def _warming(cfg, duration, rate):
    """Every COF rising by DRIFT_RISE over the record in DRIFT_LEVELS steps (a pump warming up)."""
    keys = [k for k in cfg.values if k.startswith("friction.") and k.rsplit(".", 1)[1] in ("static", "dynamic")]
    parts = [pumpsim.simulate(_with(cfg, **{k: cfg.values[k] * (1 + DRIFT_RISE * (j + 0.5) / DRIFT_LEVELS)
                                            for k in keys}), duration=duration, rate=rate)
             for j in range(DRIFT_LEVELS)]
    n = parts[0].time.size
    level = np.minimum((np.arange(n) * DRIFT_LEVELS) // n, DRIFT_LEVELS - 1)
    return parts[0], np.array([parts[i].torque[k] for k, i in enumerate(level)])


def make_case(family, truth_name, snr, seed, speed_column, duration=0.1, rate=10000.0):
    nominal = dataclasses.replace(rig(family), angle=0.0)
    dt = 1 / rate
    if truth_name in EFFECTS and truth_name == "vane_friction_spread" and nominal.vanes < 2:
        return None
    truth, lag, offset = truth_of(nominal, truth_name, dt)
    slip = 1.0 if speed_column else 1.003
    angle = 0.4 + 0.37 * seed
    truth = dataclasses.replace(truth, speed=nominal.speed * slip, angle=angle)
    ref = pumpsim.simulate(dataclasses.replace(nominal, speed=nominal.speed * slip, angle=angle),
                           duration=duration, rate=rate)
    # a sensor low-pass acts on the continuous torque: simulate LAG_FINE x finer and keep every
    # LAG_FINE-th filtered sample (filtering the samples would advance the response by ~dt/2)
    fine = LAG_FINE if lag > 0 else 1
    if truth_name == "drifting_cof":
        duration = DRIFT_DURATION
        ref = pumpsim.simulate(dataclasses.replace(nominal, speed=nominal.speed * slip, angle=angle),
                               duration=duration, rate=rate)
        sim, y = _warming(truth, duration, rate)
    else:
        sim = pumpsim.simulate(truth, duration=duration, rate=rate * fine)
        y = measured_torque(sim.time, sim.torque, lag, offset, every=fine)
    sim = ref if fine > 1 else sim  # the reported sample times
    effect_rms = math.sqrt(np.mean((y - ref.torque) ** 2))
    if truth_name == "two_effects":  # the SNR is the weaker effect's: both must be there to be seen
        effect_rms = min(math.sqrt(np.mean((pumpsim.simulate(
            dataclasses.replace(truth_of(nominal, e, dt)[0], speed=nominal.speed * slip, angle=angle),
            duration=duration, rate=rate).torque - ref.torque) ** 2)) for e in TWO_EFFECTS)
    if truth_name in EFFECTS + ("two_effects", "drifting_cof"):
        sigma = effect_rms / snr
    else:
        sd = float(np.std(ref.torque))
        sigma = 0.02 * sd if sd > 1e-3 * abs(np.mean(ref.torque)) else 0.005 * abs(float(np.mean(ref.torque)))
        y = y + disturbance(truth_name, sim.time, truth.speed, snr * sigma)
    key = zlib.crc32(f"{family}|{truth_name}|{snr:g}|{int(speed_column)}".encode())
    rng = np.random.default_rng([seed, key])
    speed = sim.speed.copy() if speed_column else None  # an encoder's instantaneous speed (a ripple shows)
    status = "in_library" if truth_name in EFFECTS else "none_or_disturbance"
    if truth_name in EFFECTS:
        if effect_rms < PRECISION * math.sqrt(np.mean(ref.torque ** 2)):
            status = "unobservable"
        elif _absorbed(nominal, Dataset(sim.time, y, speed=speed), sigma, speed_column):
            status = "absorbed"
    y = y + rng.normal(0, sigma, y.size)
    factors = [1.0] + [truth.values.get(f"effects.vane_friction_factor.{i}", 1.0) for i in range(1, nominal.vanes)]
    mu = truth.values["friction.housing.dynamic"] * float(np.mean(factors))  # the reported mu: mean over vanes
    return nominal, Dataset(sim.time, y, speed=speed), {"sigma": sigma, "effect_rms": effect_rms, "mu": mu,
                                                         "status": status}


LAG_FINE = 16  # simulation points per reported sample interval for a lagged sensor
PRECISION = 1e-9  # relative: below this an effect's torque change is the simulator's rounding


def _absorbed(nominal, clean, sigma, speed_column):
    """Does the baseline fit (mu, theta0, and the speed in its band without a speed column) on the
    noise-free measurement leave less than a quarter of the noise sigma? Then one measurement
    cannot tell the effect from a change of the baseline parameters."""
    names = ["mu", "theta0"] + ([] if speed_column else ["speed"])
    res = identify(nominal, clean, names, multistart=True, speed_in_band=True, adequacy=False)
    return bool(res.rms < 0.25 * sigma)


def classify(truth_name, out, status="in_library"):
    """right | confounded_right | wrong_name | extra_name | missed | false_unexplained | right_unexplained |
    clean (no effect, nothing claimed)."""
    named = out["effects"]
    conf = {e for pair in out["confounded"] + out["hidden_in_baseline"] for e in pair}
    if truth_name == "two_effects":
        if set(named) == set(TWO_EFFECTS):
            return "right"
        if set(named) < set(TWO_EFFECTS):
            return "partial" if named else "missed"
        return "wrong_name"
    if truth_name == "drifting_cof":
        if named:
            return "wrong_name"
        return "right" if [d["parameter"] for d in out["drift"]] == ["mu"] else "missed"
    if truth_name in EFFECTS and status == "absorbed":
        if named:
            return "wrong_name"
        return "false_unexplained" if out["unexplained"] else "clean"
    if truth_name in EFFECTS:
        if named and named[0] == truth_name:
            return "right" if len(named) == 1 else "extra_name"
        if not named and truth_name in CONFOUNDABLE and truth_name in conf:
            return "confounded_right"
        return "wrong_name" if named else "missed"
    if named:
        return "wrong_name"
    if truth_name == "none":
        return "false_unexplained" if out["unexplained"] else "clean"
    return "right_unexplained" if out["unexplained"] else "missed"


def run_case(family, truth_name, snr, seed, speed_column, **kw):
    made = make_case(family, truth_name, snr, seed, speed_column, **kw)
    if made is None:
        return None
    nominal, ds, info = made
    if info["status"] == "unobservable":
        return {"rig": family, "truth": truth_name, "snr": snr, "seed": seed, "speed_column": speed_column,
                "status": "unobservable", "effect_rms": info["effect_rms"]}
    t0, c0 = time.perf_counter(), time.process_time()
    out = diagnose(nominal, ds)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    mu = out["final"]["params"].get("mu", {}).get("value")
    return {"rig": family, "truth": truth_name, "snr": snr, "seed": seed, "speed_column": speed_column,
            "effects": out["effects"], "confounded": out["confounded"], "unexplained": out["unexplained"],
            "verdict": out["verdict"], "outcome": classify(truth_name, out, info["status"]), "status": info["status"],
            "mu_rel_error": None if mu is None else abs(mu / info["mu"] - 1), "wall_time": wall,
            "cpu_time": cpu, "samples": ds.n, "final_rms": out["final"]["rms"],
            "final_params": {k: v.get("value") for k, v in out["final"]["params"].items()}}


def grid(rigs, truths, snrs, seeds, speed_columns):
    for family in rigs:
        for truth in truths:
            for snr in (snrs if truth != "none" else snrs[:1]):
                for seed in seeds:
                    for sc in speed_columns:
                        yield family, truth, snr, seed, sc


def summarise(cases):
    """Rates. Named right: in-library, observable, not absorbed effects, the true effect named first
    and alone (or, with nothing named, reported `confounded`). False names: any name on no-effect,
    absorbed and out-of-library records. False `unexplained`: on no-effect and absorbed records and
    where the true effect was named right (a confounded pair, nothing named, is unexplained by
    design: confounded is reported in addition, never instead)."""
    cases = [c for c in cases if c is not None]
    skipped = [c for c in cases if c.get("status") == "unobservable"]
    cases = [c for c in cases if c.get("status") != "unobservable"]
    eff = [c for c in cases if c["truth"] in EFFECTS and c["status"] != "absorbed"]
    hi = [c for c in eff if c["snr"] >= 5]
    right = lambda cs: sum(c["outcome"] in ("right", "confounded_right") for c in cs)  # noqa: E731
    quiet = [c for c in cases if c["truth"] == "none" or c["status"] == "absorbed"]
    not_eff = quiet + [c for c in cases if c["truth"] in DISTURBANCES]
    judged = quiet + [c for c in eff if c["outcome"] == "right"]
    false_unexpl = [c for c in judged if c["unexplained"]]
    outcomes = sorted({c["outcome"] for c in cases})
    matrix = {}
    for c in cases:
        conf = {e for pair in c["confounded"] for e in pair}
        verdict = (c["effects"][0] if c["effects"] else ("confounded" if c["truth"] in conf else
                   ("unexplained" if c["unexplained"] else "nothing")))
        row = c["truth"] + (" (absorbed)" if c["status"] == "absorbed" else "")
        matrix.setdefault(row, {}).setdefault(verdict, 0)
        matrix[row][verdict] += 1
    mu_err = [c["mu_rel_error"] for c in cases if c["mu_rel_error"] is not None and c["outcome"] in
              ("right", "clean", "right_unexplained")]
    walls = [c["wall_time"] for c in cases]
    single = [c for c in cases if c["truth"] != "two_effects"]
    rig = {t: [c for c in cases if c["truth"] == t] for t in RIG_TRUTHS}
    return {
        "false_stack_rate": sum(len(c["effects"]) >= 2 for c in single) / max(len(single), 1),
        "false_stack_cases": len(single),
        "rig_truths": {t: {o: sum(c["outcome"] == o for c in cs) for o in sorted({c["outcome"] for c in cs})}
                       for t, cs in rig.items() if cs},
        "cases": len(cases), "unobservable": len(skipped), "absorbed": sum(c["status"] == "absorbed" for c in cases),
        "named_right_rate": right(eff) / max(len(eff), 1), "named_right_cases": len(eff),
        "named_right_rate_snr_ge_5": right(hi) / max(len(hi), 1), "named_right_cases_snr_ge_5": len(hi),
        "false_name_rate": sum(bool(c["effects"]) for c in not_eff) / max(len(not_eff), 1),
        "false_name_cases": len(not_eff),
        "false_unexplained_rate": len(false_unexpl) / max(len(judged), 1), "false_unexplained_cases": len(judged),
        "out_of_library_unexplained_rate": sum(c["unexplained"] and not c["effects"] for c in not_eff
                                               if c["truth"] in DISTURBANCES) / max(sum(c["truth"] in DISTURBANCES for c in not_eff), 1),
        "mu_rel_error_median": float(np.median(mu_err)) if mu_err else None,
        "mu_rel_error_p95": float(np.percentile(mu_err, 95)) if mu_err else None,
        "wall_time_median": float(np.median(walls)), "wall_time_max": float(np.max(walls)),
        "confusion": matrix, "outcomes": {o: sum(c["outcome"] == o for c in cases) for o in outcomes},
    }


def print_summary(s):
    cols = sorted({v for row in s["confusion"].values() for v in row})
    print(f"{'true / verdict':<34}" + "".join(f"{c[:14]:>15}" for c in cols))
    for truth, row in s["confusion"].items():
        print(f"{truth:<34}" + "".join(f"{row.get(c, 0):>15}" for c in cols))
    print(f"cases {s['cases']} (+{s['unobservable']} unobservable, left out; {s['absorbed']} absorbed by the baseline)")
    print(f"named right {s['named_right_rate']:.1%} of {s['named_right_cases']} (SNR >= 5: "
          f"{s['named_right_rate_snr_ge_5']:.1%} of {s['named_right_cases_snr_ge_5']}), false names "
          f"{s['false_name_rate']:.1%} of {s['false_name_cases']}, false unexplained "
          f"{s['false_unexplained_rate']:.1%} of {s['false_unexplained_cases']}, out-of-library unexplained "
          f"{s['out_of_library_unexplained_rate']:.1%}")
    if s["mu_rel_error_median"] is not None:
        print(f"mu relative error: median {s['mu_rel_error_median']:.2e}, 95th percentile {s['mu_rel_error_p95']:.2e}")
    print(f"wall time per case: median {s['wall_time_median']:.1f} s, max {s['wall_time_max']:.1f} s")
    print(f"false stacks (two or more names where at most one effect is true): {s['false_stack_rate']:.1%} "
          f"of {s['false_stack_cases']}")
    for t, outcomes in s["rig_truths"].items():
        print(f"  {t}: " + ", ".join(f"{o} {k}" for o, k in outcomes.items()))


REDUCED = dict(rigs=("concentric4", "eccentric5", "ellipse4", "tilted3"), truths=EFFECTS + ("none",) + DISTURBANCES,
               snrs=(5, 10), seeds=(0,), speed_columns=(False, True))
RIG = dict(rigs=("concentric4", "eccentric5", "ellipse4", "tilted3"), truths=RIG_TRUTHS, snrs=(5, 10), seeds=(0,),
           speed_columns=(False, True))
FULL = dict(rigs=tuple(RIGS), truths=EFFECTS + ("none",) + DISTURBANCES, snrs=(3, 5, 10), seeds=(0, 1, 2),
            speed_columns=(False, True))


def run(spec, log=print):
    cases = []
    for family, truth, snr, seed, sc in grid(**spec):
        c = run_case(family, truth, snr, seed, sc)
        if c is None:
            continue
        cases.append(c)
        if c["status"] == "unobservable":
            log(f"{family:<12}{truth:<22}unobservable on this rig (effect RMS {c['effect_rms']:.2g} N m)")
            continue
        log(f"{family:<12}{truth:<22}snr {snr:<3}seed {seed} {'speed ' if sc else 'torque'}: "
            f"{c['outcome']:<18}{','.join(c['effects']) or '-':<28}{c['wall_time']:6.1f} s")
    return cases


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grid", choices=["reduced", "rig", "full"], default="reduced")
    ap.add_argument("--json", default="out/bench_diagnose.json")
    ap.add_argument("--rigs", help="comma-separated subset of " + ",".join(RIGS))
    ap.add_argument("--truths", help="comma-separated subset of the effects/none/disturbances")
    ap.add_argument("--seeds", type=int, help="number of noise seeds")
    ap.add_argument("--snrs", help="comma-separated SNRs")
    a = ap.parse_args(argv)
    spec = dict({"reduced": REDUCED, "rig": RIG, "full": FULL}[a.grid])
    if a.rigs:
        spec["rigs"] = tuple(a.rigs.split(","))
    if a.truths:
        spec["truths"] = tuple(a.truths.split(","))
    if a.seeds:
        spec["seeds"] = tuple(range(a.seeds))
    if a.snrs:
        spec["snrs"] = tuple(float(x) for x in a.snrs.split(","))
    t0 = time.perf_counter()
    cases = run(spec)
    s = summarise(cases)
    print_summary(s)
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    Path(a.json).write_text(json.dumps({"grid": {k: list(v) for k, v in spec.items()}, "summary": s,
                                        "cases": cases, "total_wall_time": time.perf_counter() - t0}, indent=1))


if __name__ == "__main__":
    main()
