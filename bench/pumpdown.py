"""Pump-down benchmark (`make bench`, section "pumpdown"): the bundled EVP example evacuated
101.3 -> 30 kPa at 13.5 V by the full model (all cells, valves, motor; CVODES with the compiled
Jacobian) and by the fast path (cycle-averaged maps); wall times against simulated time, their
ratio, step counts and solver statistics, and where the full path's CPU time goes: compiled
right-hand side and Jacobian evaluations (the driver's own timing of its kernel calls), the rest
of CVODES (linear algebra, step control), and Python around the integrator. The same run with the
cell and vane geometry computed at every call instead of read from the table (PUMPSIM_GEOMETRY).
The full model also through CasADi's CVODES plugin (the fallback where the direct driver cannot be
built), and over the first `--span` seconds against SciPy LSODA, BDF and Radau on the same
compiled right-hand side and Jacobian, interleaved, median of 3, each with its error against an
rtol 1e-8 run (bench/scipy_compare.py). Targets (issue 28): full path <= 0.3 x real time and
>= 1.5x faster than SciPy's best; fast path <= 1 s."""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pumpsim import cvodes_driver  # noqa: E402
from pumpsim.config import load_config  # noqa: E402
from pumpsim.pneumatics import pumpdown as pdm  # noqa: E402
from pumpsim.cli.pumpdown import map_pressures  # noqa: E402
from pumpsim.kernels.pneumatic import kernels  # noqa: E402
from pumpsim.pneumatics import geometry_table, run  # noqa: E402
from scipy_compare import casadi_plugin  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--json", default=str(ROOT / "out" / "bench.json"))
    ap.add_argument("--config", default=str(ROOT / "examples" / "evp_booster.toml"))
    ap.add_argument("--span", type=float, default=0.5, help="simulated seconds of the SciPy comparison")
    ap.add_argument("--profile-span", type=float, default=1.0,
                    help="simulated seconds of the step profile (what limits the steps; 0: none)")
    a = ap.parse_args()
    cfg = load_config(a.config)
    kernels(cfg)  # build outside the timing
    print(f"pump-down: {cfg.name}, {cfg.pneumatic.booster_start / 1e3:.1f} -> "
          f"{cfg.pneumatic.booster_target / 1e3:.1f} kPa, {cfg.pneumatic.values['motor.voltage']:g} V")
    os.environ[cvodes_driver.TIMING_ENV] = "1"  # the driver times its kernel calls (cpu_split)
    t0, c0 = time.perf_counter(), time.process_time()
    full = pdm.pumpdown(cfg)
    wall_full, cpu_full = time.perf_counter() - t0, time.process_time() - c0
    del os.environ[cvodes_driver.TIMING_ENV]
    s, st = full.summary, full.summary["solver"]
    revs = (full.columns["angle"][-1] - full.columns["angle"][0]) / (2 * 3.141592653589793)
    sim = s["duration"]
    print(f"  full model : {sim:.3f} s simulated ({revs:.0f} revolutions) in {wall_full:.2f} s wall "
          f"= {wall_full / sim:.2f} x real time (target <= 0.3; {cpu_full:.2f} CPU s = "
          f"{cpu_full / sim:.2f} x, what a quiet machine's wall would be); {st['nsteps']} steps "
          f"({st['nsteps'] / revs:.0f}/rev, {wall_full / st['nsteps'] * 1e6:.1f} us/step), "
          f"{st['nfevals']} rhs, {st['njevals']} Jacobians, {st['netfails']} error-test and "
          f"{st['nncfails']} Newton failures; rtol {st['rtol']:g}, atol {st['atol']:g}")
    exact = exact_geometry(cfg, full, cpu_full)
    with casadi_plugin():
        t0 = time.perf_counter()
        plug = pdm.pumpdown(cfg)
        wall_plug = time.perf_counter() - t0
    sp = plug.summary["solver"]
    print(f"  full model through CasADi's CVODES plugin: {wall_plug:.2f} s wall ({wall_full / wall_plug:.2f} of it "
          f"with the direct driver); {sp['nsteps']} steps, {sp['njevals']} Jacobians, {sp['netfails']} error-test "
          f"and {sp['nncfails']} Newton failures; time to target {plug.summary['time_to_target']:.4f} s")
    split = cpu_split(st, cpu_full)
    print(f"  where the CPU time goes ({st.get('geometry', 'exact')} geometry): rhs {split['rhs_call_us']:.1f} us x {st['nfevals']} = "
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
           "full_real_time_factor": wall_full / sim, "full_cpu_s": cpu_full,
           "full_cpu_real_time_factor": cpu_full / sim, "full_solver": st, "full_cpu_split": split,
           "steps_per_revolution": st["nsteps"] / revs, "fast_wall_s": wall_fast,
           "maps_wall_s": wall_maps, "map_steps": maps.steps, "ratio_full_fast": wall_full / wall_fast,
           "time_to_target": {"full": s["time_to_target"], "fast": fast["time_to_target"]},
           "mean_current": {"full": s["mean_current"], "fast": fast["mean_current"]},
           "peak_current": s["peak_current"], "energy": {"full": s["energy"], "fast": fast["energy"]},
           "driver": st.get("driver"), "exact_geometry": exact, "casadi_plugin_wall_s": wall_plug, "casadi_plugin_solver": sp,
           "scipy_span": scipy_span(cfg, a.span),
           "step_profile": step_profile(cfg, a.profile_span) if a.profile_span > 0 else None}
    path = Path(a.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = json.loads(path.read_text()) if path.exists() else {}
    data["pumpdown"] = res
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float))
    os.replace(tmp, path)
    print(f"wrote {path} (pumpdown)")


def exact_geometry(cfg, full, cpu_table):
    """The same pump-down with the cell geometry computed at every call (PUMPSIM_GEOMETRY=exact):
    its CPU time against the tabulated run's, and the figures' relative differences (the
    integration's own error at the run's tolerances: the step sequences differ)."""
    if full.summary["solver"].get("geometry") != "table":
        return None
    old = os.environ.get(geometry_table.ENV)
    os.environ[geometry_table.ENV] = "exact"
    try:
        c0 = time.process_time()
        ex = pdm.pumpdown(cfg)
        cpu = time.process_time() - c0
    finally:
        if old is None:
            del os.environ[geometry_table.ENV]
        else:
            os.environ[geometry_table.ENV] = old
    names = ("time_to_target", "energy", "mean_current", "peak_current")
    diff = {n: abs(full.summary[n] - ex.summary[n]) / abs(ex.summary[n]) for n in names}
    print(f"  full model, exact geometry at every call: {cpu:.2f} CPU s = {cpu / ex.summary['duration']:.2f} x "
          f"real time ({cpu / cpu_table:.2f}x the tabulated run's CPU); figures' relative differences "
          + ", ".join(f"{n} {v:.1e}" for n, v in diff.items()))
    return {"cpu_s": cpu, "ratio_to_table": cpu / cpu_table, "relative_differences": diff,
            "solver": ex.summary["solver"]}


def scipy_span(cfg, span, repeats=3):
    """The first `span` s of the pump-down: the runtime's CVODES (direct driver, CasADi plugin) and
    SciPy's stiff methods on the same compiled rhs and Jacobian, interleaved, median of `repeats`;
    errors of the booster pressure (largest over the grid) and the electrical energy (at the end)
    against an rtol 1e-8 run. The geometry computed at every call here (PUMPSIM_GEOMETRY=exact):
    the integrators on the very same right-hand side (the table's gain is exact_geometry's row)."""
    import numpy as np

    os.environ[geometry_table.ENV] = "exact"
    try:
        return _scipy_span(cfg, span, repeats, np)
    finally:
        del os.environ[geometry_table.ENV]


def _scipy_span(cfg, span, repeats, np):

    from scipy_compare import (METHODS, casadi_plugin, compiled_ode, interleaved, print_table, report_ratio,
                                scipy_run)
    from pumpsim.kernels.pneumatic import parameter_vector
    from pumpsim.tolerances import PUMPDOWN_ATOL, PUMPDOWN_RTOL

    kern, p, rate = kernels(cfg), parameter_vector(cfg), 2000.0
    x0 = run.initial_state(cfg, kern, p)
    nx, nq = x0.size, kern["pump_rhs"].size1_out(1)
    pb = run.booster_pressure(kern.structure, p)
    ref = run.integrate(cfg, span, rate, rtol=1e-8, atol=1e-9)
    t, P_ref, E_ref = ref.time, pb(ref.states), ref.quad[-1, 0]

    def error(P, E):
        e_p, e_e = np.max(np.abs(P - P_ref)) / P_ref[0], abs(E - E_ref) / abs(E_ref)
        return {"error_pressure_rel": float(e_p), "error_energy_rel": float(e_e),
                "error_text": f"booster pressure {e_p:.1e}, energy {e_e:.1e} (relative)"}

    def compiled(rtol=PUMPDOWN_RTOL, atol=PUMPDOWN_ATOL):
        r = run.integrate(cfg, span, rate, rtol=rtol, atol=atol)
        st = r.stats
        return {"steps": st["nsteps"], "rhs": st["nfevals"], "jac": st["njevals"], **error(pb(r.states), r.quad[-1, 0])}

    def plugin():
        with casadi_plugin():
            return compiled()

    rhs, jac = compiled_ode(kern, "pump_rhs", [x0, p], [0, nx])
    y0 = np.concatenate([x0, np.zeros(nq)])
    atol = PUMPDOWN_ATOL * np.concatenate([run.state_scale(x0, p, kern.structure), np.ones(nq)])

    def scipy(method):
        sol = scipy_run(rhs, jac, y0, t[-1], t, method, PUMPDOWN_RTOL, atol)
        if not sol.success:
            return {"steps": None, "rhs": int(sol.nfev), "jac": int(sol.njev), "error_text": sol.message}
        return {"steps": None, "rhs": int(sol.nfev), "jac": int(sol.njev), **error(pb(sol.y[:nx].T), sol.y[nx, -1])}

    rows = {"compiled CVODES, direct driver": compiled, "compiled CVODES, CasADi plugin": plugin,
            "compiled CVODES, direct, tol / 10": lambda: compiled(PUMPDOWN_RTOL / 10, PUMPDOWN_ATOL / 10),
            "compiled CVODES, direct, tol / 100": lambda: compiled(PUMPDOWN_RTOL / 100, PUMPDOWN_ATOL / 100)}
    rows.update({f"SciPy {m} (compiled rhs+Jac)": (lambda m=m: scipy(m)) for m in METHODS})
    res = interleaved(rows, repeats)
    best = print_table(f"  pump-down, first {span:g} s, rtol {PUMPDOWN_RTOL:g}, atol {PUMPDOWN_ATOL:g}; median of "
                       f"{repeats}, interleaved", res)
    return {"span": span, "rows": res, "best_scipy": best,
            **report_ratio(res, best, ("error_pressure_rel", "error_energy_rel"), indent="  ")}


def step_profile(cfg, span, bins=18):
    """What limits the full model's steps over its first `span` s (one-step CVODES, the run's
    tolerances): which state dominates the local error (share of the steps it dominates, share of
    the summed squared weighted errors), and where in a vane pitch (rotor angle mod 2 pi / N) the
    steps and the error-test and Newton failures fall."""
    import numpy as np

    from pumpsim.kernels.pneumatic import parameter_vector
    from pumpsim.tolerances import PUMPDOWN_ATOL, PUMPDOWN_RTOL

    kern, p = kernels(cfg), parameter_vector(cfg)
    x0 = run.initial_state(cfg, kern, p)
    integ = run.PumpIntegrator(kern, p, PUMPDOWN_RTOL, PUMPDOWN_ATOL, run.state_scale(x0, p, kern.structure))
    if integ.direct is None:
        return None
    pr = integ.direct.profile(0.0, np.concatenate([x0, np.zeros(integ.nq)]), span)
    names = run.state_names(kern.structure.vanes) + list(run.QUAD_NAMES)
    E2 = pr["weighted_error"] ** 2
    lead = np.bincount(np.argmax(E2, axis=1), minlength=len(names)) / len(E2)
    sq = E2.sum(axis=0) / E2.sum()
    order = np.argsort(-lead)[:6]
    dominant = {names[i]: {"steps_share": float(lead[i]), "error_share": float(sq[i])} for i in order}
    pitch = 2 * np.pi / kern.structure.vanes
    edges = np.linspace(0.0, np.degrees(pitch), bins + 1)
    angle = np.degrees(np.mod(pr["angle"], pitch))
    count = lambda w=None: np.histogram(angle, edges, weights=w)[0].astype(int).tolist()  # noqa: E731
    rms = np.sqrt(E2.mean(axis=1))
    res = {"span": span, "steps": len(rms), "dominant": dominant, "pitch_deg": float(np.degrees(pitch)),
           "bin_edges_deg": edges.tolist(), "steps_by_angle": count(),
           "error_test_failures_by_angle": count(pr["error_test_failures"]),
           "newton_failures_by_angle": count(pr["newton_failures"]),
           "error_norm_median": float(np.median(rms))}
    print(f"  step profile, first {span:g} s: {res['steps']} steps, median error norm {res['error_norm_median']:.2f} "
          "(1 = at the tolerance); the local error led by " + ", ".join(
              f"{n} {v['steps_share']:.0%}" for n, v in dominant.items()))
    print(f"  by rotor angle in the vane pitch ({res['pitch_deg']:.0f} deg): from deg  steps  error-test  Newton")
    for k in range(bins):
        print(f"    {edges[k]:5.1f} {res['steps_by_angle'][k]:7d} {res['error_test_failures_by_angle'][k]:7d} "
              f"{res['newton_failures_by_angle'][k]:7d}")
    return res


def cpu_split(st, cpu):
    """The full run's CPU time by part (CPU, not wall: meaningful on a loaded machine). The driver
    timed its own kernel calls (PUMPSIM_CVODES_TIMING: the monotonic clock around each call, the
    table's interpolation included): their shares of the integrator's wall, times the
    integrator's CPU, are the right-hand side's and the Jacobian's CPU; the rest of the
    integrator's CPU is CVODES' own work, the rest of the run's the Python around it. Timing each
    kernel apart in a loop (as before) came out 1.5-3x off: a kernel called back to back keeps
    its code and work arrays in cache, which it does not between CVODES' steps."""
    inside, wall = st.get("integrator_cpu", cpu), st.get("integrator_wall", 0.0)
    if not st.get("rhs_wall") or wall <= 0:
        nan = float("nan")
        return {"rhs_call_us": nan, "jac_call_us": nan, "rhs_s": nan, "jac_s": nan, "cvodes_rest_s": nan,
                "python_s": cpu - inside, "python_share": (cpu - inside) / cpu}
    rhs, jac = inside * st["rhs_wall"] / wall, inside * st["jac_wall"] / wall
    return {"rhs_call_us": rhs / st["nfevals"] * 1e6, "jac_call_us": jac / st["njevals"] * 1e6,
            "rhs_s": rhs, "jac_s": jac, "cvodes_rest_s": inside - rhs - jac,
            "python_s": cpu - inside, "python_share": (cpu - inside) / cpu}


if __name__ == "__main__":
    main()
