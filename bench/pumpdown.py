"""Pump-down benchmark (`make bench`, section "pumpdown"): the bundled EVP example evacuated
101.3 -> 30 kPa at 13.5 V by the full model (all cells, valves, motor; CVODES with the compiled
Jacobian) and by the fast path (cycle-averaged maps); wall times against simulated time, their
ratio, step counts and solver statistics, and where the full path's wall time goes: compiled
right-hand side and Jacobian evaluations (calls x the cost of one call, timed on the run's own
states), the rest of CVODES (linear algebra, step control), and Python around the integrator.
Targets (issue 15): full path <= real time, fast path <= 1 s."""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pumpsim.config import load_config  # noqa: E402
from pumpsim.pneumatics import pumpdown as pdm  # noqa: E402
from pumpsim.cli.pumpdown import map_pressures  # noqa: E402
from pumpsim.kernels.pneumatic import kernels  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", default=str(ROOT / "out" / "bench.json"))
    ap.add_argument("--config", default=str(ROOT / "examples" / "evp_booster.toml"))
    a = ap.parse_args()
    cfg = load_config(a.config)
    kernels(cfg)  # build outside the timing
    print(f"pump-down: {cfg.name}, {cfg.pneumatic.booster_start / 1e3:.1f} -> "
          f"{cfg.pneumatic.booster_target / 1e3:.1f} kPa, {cfg.pneumatic.values['motor.voltage']:g} V")
    t0 = time.perf_counter()
    full = pdm.pumpdown(cfg)
    wall_full = time.perf_counter() - t0
    s, st = full.summary, full.summary["solver"]
    revs = (full.columns["angle"][-1] - full.columns["angle"][0]) / (2 * 3.141592653589793)
    sim = s["duration"]
    print(f"  full model : {sim:.3f} s simulated ({revs:.0f} revolutions) in {wall_full:.2f} s wall "
          f"= {wall_full / sim:.2f} x real time (target <= 1); {st['nsteps']} steps "
          f"({st['nsteps'] / revs:.0f}/rev, {wall_full / st['nsteps'] * 1e6:.1f} us/step), "
          f"{st['nfevals']} rhs, {st['njevals']} Jacobians, {st['netfails']} error-test and "
          f"{st['nncfails']} Newton failures; rtol {st['rtol']:g}, atol {st['atol']:g}")
    split = wall_split(cfg, full, st, wall_full)
    print(f"  where the wall goes: rhs {split['rhs_call_us']:.1f} us x {st['nfevals']} = "
          f"{split['rhs_s']:.2f} s, Jacobian {split['jac_call_us']:.1f} us x {st['njevals']} = "
          f"{split['jac_s']:.2f} s, rest of CVODES (linear solves, step control) {split['cvodes_rest_s']:.2f} s, "
          f"Python {split['python_s']:.2f} s ({split['python_share']:.0%})")
    t0 = time.perf_counter()
    maps = pdm.pump_maps(cfg, map_pressures(cfg, s["final_pressure"]))
    wall_maps = time.perf_counter() - t0
    import scipy.integrate  # noqa: F401  (one-time imports are not the fast path's cost)
    import scipy.interpolate  # noqa: F401

    t0 = time.perf_counter()
    fast = pdm.fast_pumpdown(cfg, maps)
    wall_fast = time.perf_counter() - t0
    print(f"  fast path  : {wall_fast * 1e3:.1f} ms from the maps (target <= 1 s; {fast['rhs_evaluations']} "
          f"rhs), maps {wall_maps:.1f} s ({len(maps.pressure)} pressures, {maps.steps} steps)")
    print(f"  ratio full / fast: {wall_full / wall_fast:.0f}x (full / (maps + fast): "
          f"{wall_full / (wall_maps + wall_fast):.1f}x)")
    print(f"  time to target {s['time_to_target']:.3f} s full, {fast['time_to_target']:.3f} s fast; "
          f"mean current {s['mean_current']:.2f} / {fast['mean_current']:.2f} A; peak "
          f"{s['peak_current']:.1f} A; energy {s['energy']:.0f} / {fast['energy']:.0f} J")
    res = {"simulated_s": sim, "revolutions": revs, "full_wall_s": wall_full,
           "full_real_time_factor": wall_full / sim, "full_solver": st, "full_wall_split": split,
           "steps_per_revolution": st["nsteps"] / revs, "fast_wall_s": wall_fast,
           "maps_wall_s": wall_maps, "map_steps": maps.steps, "ratio_full_fast": wall_full / wall_fast,
           "time_to_target": {"full": s["time_to_target"], "fast": fast["time_to_target"]},
           "mean_current": {"full": s["mean_current"], "fast": fast["mean_current"]},
           "peak_current": s["peak_current"], "energy": {"full": s["energy"], "fast": fast["energy"]}}
    path = Path(a.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = json.loads(path.read_text()) if path.exists() else {}
    data["pumpdown"] = res
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float))
    os.replace(tmp, path)
    print(f"wrote {path} (pumpdown)")


def wall_split(cfg, full, st, wall):
    """The full run's wall time by part: one call of the compiled rhs and Jacobian timed on 200 of
    the run's states (a mapped call, so no Python per state), times the calls CVODES made."""
    import numpy as np

    kern = kernels(cfg)
    X = full.run.states[:: max(1, len(full.run.states) // 200)].T
    p = np.asarray(full.run.p).reshape(-1, 1)
    cost = {}
    for name in ("pump_rhs", "pump_rhs_jac"):
        f = kern.mapped(name, X.shape[1])
        f(X, p)
        t0 = time.perf_counter()
        for _ in range(5):
            f(X, p)
        cost[name] = (time.perf_counter() - t0) / (5 * X.shape[1])
    rhs, jac = cost["pump_rhs"] * st["nfevals"], cost["pump_rhs_jac"] * st["njevals"]
    inside = st.get("integrator_wall", wall)
    return {"rhs_call_us": cost["pump_rhs"] * 1e6, "jac_call_us": cost["pump_rhs_jac"] * 1e6,
            "rhs_s": rhs, "jac_s": jac, "cvodes_rest_s": max(inside - rhs - jac, 0.0),
            "python_s": wall - inside, "python_share": (wall - inside) / wall}


if __name__ == "__main__":
    main()
