"""Command line (spec §7). Exit status: 0 success, 2 bad input, 1 numerical failure."""
from __future__ import annotations

import argparse
import sys

from .errors import PumpsimError
from .tolerances import ATOL, RTOL


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # bad options are bad input: status 2 with the usage line
        self.print_usage(sys.stderr)
        print(f"pumpsim: error: {message}", file=sys.stderr)
        sys.exit(2)


def _progress_printer(total):
    """Simulated-time progress on a terminal; silent in pipes and tests."""
    if not sys.stderr.isatty():
        return None
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        return None
    bar = tqdm(total=total, unit="s sim", unit_scale=True, leave=False, file=sys.stderr,
               bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s simulated [{elapsed}<{remaining}]")
    state = {"t": 0.0}

    def update(t):
        bar.update(max(0.0, t - state["t"]))
        state["t"] = t
        if t >= total:
            bar.close()

    return update


def cmd_simulate(a) -> int:
    from . import SimulationResult, SolverError, load_config, simulate

    cfg = load_config(a.config)
    if a.plot:  # an unsupported figure format is bad input: refused before any work
        from .plotting import figure_format

        figure_format(a.plot)
    opts = {}
    if a.model == "contact" and a.initial:
        opts["initial"] = a.initial
    duration = a.duration
    progress = _progress_printer(duration) if duration else None
    try:
        res = simulate(cfg, model=a.model, duration=duration, rate=a.rate, method=a.method,
                       rtol=a.rtol, atol=a.atol, max_step=a.max_step, progress=progress,
                       max_steps=a.max_steps, **opts)
    except SolverError as e:
        if isinstance(e.partial, SimulationResult) and a.out:  # keep what was computed
            e.partial.to_csv(a.out)
            print(f"pumpsim: the samples computed before the failure are in {a.out}", file=sys.stderr)
        raise
    if a.out:
        res.to_csv(a.out)
    if a.plot:
        res.plot(a.plot, name=cfg.name, x=a.plot_x)
    print(res.summary())
    for w in res.warnings:
        print(f"pumpsim: warning: {w}", file=sys.stderr)
    return 0


def cmd_study(a) -> int:
    from . import load_config
    from .errors import ConfigError
    from .study import HEADER, solver_study, write_json

    cfg = load_config(a.config)
    if not cfg.contact_given:
        raise ConfigError("the solver study needs [contact.housing] with a stiffness in the config")
    if not a.revolutions > 0:
        raise ConfigError(f"--revolutions must be > 0, got {a.revolutions}")
    print(f"contact model solver study: {cfg.name}, constant speed, {a.revolutions:g} revolutions "
          "from an in-contact start; deviations from Model 2 over the last revolution")
    print(HEADER)
    result = solver_study(cfg, revolutions=a.revolutions, speed=a.speed, log=print)
    if a.json:
        write_json(a.json, result)
    return 0


def _data_options(a):
    from .data import DataOptions

    return DataOptions(time=a.time_column, torque=a.torque_column, speed=a.speed_column,
                       angle=a.angle_column, torque_unit=a.torque_unit, speed_unit=a.speed_unit,
                       resample=a.resample, steady=a.steady)


def _add_data_options(p):
    g = p.add_argument_group("data")
    g.add_argument("--time-column", default="time")
    g.add_argument("--torque-column", default="torque")
    g.add_argument("--speed-column", default="speed")
    g.add_argument("--angle-column", default="angle")
    g.add_argument("--torque-unit", default="N*m", help="N*m or N*mm")
    g.add_argument("--speed-unit", default="rad/s", help="rad/s or rpm")
    g.add_argument("--resample", type=float, help="resample to this rate [Hz]")
    g.add_argument("--steady", action="store_true",
                   help="fit only the constant-speed section (needs a speed column)")


def _parse_params(text):
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        from .errors import ConfigError

        raise ConfigError("--params names no parameter")
    return names


def _parse_initial(items):
    from .errors import ConfigError

    out = {}
    for item in items or []:
        name, sep, val = item.partition("=")
        try:
            out[name.strip()] = float(val)
        except ValueError:
            raise ConfigError(f"--start takes NAME=VALUE, got '{item}'") from None
        if not sep:
            raise ConfigError(f"--start takes NAME=VALUE, got '{item}'")
    return out


def cmd_identify(a) -> int:
    import json

    from . import load_config
    from .data import load_data
    from .identify import identify
    from .io import write_text

    cfg = load_config(a.config)
    params = _parse_params(a.params)
    data = load_data(a.data, _data_options(a),
                     nominal_speed=None if ("speed" in params or a.transient) else
                     (cfg.speed if cfg.mode == "speed" else None))
    if a.transient:
        from .transient import identify_transient

        res = identify_transient(cfg, data, params=params, initial=_parse_initial(a.start), max_iter=a.max_iter)
    else:
        res = identify(cfg, data, params=params, method=a.method, relaxation=a.relaxation,
                       initial=_parse_initial(a.start), max_iter=a.max_iter)
    print(res)
    if a.json:
        write_text(a.json, json.dumps(res.to_json(), indent=1))
    if a.report:
        from .report import identification_report

        identification_report(res, a.report, title=f"pumpsim identification: {cfg.name}", cfg=cfg, data=data)
    return 0


def cmd_diagnose(a) -> int:
    import json

    from . import load_config
    from .data import load_data
    from .diagnose import diagnose, step_table, tty_progress
    from .io import write_text

    cfg = load_config(a.config)
    # several files: measurements of one pump at different speeds, fitted together
    data = [load_data(d, _data_options(a), nominal_speed=cfg.speed if cfg.mode == "speed" else None)
            for d in a.data]
    out = diagnose(cfg, data, progress=tty_progress())
    if sys.stderr.isatty():
        print(file=sys.stderr)
    print(step_table(out))
    if a.json:
        write_text(a.json, json.dumps({k: v for k, v in out.items() if not k.startswith("_")}, indent=1))
    if a.report:
        from .report import diagnosis_report

        diagnosis_report(out, a.report, title=f"pumpsim diagnosis: {cfg.name}", cfg=cfg, data=data)
    return 0


def _add_fit_outputs(p):
    """What identify and diagnose share: JSON, HTML report and the data-reading options."""
    p.add_argument("--json")
    p.add_argument("--report", help="self-contained HTML report")
    _add_data_options(p)


def build_parser():
    ap = _Parser(prog="pumpsim", description="Rotary vane vacuum pump simulation and identification.")
    sub = ap.add_subparsers(dest="command", required=True, parser_class=_Parser)
    s = sub.add_parser("simulate", help="simulate a pump configuration")
    s.add_argument("config")
    s.add_argument("--model", choices=["constrained", "contact"], default="constrained")
    s.add_argument("--duration", type=float, help="simulated time [s] (default: two revolutions)")
    s.add_argument("--rate", type=float, default=10000.0, help="output sample rate [Hz]")
    s.add_argument("--out", help="CSV file for the spec §7 columns")
    s.add_argument("--plot", help="PNG file for the figure set")
    s.add_argument("--plot-x", dest="plot_x", choices=["angle", "time"], default="angle",
                   help="figure x axis: rotor angle in degrees with revolutions overlaid, or time "
                        "(default: %(default)s)")
    s.add_argument("--method", choices=["cvodes", "idas", "rk"], default="cvodes",
                   help="integrator for torque drive / the contact model")
    s.add_argument("--rtol", type=float, default=RTOL)
    s.add_argument("--atol", type=float, default=ATOL,
                   help="absolute tolerance of positions [rad, m]; the contact model allows "
                        "atol x starting speed for speeds and vane velocities [rad/s, m/s]")
    s.add_argument("--max-step", type=float, dest="max_step", help="largest integrator step [s]")
    s.add_argument("--max-steps", type=int, dest="max_steps", default=500000,
                   help="integrator steps allowed per call before it gives up")
    s.add_argument("--initial", choices=["bottom", "rotor", "housing"],
                   help="contact model: initial vane state (default rotor)")
    s.set_defaults(func=cmd_simulate)
    ip = sub.add_parser("identify", help="fit friction (and phase, speed, offsets) to measured torque")
    ip.add_argument("config")
    ip.add_argument("data", help="CSV, MATLAB .mat or NI .tdms file")
    ip.add_argument("--params", default="mu,theta0",
                    help="comma-separated: mu, mu_slot, theta0, speed, torque_offset, delay or any "
                         "numeric config key path (e.g. housing.center.0)")
    ip.add_argument("--method", default="gauss-newton", choices=["gauss-newton", "levenberg-marquardt", "ipopt"])
    ip.add_argument("--relaxation", type=float, default=1.0, help="Gauss-Newton relaxation factor f in (0, 1]")
    ip.add_argument("--start", action="append", metavar="NAME=VALUE", help="initial value of a fitted parameter")
    ip.add_argument("--max-iter", type=int, default=50, dest="max_iter")
    ip.add_argument("--transient", action="store_true",
                    help="the data is a run-up/coast-down: apply the measured torque, fit the measured "
                         "speed (parameters mu, mu_slot, speed0, theta0 or config paths)")
    _add_fit_outputs(ip)
    ip.set_defaults(func=cmd_identify)
    dg = sub.add_parser("diagnose", help="find, name and add the effect missing from the model")
    dg.add_argument("config")
    dg.add_argument("data", nargs="+", help="one or more measurements (several speeds separate "
                    "offset, viscous friction and COF)")
    _add_fit_outputs(dg)
    dg.set_defaults(func=cmd_diagnose)
    st = sub.add_parser("study", help="contact-model solver study (report §7-8)")
    st.add_argument("config")
    st.add_argument("--revolutions", type=float, default=10.0)
    st.add_argument("--speed", type=float, help="constant speed [rad/s] (default: the config's)")
    st.add_argument("--json", help="write the table as JSON")
    st.set_defaults(func=cmd_study)
    from .design.cli import add_design_commands  # sweep, sensitivity, optimize (spec §9)

    add_design_commands(sub)
    from .pneumatics.cli import add_pumpdown_command  # pumpdown (spec §8)

    add_pumpdown_command(sub)
    return ap


def main(argv=None) -> int:
    ap = build_parser()
    a = ap.parse_args(argv)
    try:
        return a.func(a)
    except PumpsimError as e:
        print(f"pumpsim: error: {e}", file=sys.stderr)
        return e.exit_status
    except KeyboardInterrupt:
        print("pumpsim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
