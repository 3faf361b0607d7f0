"""`pumpsim pumpdown CONFIG`: evacuate the booster (pressure, current, energy)."""
from __future__ import annotations

import json
import math
import sys

from ..errors import ConfigError
from ..tolerances import CONTACT_PUMPDOWN_ATOL, CONTACT_PUMPDOWN_RTOL, PUMPDOWN_ATOL, PUMPDOWN_RTOL
from .common import REPORT_SUFFIXES, add_force, live, load_config, outputs, positive_float, staged, tolerance, warn


def register(sub) -> None:
    pd = sub.add_parser("pumpdown", help="evacuate the booster: pressure, current, energy")
    pd.add_argument("config")
    pd.add_argument("--until", type=positive_float, help="target booster pressure [Pa] (default booster.target)")
    pd.add_argument("--duration", type=positive_float, help="longest simulated time [s] (default 120)")
    pd.add_argument("--out", help="CSV file: time, angle, speed, torque, booster_pressure, current and per cell pressure, volume, temperature")
    pd.add_argument("--plot", help="PNG file for the pump-down figures")
    pd.add_argument("--json", help="JSON file for the summary and the solver statistics")
    pd.add_argument("--report", help="HTML report (figures and tables)")
    pd.add_argument("--fast", action="store_true",
                    help="also run the fast path (cycle-averaged maps) and compare (always with "
                         "--plot/--report: the maps give the S(p) figure)")
    pd.add_argument("--model", choices=["constrained", "contact"], default="constrained",
                    help="constrained: Model 2 (tips on the housing); contact: Model 1 (vanes free in "
                         "their slots, penalty contacts, lift-off reported; needs [contact.housing])")
    pd.add_argument("--rate", type=positive_float, default=2000.0, help="output sample rate [Hz]")
    pd.add_argument("--rtol", type=tolerance, default=None,
                    help=f"relative tolerance (default {PUMPDOWN_RTOL:g}; {CONTACT_PUMPDOWN_RTOL:g} "
                         "with --model contact)")
    pd.add_argument("--atol", type=tolerance, default=None,
                    help=f"absolute tolerance relative to each state's starting size (default "
                         f"{PUMPDOWN_ATOL:g}; {CONTACT_PUMPDOWN_ATOL:g} with --model contact)")
    add_force(pd)
    pd.set_defaults(func=run)


def _progress(t, pb):
    print(f"\r  t = {t:7.3f} s, booster {pb / 1e3:6.2f} kPa", end="", file=sys.stderr, flush=True)


def run(a) -> int:
    from ..io import write_text

    outs = outputs(a, [a.config], out=None, plot=(".png",), json=None, report=REPORT_SUFFIXES)
    if a.model == "contact" and (a.fast or a.plot or a.report):
        raise ConfigError("--fast, --plot and --report use Model 2's cycle-averaged maps: run them "
                          "without --model contact")
    cfg = load_config(a)  # the unit/plausibility checks, --force and their warnings as simulate
    from ..pneumatics import pumpdown as pdm  # (after the config: its first work waits for no model import)

    if cfg.pneumatic is None:
        raise ConfigError(f"{a.config}: pumpdown needs the gas tables [ports] and [booster]")
    start = cfg.pneumatic.booster_start
    if a.until is not None and not a.until < start:
        raise ConfigError(f"--until must be in (0, booster.pressure ({start:g} Pa)), got {a.until:g}: the "
                          "target is a booster pressure below the start, in Pa")
    progress = _progress if live() else None
    res = pdm.pumpdown(cfg, until=a.until, duration=a.duration, rate=a.rate, rtol=a.rtol, atol=a.atol,
                       progress=progress, model=a.model)
    if progress:
        print(file=sys.stderr)
    maps = fast = None
    if a.fast or a.plot or a.report:
        p_end = min(res.summary["final_pressure"], res.summary["target_pressure"] or math.inf)
        maps = pdm.pump_maps(cfg, map_pressures(cfg, p_end))
        fast = pdm.fast_pumpdown(cfg, maps, until=a.until, duration=fast_duration(res.summary, maps))
        res.summary["fast_path"] = {**fast, "map_wall_time": maps.wall_time, "map_steps": maps.steps,
                                    "maps": maps_dict(maps)}
    print(res.text())
    if fast:
        t_f = fast["time_to_target"]
        made = f"({fast['wall_time'] * 1e3:.1f} ms from maps made in {maps.wall_time:.1f} s)"
        current = f", mean current {fast['mean_current']:.2f} A" if fast["mean_current"] is not None else ""
        print(f"  fast path: time to target {t_f:.3f} s{current} {made}" if t_f is not None else
              f"  fast path: target not reached; booster {fast['final_pressure'] / 1e3:.2f} kPa at "
              f"{fast['time'][-1]:.3f} s{current} {made}")
    warn(res.warnings)
    with staged(outs) as tmp:
        if a.out:
            res.to_csv(tmp["--out"])
        if a.json:
            write_text(tmp["--json"], json.dumps(res.summary, indent=1, default=float))
        if a.plot or a.report:
            from ..report.pumpdown import pumpdown_figure, pumpdown_report

            if a.plot:
                pumpdown_figure(res, maps, cfg, tmp["--plot"])
            if a.report:
                pumpdown_report(res, maps, cfg, tmp["--report"])
    return 0


def fast_duration(summary, maps) -> float:
    """The fast path's longest time: the full run's own when it stopped short of the target (so
    that the final pressures and mean currents compare), else room to reach the target."""
    t_full = summary["duration"]
    if summary["time_to_target"] is None and t_full > maps.runup.get("time", 0.0):
        return t_full
    return max(2 * t_full, 1.0)


def map_pressures(cfg, p_end, n=10):
    """Map grid, geometric, from 5 % of the start pressure (so that S(p) reaches the ultimate
    pressure of most pumps) or below the lowest pressure reached, to the start."""
    import numpy as np

    lo = min(0.8 * p_end, 0.05 * cfg.pneumatic.booster_start)
    return list(np.geomspace(lo, cfg.pneumatic.booster_start, n))


def maps_dict(m) -> dict:
    return {k: [float(x) for x in getattr(m, k)] for k in
            ("pressure", "mass_flow", "pumping_speed", "current", "torque", "speed", "gas_torque",
             "friction_torque")}
