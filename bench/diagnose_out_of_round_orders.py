"""Out-of-round orders on the diagnose grid's rigs (review findings: an order-3 lobing called
"consistent with noise", an order 6 named as order 4 + a speed ripple): per rig, order, amplitude,
phase, noise seed and speed column, the effect's torque RMS against the nominal model, what the
baseline fit (mu, theta0, speed: the grid's `_absorbed`) leaves of it on noise-free data -- its
smooth part (5-point running median) and its one-sample spikes (friction reversals on the other
side of a sample) -- all in noise sigmas, and the diagnosis.

    python bench/diagnose_out_of_round_orders.py --rigs ellipse4,eccentric5 --k 6 --A 1e-5,2e-5 \
        --gammas 0.3,1.0 --seeds 2 --sc 0,1 [--noise 0.02 | --snr 5] [--norun] [--out FILE.json]

Conventions as bench/diagnose_grid.py (make_case): without a speed column the pump runs 0.3 %
fast, the rotor starts at 0.4 + 0.37 x seed; the noise is `noise` x the nominal torque's standard
deviation (a quarter of its mean where it is constant), or effect RMS / `snr`."""
import dataclasses, json, math, sys, time, zlib
from pathlib import Path
import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
import pumpsim
import diagnose_grid
from pumpsim.bundled import example_table, with_changes
from pumpsim.config import config_from_dict
from pumpsim.data import Dataset
from pumpsim.geometry import check_geometry
from pumpsim.diagnosis import diagnose
from pumpsim.identification import identify

RIGS = {**diagnose_grid.RIGS,  # and the vane counts the grid lacks (3, 4, 5 on one housing)
    "concentric3": ("test_rig", {"rotor.vanes": 3}),
    "concentric5": ("test_rig", {"rotor.vanes": 5}),
    "eccentric4": ("test_rig", {"housing.center": [1.0e-3, 0.0]}),
    "eccentric3": ("test_rig", {"rotor.vanes": 3, "housing.center": [1.0e-3, 0.0]}),
    "ellipse5": ("ellipse_4vanes", {"rotor.vanes": 5}),
}


def rig(family):
    base, changes = RIGS[family]
    cfg = config_from_dict(with_changes(example_table(base), changes))
    check_geometry(cfg)
    return cfg


def case(family, k, A, gamma, seed, speed_column, noise=None, snr=None, rate=10000.0, duration=0.1, run=True,
         absorbed=True):
    nominal = dataclasses.replace(rig(family), angle=0.0)
    slip = 1.0 if speed_column else 1.003
    angle = 0.4 + 0.37 * seed
    truth = dataclasses.replace(nominal.with_harmonics(nominal.harmonics + [[k, A, gamma]]),
                                speed=nominal.speed * slip, angle=angle)
    ref = pumpsim.simulate(dataclasses.replace(nominal, speed=nominal.speed * slip, angle=angle),
                           duration=duration, rate=rate)
    sim = pumpsim.simulate(truth, duration=duration, rate=rate)
    y = sim.torque.copy()
    eff = math.sqrt(np.mean((y - ref.torque) ** 2))
    sd = float(np.std(ref.torque))
    sd_ref = sd if sd > 1e-3 * abs(np.mean(ref.torque)) else 0.25 * abs(float(np.mean(ref.torque)))
    sigma = noise * sd_ref if noise is not None else eff / snr
    speed = sim.speed.copy() if speed_column else None
    out = {"rig": family, "k": k, "A": A, "gamma": gamma, "seed": seed, "speed_column": speed_column,
           "effect_rms": eff, "sigma": sigma, "snr": eff / sigma, "mean_torque": float(np.mean(ref.torque))}
    if absorbed:
        names = ["mu", "theta0"] + ([] if speed_column else ["speed"])
        res = identify(nominal, Dataset(sim.time, y, speed=speed), names, multistart=True, speed_in_band=True,
                       adequacy=False)
        out["absorbed_rms"] = float(res.rms)
        out["absorbed_over_sigma"] = float(res.rms / sigma)
        # the clean residual's smooth part (5-point running median: drops one-sample spikes, the
        # friction reversals that fall on the other side of a sample) and its spike part
        from numpy.lib.stride_tricks import sliding_window_view as swv
        r = res.residual
        med = np.median(swv(np.pad(r, 2, mode="edge"), 5), axis=1)
        out["smooth_over_sigma"] = float(np.sqrt(np.mean(med ** 2)) / sigma)
        out["spikes_over_sigma"] = float(np.sqrt(np.mean((r - med) ** 2)) / sigma)
    if not run:
        return out
    key = zlib.crc32(f"{family}|oor{k}|{A:g}|{int(speed_column)}".encode())
    rng = np.random.default_rng([seed, key])
    yn = y + rng.normal(0, sigma, y.size)
    t0 = time.perf_counter()
    d = diagnose(nominal, Dataset(sim.time, yn, speed=speed))
    out.update(effects=d["effects"], confounded=d["confounded"], unexplained=d["unexplained"], verdict=d["verdict"],
               final_rms_over_sigma=d["final"]["rms"] / sigma, baseline_rms_over_sigma=d["baseline"]["rms"] / sigma,
               detectors={k_: d["final"][k_] for k_ in ("runs_p_value", "ljung_box_p_value", "synchronous_f_p_value",
                                                         "noise_level_p_value")},
               det_sigma_over_sigma=d.to_json()["detectors"]["noise_sigma"] / sigma,
               family_p=d.to_json()["detectors"]["combined_p"]["family"],
               orders=[s["params"].get("order") for s in d["steps"]], wall=time.perf_counter() - t0,
               screen0=[(r["candidate"], r["p_value"], r["significant"], r["one_step_rms"] and r["one_step_rms"] / sigma)
                        for r in d.to_json()["screens"][0]["candidates"][:8]] if d.to_json().get("screens") else None)
    return out


if __name__ == "__main__":
    import argparse
    ap = argparse.ArgumentParser()
    ap.add_argument("--rigs", default="concentric4")
    ap.add_argument("--k", type=int, default=3)
    ap.add_argument("--A", default="6e-5")
    ap.add_argument("--gammas", default="0.3")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--noise", default="0.02")
    ap.add_argument("--snr", default=None)
    ap.add_argument("--sc", default="0")
    ap.add_argument("--norun", action="store_true")
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    rows = []
    for fam in a.rigs.split(","):
        for A in map(float, a.A.split(",")):
            for g in map(float, a.gammas.split(",")):
                for sc in map(int, a.sc.split(",")):
                    levels = [("noise", float(x)) for x in a.noise.split(",")] if a.snr is None else \
                        [("snr", float(x)) for x in a.snr.split(",")]
                    for kind, lev in levels:
                        for seed in range(a.seeds):
                            o = case(fam, a.k, A, g, seed, bool(sc), run=not a.norun,
                                     **{kind: lev})
                            rows.append(o)
                            msg = (f"{fam:<12} k={a.k} A={A*1e6:4.0f}um g={g:.2f} sc={sc} seed={seed} "
                                   f"eff/sig={o['snr']:6.2f} abs/sig={o.get('absorbed_over_sigma', float('nan')):6.3f} "
                                   f"smooth/sig={o.get('smooth_over_sigma', float('nan')):6.3f}")
                            if not a.norun:
                                msg += (f" -> {','.join(f'{e}' + (f'(k={k_})' if k_ else '') for e, k_ in zip(o['effects'], o['orders'])) or '-'}"
                                        f" unexpl={o['unexplained']} conf={o['confounded']} fin/sig={o['final_rms_over_sigma']:.3f}"
                                        f" base/sig={o['baseline_rms_over_sigma']:.3f} detsig/sig={o['det_sigma_over_sigma']:.2f} famp={o['family_p']:.2g} {o['wall']:.0f}s")
                            print(msg, flush=True)
    if a.out:
        Path(a.out).write_text(json.dumps(rows, indent=1, default=str))
