"""Command line (spec §7).

Exit status: 0 success; 2 bad input (config, data, options, unit mistakes, output paths: the
message names the key, row, file or option and the limit; nothing is written) or a file-system
fault the user can fix (read-only, missing, full, no permission, an output another run holds: the
path, the operation and what to do); 1 a numerical failure (the message names the time and
state) or a fit whose answer must not be used as is (not converged, ended on a parameter bound,
or a named parameter not identifiable from the data: the outputs are still written, complete, and
say so); 130 / 143 interrupted by SIGINT / SIGTERM (one line: how far the run got, what is kept;
no partial file).

One function registers each command (`register_*`) and one runs it (`cmd_*`); a new command adds
its pair to COMMANDS. Output files are declared with `_outputs` before any work starts and written
together at the end (`pumpsim.io.Outputs`).
"""
from __future__ import annotations

import argparse
import contextlib
import os
import sys

from .errors import PumpsimError
from .tolerances import ATOL, RTOL

REPORT_SUFFIXES = (".html", ".htm")
FIGURE = object()  # an output whose type the figure writer decides (pumpsim.report.simulation.figure_format)


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # bad options are bad input: status 2 with the usage line
        import re

        message = re.sub(r"^argument (--[\w-]+): must", r"\1 must", message)
        self.print_usage(sys.stderr)
        print(f"pumpsim: error: {message}", file=sys.stderr)
        sys.exit(2)


class _Help(argparse.ArgumentDefaultsHelpFormatter):
    """--help shows every default."""


def _positive_float(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got '{text}'") from None
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"must be > 0 (and finite), got {text}")
    return v


def _tolerance(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got '{text}'") from None
    if not 0 < v < 1:
        raise argparse.ArgumentTypeError(f"must be in (0, 1), got {text}")
    return v


def _positive_int(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got '{text}'") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {text}")
    return v


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


def _fit_log():
    """One line per fit iteration on a terminal (long fits show they are alive)."""
    if not sys.stderr.isatty():
        return None

    def log(entry):
        print(f"\r\033[Kpumpsim: iteration {entry.get('iteration', '')} residual RMS {entry['rms']:.6g} N m",
              end="", file=sys.stderr, flush=True)

    return log


# --- shared option groups -------------------------------------------------------------------

def _add_force(p):
    p.add_argument("--force", action="store_true",
                   help="proceed although the unit/plausibility checks suspect a unit mistake")


def _outputs(a, inputs, **options):
    """The run's output files: options maps an attribute of `a` to its allowed suffixes (None: any,
    FIGURE: what the figure writer accepts). Checked now, before any work; written later inside
    `staged()`."""
    from .io import Outputs

    outs = Outputs(inputs)
    for attr, suffixes in options.items():
        path = getattr(a, attr, None)
        if suffixes is FIGURE:
            from .report.simulation import figure_format

            outs.add("--" + attr.replace("_", "-"), path, kind=figure_format)
        else:
            outs.add("--" + attr.replace("_", "-"), path, suffixes)
    outs.check()
    from .locks import hold_files

    hold_files({"--" + attr.replace("_", "-"): getattr(a, attr, None) for attr in options})
    return outs


@contextlib.contextmanager
def _staged(outs):
    """outs.staged() with a file-system fault while writing named: the output, what to do (exit 2)."""
    from . import fsfaults

    tmps = {}
    try:
        with outs.staged() as tmp:
            tmps.update(tmp)
            yield tmp
    except OSError as e:
        named = os.path.abspath(str(e.filename)) if e.filename is not None else None
        same = [o for o, t in tmps.items() if os.path.abspath(t) == named]
        if same:
            raise fsfaults.error(e, "writing", fsfaults.target_of(tmps[same[0]]), same[0]) from None
        every = ", ".join(f"{o} '{fsfaults.target_of(t)}'" for o, t in tmps.items())
        raise fsfaults.error(e, f"writing {every}" if every else "writing the outputs") from None


def _load_config(a):
    from .checks import checked_config

    cfg = checked_config(a.config, force=getattr(a, "force", False))
    _warn(cfg.warnings)
    return cfg


def _add_data_options(p):
    g = p.add_argument_group("data (units from the header, e.g. 'torque [N*mm]', else SI)")
    g.add_argument("--time-column", default="time", help="time column / channel / variable")
    g.add_argument("--torque-column", default="torque", help="torque column")
    g.add_argument("--speed-column", default="speed", help="speed column (used when present)")
    g.add_argument("--angle-column", default="angle", help="angle column (used when present)")
    g.add_argument("--time-unit", help="s, ms or us (default: the header's unit, else s)")
    g.add_argument("--torque-unit", help="N*m, N*mm, mN*m or N*cm (default: the header's unit, else N*m)")
    g.add_argument("--speed-unit", help="rad/s, rpm or rev/s (default: the header's unit, else rad/s)")
    g.add_argument("--resample", type=_rate_or_auto, metavar="HZ|auto",
                   help="interpolate onto a uniform grid at this rate [Hz] ('auto': the measured sample "
                        "rate), also across gaps in time, which are refused otherwise")
    g.add_argument("--steady", action="store_true",
                   help="fit only the constant-speed section (needs a speed column)")


def _rate_or_auto(text):
    return "auto" if text.strip().lower() == "auto" else _positive_float(text)


def _read_data(a, path, nominal_speed):
    """load_data with the command's data options; what it did to the data (resampled, time from a
    sample rate, jittered steps) is said on stderr."""
    from .data import load_data

    ds = load_data(path, _data_options(a), nominal_speed=nominal_speed)
    for note in ds.notes:
        print(f"pumpsim: {ds.name}: {note}", file=sys.stderr)
    return ds


def _data_options(a):
    from .data import DataOptions

    return DataOptions(time=a.time_column, torque=a.torque_column, speed=a.speed_column,
                       angle=a.angle_column, torque_unit=a.torque_unit, speed_unit=a.speed_unit,
                       time_unit=a.time_unit, resample=a.resample, steady=a.steady)


def _add_fit_outputs(p):
    """What identify and diagnose share: JSON, HTML report, data options and --force."""
    p.add_argument("--json", help="write the result as JSON")
    p.add_argument("--report", help="self-contained HTML report (.html)")
    _add_force(p)
    _add_data_options(p)


def _write_fit_outputs(outs, a, document: dict, write_report) -> None:
    """--json (the document) and --report (write_report(path)), renamed into place together."""
    import json

    from .io import write_text

    with _staged(outs) as tmp:
        if a.json:
            write_text(tmp["--json"], json.dumps(document, indent=1))
        if a.report:
            write_report(tmp["--report"])


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
        if not sep or not name.strip():
            raise ConfigError(f"--start takes NAME=VALUE, got '{item}'")
        if out[name.strip()] != out[name.strip()] or abs(out[name.strip()]) == float("inf"):
            raise ConfigError(f"--start {name.strip()} must be a finite number, got '{val}'")
    return out


def _warn(lines):
    for w in lines:
        print(f"pumpsim: warning: {w}", file=sys.stderr)


# --- simulate -------------------------------------------------------------------------------

def register_simulate(sub):
    s = sub.add_parser("simulate", help="simulate a pump configuration", formatter_class=_Help,
                       description="Simulate a configuration (Model 2 constrained or Model 1 contact).")
    s.add_argument("config", help="TOML configuration (SI units: m, kg, s, rad)")
    s.add_argument("--model", choices=["constrained", "contact"], default="constrained",
                   help="constrained: Model 2 (tip on the housing); contact: Model 1 (penalty contacts)")
    s.add_argument("--duration", type=_positive_float,
                   help="simulated time [s] (default: two revolutions at the configured speed for a "
                        "speed drive, 0.5 s for a torque drive)")
    s.add_argument("--rate", type=_positive_float, default=10000.0, help="output sample rate [Hz]")
    s.add_argument("--out", help="CSV file: time, angle, speed, torque and the per-vane columns")
    s.add_argument("--plot", help="figure file (.png, .svg or .pdf)")
    s.add_argument("--plot-x", dest="plot_x", choices=["angle", "time"], default="angle",
                   help="figure x axis: rotor angle in degrees with revolutions overlaid, or time")
    s.add_argument("--method", choices=["cvodes", "idas", "rk"], default="cvodes",
                   help="integrator for a torque drive / the contact model (rk: explicit RK4, fixed step)")
    s.add_argument("--rtol", type=_tolerance, default=RTOL, help="relative tolerance")
    s.add_argument("--atol", type=_tolerance, default=ATOL,
                   help="absolute tolerance of positions [rad, m]; the contact model allows "
                        "atol x starting speed for speeds and vane velocities [rad/s, m/s]")
    s.add_argument("--max-step", type=_positive_float, dest="max_step",
                   help="largest integrator step [s] (rk: the fixed step, default 1e-6 s)")
    s.add_argument("--max-steps", type=_positive_int, dest="max_steps", default=500000,
                   help="integrator steps allowed per call before it gives up")
    s.add_argument("--initial", choices=["bottom", "rotor", "housing"],
                   help="contact model: initial vane state (default: operation.initial_vane_state, else rotor)")
    s.add_argument("--keep-partial", action="store_true", dest="keep_partial",
                   help="on a numerical failure, write the samples computed before it to --out")
    _add_force(s)
    s.set_defaults(func=cmd_simulate)


def _write_simulation(outs, a, res, cfg) -> None:
    with _staged(outs) as tmp:
        if a.out:
            res.to_csv(tmp["--out"])
        if a.plot:
            res.plot(tmp["--plot"], name=cfg.name, x=a.plot_x)


def cmd_simulate(a) -> int:
    from . import SimulationResult, SolverError, simulate
    from .interrupt import Interrupted

    outs = _outputs(a, [a.config], out=None, plot=FIGURE)
    cfg = _load_config(a)
    opts = {}
    if a.model == "contact" and a.initial:
        opts["initial"] = a.initial
    elif a.initial:
        from .errors import ConfigError

        raise ConfigError("--initial is for the contact model (--model contact)")
    progress = _progress_printer(a.duration) if a.duration else None
    try:
        res = simulate(cfg, model=a.model, duration=a.duration, rate=a.rate, method=a.method,
                       rtol=a.rtol, atol=a.atol, max_step=a.max_step, progress=progress,
                       max_steps=a.max_steps, **opts)
    except (SolverError, Interrupted) as e:
        part = e.partial
        if a.keep_partial and isinstance(part, SimulationResult) and part.time.size >= 2 and (a.out or a.plot):
            _write_simulation(outs, a, part, cfg)  # every requested file, complete, or none
            kept = " and ".join(x for x in (a.out, a.plot) if x)
            if isinstance(e, Interrupted):
                e.notes.append(f"the {part.time.size} samples computed before it are in {kept}")
            else:
                print(f"pumpsim: the samples computed before the failure are in {kept}", file=sys.stderr)
        raise
    _write_simulation(outs, a, res, cfg)
    print(res.summary())
    _warn(res.warnings)
    return 0


# --- identify -------------------------------------------------------------------------------

def register_identify(sub):
    ip = sub.add_parser("identify", help="fit friction (and phase, speed, offsets) to measured torque",
                        formatter_class=_Help,
                        description="Fit model parameters to a measured drive torque at constant speed.")
    ip.add_argument("config", help="TOML configuration (SI units)")
    ip.add_argument("data", help="CSV, MATLAB .mat or NI .tdms file")
    ip.add_argument("--params", default=None,
                    help="comma-separated: mu, mu_slot, theta0, speed, torque_offset, delay or any "
                         "numeric config key path (e.g. housing.center.0); default mu,theta0 -- for a "
                         "bench log (columns time, voltage, current, booster_pressure) "
                         f"{','.join(BENCH_DEFAULT_PARAMS)}")
    ip.add_argument("--method", default="gauss-newton", choices=["gauss-newton", "levenberg-marquardt", "ipopt"],
                    help="least-squares solver")
    ip.add_argument("--relaxation", type=float, default=1.0, help="Gauss-Newton relaxation factor f in (0, 1]")
    ip.add_argument("--start", action="append", metavar="NAME=VALUE", help="initial value of a fitted parameter")
    ip.add_argument("--max-iter", type=_positive_int, default=50, dest="max_iter", help="iteration limit")
    ip.add_argument("--transient", action="store_true",
                    help="the data is a run-up/coast-down: apply the measured torque, fit the measured "
                         "speed (parameters mu, mu_slot, speed0, theta0 or config paths)")
    _add_fit_outputs(ip)
    ip.set_defaults(func=cmd_identify)


BENCH_DEFAULT_PARAMS = ("mu", "booster.leak", "motor.resistance")


def cmd_identify(a) -> int:
    from .api import identify
    from .benchlog import is_bench_log

    outs = _outputs(a, [a.config, a.data], json=None, report=REPORT_SUFFIXES)
    cfg = _load_config(a)
    if is_bench_log(a.data, a.time_column, a.speed_column):
        from .identification.pumpdown_fit import cmd_identify_bench

        return cmd_identify_bench(a, cfg, outs, _parse_params(a.params or ",".join(BENCH_DEFAULT_PARAMS)),
                                  _parse_initial(a.start), _write_fit_outputs, _fit_log())
    params = _parse_params(a.params or "mu,theta0")
    initial = _parse_initial(a.start)
    data = _read_data(a, a.data, None if ("speed" in params or a.transient) else
                      (cfg.speed if cfg.mode == "speed" else None))
    if a.transient:
        from .identification import identify_transient

        res = identify_transient(cfg, data, params=params, initial=initial, max_iter=a.max_iter, method=a.method)
    else:
        if sys.stderr.isatty():
            print(f"pumpsim: fitting {', '.join(params)} to {data.n:,} samples of {data.name}", end="",
                  file=sys.stderr, flush=True)
        res = identify(cfg, data, params=params, method=a.method, relaxation=a.relaxation,
                       initial=initial, max_iter=a.max_iter, force=a.force, log=_fit_log())
        if sys.stderr.isatty():
            print(file=sys.stderr)
        _warn(w for w in res.warnings if w not in cfg.warnings)
    print(res)
    from .report.identification import identification_report

    _write_fit_outputs(outs, a, res.to_json(), lambda path: identification_report(
        res, path, title=f"pumpsim identification: {cfg.name}", cfg=cfg, data=data))
    problems = res.problems()
    if problems:
        print("pumpsim: the fit is not a usable estimate: " + "; ".join(problems), file=sys.stderr)
        return 1
    return 0


# --- diagnose -------------------------------------------------------------------------------

BUDGET_PER_5000 = 30.0  # s: the command's default time budget per 5,000 samples

def register_diagnose(sub):
    dg = sub.add_parser("diagnose", help="find, name and add the effect missing from the model",
                        formatter_class=_Help,
                        description="Discrepancy workflow: baseline fit, residual tests, effect library.")
    dg.add_argument("config", help="TOML configuration (SI units)")
    dg.add_argument("data", nargs="+", help="one or more measurements (several speeds separate "
                    "offset, viscous friction and COF)")
    dg.add_argument("--speed-tolerance", type=float, dest="speed_tolerance",
                    help="relative band about the configured speed inside which a measurement without a "
                         "speed column may refine it (default: operation.speed_tolerance, 0.02)")
    dg.add_argument("--budget", type=float, default=None, metavar="SECONDS",
                    help=f"wall time after which no further search step starts; what it cuts is reported "
                         f"(default: {BUDGET_PER_5000:g} s per 5,000 samples; 0: no limit)")
    _add_fit_outputs(dg)
    dg.set_defaults(func=cmd_diagnose)


def cmd_diagnose(a) -> int:
    from .api import diagnose
    from .diagnosis import tty_progress

    outs = _outputs(a, [a.config, *a.data], json=None, report=REPORT_SUFFIXES)
    cfg = _load_config(a)
    # several files: measurements of one pump at different speeds, fitted together
    data = [_read_data(a, d, cfg.speed if cfg.mode == "speed" else None) for d in a.data]
    if a.budget is not None and not a.budget >= 0:
        raise ConfigError(f"--budget must be >= 0 seconds (0: no limit), got {a.budget:g}")
    samples = sum(d.n for d in data)
    budget = BUDGET_PER_5000 * max(1.0, samples / 5000) if a.budget is None else (a.budget or None)
    out = diagnose(cfg, data, force=a.force, progress=tty_progress(), speed_tolerance=a.speed_tolerance,
                   budget=budget)
    if sys.stderr.isatty():
        print(file=sys.stderr)
    print(out)
    from .report.diagnosis import diagnosis_report

    _write_fit_outputs(outs, a, out.to_json(), lambda path: diagnosis_report(
        out, path, title=f"pumpsim diagnosis: {cfg.name}", cfg=cfg, data=data))
    return 0


# --- study ----------------------------------------------------------------------------------

def register_study(sub):
    st = sub.add_parser("study", help="contact-model solver study: tolerances, contact stiffness, integrators", formatter_class=_Help)
    st.add_argument("config", help="TOML configuration with [contact.housing]")
    st.add_argument("--revolutions", type=_positive_float, default=10.0, help="revolutions simulated per setting")
    st.add_argument("--speed", type=_positive_float, help="constant speed [rad/s] (default: the config's)")
    st.add_argument("--json", help="write the table as JSON")
    _add_force(st)
    st.set_defaults(func=cmd_study)


def cmd_study(a) -> int:
    from .errors import ConfigError
    from .study import HEADER, solver_study, write_json

    outs = _outputs(a, [a.config], json=None)
    cfg = _load_config(a)
    if not cfg.contact_given:
        raise ConfigError("the solver study needs [contact.housing] with a stiffness in the config")
    print(f"contact model solver study: {cfg.name}, constant speed, {a.revolutions:g} revolutions "
          "from an in-contact start; deviations from Model 2 over the last revolution")
    print(HEADER)
    result = solver_study(cfg, revolutions=a.revolutions, speed=a.speed, log=print)
    with _staged(outs) as tmp:
        if a.json:
            write_json(tmp["--json"], result)
    return 0


def register_design(sub):
    from .design.cli import add_design_commands  # sweep, sensitivity, optimize (spec §9)

    add_design_commands(sub)


def register_pumpdown(sub):
    from .pneumatics.cli import add_pumpdown_command  # pumpdown (spec §8)

    add_pumpdown_command(sub)


# --- kernels, example ----------------------------------------------------------------------

def register_kernels(sub):
    from .model_spec.manifest import GENERATED_ENV

    k = sub.add_parser("kernels", help="list, build or clear the compiled model kernels",
                       formatter_class=_Help,
                       description="Compiled kernels (one C library per model variant) are built on first "
                       "use into a checkout's generated/ or, for an installed package, the per-user cache "
                       f"(~/.cache/pumpsim/kernels on Linux); {GENERATED_ENV}=DIR moves them (e.g. to a "
                       "shared, prebuilt folder on a cluster).")
    ks = k.add_subparsers(dest="action", required=True, parser_class=_Parser)
    ks.add_parser("list", help="the kernels in the folder: variant, key, size, status, path")
    b = ks.add_parser("build", help="build (or check) the kernels that configs or studies need, "
                      "e.g. for a CI image or a cluster's shared folder", formatter_class=_Help)
    b.add_argument("files", nargs="+", metavar="FILE", help="TOML configs or studies")
    b.add_argument("--model", choices=["constrained", "contact"], action="append",
                   help="models of a config (repeatable; default: constrained)")
    c = ks.add_parser("clear", help="remove the kernels (they are rebuilt on use)")
    c.add_argument("--stale", action="store_true",
                   help="only those this installation does not load (another model source, CasADi or CPU)")
    k.set_defaults(func=cmd_kernels)


def _megabytes(n: int) -> str:
    return f"{n / 1e6:.1f} MB"


def cmd_kernels(a) -> int:
    from . import kernels
    from .model_spec.manifest import GENERATED_ENV, generated_dir

    if a.action == "build":
        from .variants import build_for

        build_for(a.files, a.model, log=lambda m: print(m, flush=True))
    elif a.action == "clear":
        gone = kernels.clear(stale_only=a.stale)
        print(f"removed {len(gone)} kernel folder(s), {_megabytes(sum(k['size'] for k in gone))}, "
              f"from {generated_dir()}")
    else:
        found = kernels.cached()
        print(f"kernel folder: {generated_dir()} (set {GENERATED_ENV} to move it)")
        if found:
            w = max(len(k["variant"]) for k in found)
            print(f"{'variant':<{w}}  {'key':<20}  {'size':>8}  {'status':<6}  path")
        for k in found:
            print(f"{k['variant']:<{w}}  {k['key']:<20}  {_megabytes(k['size']):>8}  "
                  f"{'ok' if k['usable'] else 'stale':<6}  {k['folder']}")
        print(f"{len(found)} kernel(s), {_megabytes(sum(k['size'] for k in found))}"
              + ("; stale: not recorded for this model source, CasADi or CPU (`pumpsim kernels clear --stale`)"
                 if any(not k["usable"] for k in found) else ""))
    return 0


def register_example(sub):
    e = sub.add_parser("example", help="copy a bundled example (config, measurements, studies) into a folder",
                       formatter_class=_Help,
                       description="Copy a bundled configuration, its simulated measurements (DIR/data/) and "
                       "its studies (DIR/studies/) into DIR; `pumpsim example test_rig examples` makes the "
                       "documentation's paths (examples/...) work.")
    e.add_argument("name", nargs="?", help="example name (see --list)")
    e.add_argument("dir", nargs="?", help="destination folder (created if missing)")
    e.add_argument("--list", action="store_true", help="list the bundled examples and their files")
    e.set_defaults(func=cmd_example)


def cmd_example(a) -> int:
    from . import bundled
    from .errors import ConfigError

    if a.list:
        for name in bundled.names():
            print(f"{name}: {bundled.description(name)}\n    {', '.join(bundled.files(name))}")
        return 0
    if not a.name or not a.dir:
        raise ConfigError("give an example NAME and a folder DIR (`pumpsim example test_rig examples`), "
                          "or --list")
    for path in bundled.copy_example(a.name, a.dir):
        print(path)
    return 0


# A command = its parser registration; each registration sets `func`. New commands append here.
COMMANDS = [register_simulate, register_identify, register_diagnose, register_study, register_design,
            register_pumpdown, register_kernels, register_example]


def build_parser():
    ap = _Parser(prog="pumpsim", description="Rotary vane vacuum pump simulation and identification. "
                 "Config values are SI (m, kg, s, rad, N); exit status 0 ok, 2 bad input, 1 numerical "
                 "failure or unusable fit.")
    from . import __version__

    ap.add_argument("--version", action="version", version=f"pumpsim {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for register in COMMANDS:
        register(sub)
    return ap


def main(argv=None) -> int:
    """Run the command line with `argv` (default sys.argv[1:]); returns the exit status."""
    from . import interrupt

    try:
        with interrupt.handling():  # from the start: building the parser imports much already
            return _main(argv)
    except KeyboardInterrupt as e:  # Interrupted, or SIGINT outside the handler's scope
        return _report_interrupt(e if isinstance(e, interrupt.Interrupted) else interrupt.Interrupted())


def _main(argv) -> int:
    ap = build_parser()
    try:
        a = ap.parse_args(argv)
    except SystemExit as e:  # --help, --version, bad options (status 2, message printed)
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
    from . import fsfaults, interrupt, locks

    try:
        with locks.session():
            status = a.func(a)
            if interrupt.pending():  # a signal some native code took for its own failure, then went on
                late = interrupt.Interrupted()
                late.notes.append("the run had ended: its outputs are written, complete")
                raise late
            return status
    except BrokenPipeError:  # the reader of our output went away (`| head`): stop quietly
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except Exception as e:
        if interrupt.pending():  # the failure is the signal's doing (a solver callback's, say)
            return _report_interrupt(interrupt.Interrupted())
        if isinstance(e, PumpsimError):
            print(f"pumpsim: error: {e}", file=sys.stderr)
            return e.exit_status
        if isinstance(e, OSError):  # a file-system fault no guard named: say what the OS said
            err = fsfaults.error(e)
            print(f"pumpsim: error: {err}", file=sys.stderr)
            return err.exit_status
        if isinstance(e, MemoryError):
            print("pumpsim: error: out of memory (shorten the data, --resample, or a shorter --duration)",
                  file=sys.stderr)
            return 1
        if os.environ.get("PUMPSIM_DEBUG"):  # a bug, not a user error: one line unless debugging
            raise
        print(f"pumpsim: internal error (please report; PUMPSIM_DEBUG=1 shows the traceback): "
              f"{type(e).__name__}: {e}", file=sys.stderr)
        return 1


def _report_interrupt(e) -> int:
    print(f"pumpsim: {e.message()}", file=sys.stderr)
    return e.exit_status

if __name__ == "__main__":
    sys.exit(main())
