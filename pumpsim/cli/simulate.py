"""`pumpsim simulate CONFIG`: one run of the constrained or the contact model."""
from __future__ import annotations

from ..tolerances import ATOL, RTOL
from .common import FIGURE, Help, add_force, load_config, outputs, positive_float, positive_int, \
    info, progress_printer, staged, tolerance, warn


def register(sub):
    s = sub.add_parser("simulate", help="simulate a pump configuration", formatter_class=Help,
                       description="Simulate a configuration (Model 2 constrained or Model 1 contact).")
    s.add_argument("config", help="TOML configuration (SI units: m, kg, s, rad)")
    s.add_argument("--model", choices=["constrained", "contact"], default="constrained",
                   help="constrained: Model 2 (tip on the housing); contact: Model 1 (penalty contacts)")
    s.add_argument("--duration", type=positive_float,
                   help="simulated time [s] (default: two revolutions at the configured speed for a "
                        "speed drive, 0.5 s for a torque drive)")
    s.add_argument("--rate", type=positive_float, default=10000.0, help="output sample rate [Hz]")
    s.add_argument("--out", help="CSV file: time, angle, speed, torque and the per-vane columns")
    s.add_argument("--plot", help="figure file (.png, .svg or .pdf)")
    s.add_argument("--plot-x", dest="plot_x", choices=["angle", "time"], default="angle",
                   help="figure x axis: rotor angle in degrees with revolutions overlaid, or time")
    s.add_argument("--method", choices=["cvodes", "idas", "rk"], default="cvodes",
                   help="integrator for a torque drive / the contact model (rk: explicit RK4, fixed step)")
    s.add_argument("--rtol", type=tolerance, default=RTOL, help="relative tolerance")
    s.add_argument("--atol", type=tolerance, default=ATOL,
                   help="absolute tolerance of positions [rad, m]; the contact model allows "
                        "atol x starting speed for speeds and vane velocities [rad/s, m/s]")
    s.add_argument("--max-step", type=positive_float, dest="max_step",
                   help="largest integrator step [s] (rk: the fixed step, default 1e-6 s)")
    s.add_argument("--max-steps", type=positive_int, dest="max_steps", default=500000,
                   help="integrator steps allowed per call before it gives up")
    s.add_argument("--initial", choices=["bottom", "rotor", "housing"],
                   help="contact model: initial vane state (default: operation.initial_vane_state, else rotor)")
    s.add_argument("--keep-partial", action="store_true", dest="keep_partial",
                   help="on a numerical failure, write the samples computed before it to --out")
    add_force(s)
    s.set_defaults(func=run)


def _write(outs, a, res, cfg) -> None:
    with staged(outs) as tmp:
        if a.out:
            res.to_csv(tmp["--out"])
        if a.plot:
            res.plot(tmp["--plot"], name=cfg.name, x=a.plot_x)


def run(a) -> int:
    from .. import SimulationResult, SolverError, simulate
    from ..errors import ConfigError
    from ..interrupt import Interrupted

    outs = outputs(a, [a.config], out=None, plot=FIGURE)
    cfg = load_config(a)
    opts = {}
    if a.model == "contact" and a.initial:
        opts["initial"] = a.initial
    elif a.initial:
        raise ConfigError("--initial is for the contact model (--model contact)")
    progress = progress_printer(a.duration) if a.duration else None
    try:
        res = simulate(cfg, model=a.model, duration=a.duration, rate=a.rate, method=a.method,
                       rtol=a.rtol, atol=a.atol, max_step=a.max_step, progress=progress,
                       max_steps=a.max_steps, **opts)
    except (SolverError, Interrupted) as e:
        part = e.partial
        if a.keep_partial and isinstance(part, SimulationResult) and part.time.size >= 2 and (a.out or a.plot):
            _write(outs, a, part, cfg)  # every requested file, complete, or none
            kept = " and ".join(x for x in (a.out, a.plot) if x)
            if isinstance(e, Interrupted):
                e.notes.append(f"the {part.time.size} samples computed before it are in {kept}")
            else:
                info(f"the samples computed before the failure are in {kept}")
        elif a.keep_partial and (a.out or a.plot):
            n = part.time.size if isinstance(part, SimulationResult) else 0
            note = f"--keep-partial: {n} output sample(s) computed before it stopped, fewer than 2: nothing kept"
            if isinstance(e, Interrupted):
                e.notes.append(note)
            else:
                info(note)
        raise
    _write(outs, a, res, cfg)
    print(res.summary(warnings=False))
    warn(w.replace("use model='contact'", "use --model contact") for w in res.warnings)  # the flag, not the keyword
    return 0
