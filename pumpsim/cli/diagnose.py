"""`pumpsim diagnose CONFIG DATA...`: the discrepancy workflow (baseline fit, residual tests,
effect library)."""
from __future__ import annotations

import sys
from pathlib import Path

from .common import Help, REPORT_SUFFIXES, add_fit_outputs, data_options, in_range, live, load_config, outputs, read_bench, \
    read_data, refuse_bench_only, refuse_torque_only, write_fit_outputs
from .identify import unusable

BUDGET_PER_5000 = 30.0  # s: the command's default time budget per 5,000 samples


def register(sub):
    dg = sub.add_parser("diagnose", help="find, name and add the effect missing from the model",
                        formatter_class=Help,
                        description="Discrepancy workflow: baseline fit, residual tests, effect library.")
    dg.add_argument("config", help="TOML configuration (SI units)")
    dg.add_argument("data", nargs="+", help="one or more measurements (several speeds separate "
                    "offset, viscous friction and COF)")
    dg.add_argument("--speed-tolerance", type=in_range(0.0, 0.5, low_open=False), dest="speed_tolerance",
                    help="relative band about the configured speed inside which a measurement without a "
                         "speed column may refine it (default: operation.speed_tolerance, 0.02)")
    dg.add_argument("--budget", type=float, default=None, metavar="SECONDS",
                    help=f"wall time after which no further search step starts; what it cuts is reported "
                         f"(default: {BUDGET_PER_5000:g} s per 5,000 samples; 0: no limit)")
    dg.add_argument("--resistance-known", action="store_true", dest="resistance_known",
                    help="bench log: the config's motor.resistance is measured (a stalled-rotor test at the "
                         "motor terminals), so a supply resistance is told from a winding-resistance error")
    dg.add_argument("--atmosphere-known", action="store_true", dest="atmosphere_known",
                    help="bench log: it starts with the booster vented and the config's gas.atmosphere (the "
                         "booster's start) is the day's barometer reading, so a pressure sensor's offset and "
                         "span are told from the pump's effects")
    add_fit_outputs(dg)
    dg.set_defaults(func=run)


def _refuse_repeated(paths) -> None:
    """Several files are several measurements: one file given twice would count its samples twice
    (intervals too narrow by sqrt 2)."""
    import hashlib

    from ..errors import ConfigError

    seen = {}
    for p in paths:
        try:
            key = hashlib.sha256(Path(p).read_bytes()).hexdigest()
        except OSError:
            continue  # the reader names a missing or unreadable file
        if key in seen:
            raise ConfigError(f"'{p}' holds the same measurement as '{seen[key]}' (identical content): "
                              "give each record once")
        seen[key] = p


def run(a) -> int:
    from ..errors import ConfigError

    outs = outputs(a, [a.config, *a.data], json=None, report=REPORT_SUFFIXES)
    _refuse_repeated(a.data)
    cfg = load_config(a)
    from ..api import diagnose  # (after the config: a command's first work waits for no model import)
    from ..benchlog import is_bench_log
    from ..diagnosis import tty_progress

    if any(is_bench_log(d, data_options(a)) for d in a.data):
        return run_bench(a, cfg, outs)
    refuse_bench_only(a, a.data[0])
    for flag, given in (("--resistance-known", a.resistance_known), ("--atmosphere-known", a.atmosphere_known)):
        if given:
            raise ConfigError(f"{flag} is for a bench log (columns time, voltage, current, booster_pressure)")
    # several files: measurements of one pump at different speeds, fitted together
    data = [read_data(a, d, cfg.speed if cfg.mode == "speed" else None) for d in a.data]
    if a.budget is not None and not a.budget >= 0:
        raise ConfigError(f"--budget must be >= 0 seconds (0: no limit), got {a.budget:g}")
    samples = sum(d.n for d in data)
    budget = BUDGET_PER_5000 * max(1.0, samples / 5000) if a.budget is None else (a.budget or None)
    out = diagnose(cfg, data, force=a.force, progress=tty_progress() if live() else None, speed_tolerance=a.speed_tolerance,
                   budget=budget)
    if live():
        print(file=sys.stderr)
    print(out)

    def report(path):
        from ..report.diagnosis import diagnosis_report

        diagnosis_report(out, path, title=f"pumpsim diagnosis: {cfg.name}", cfg=cfg, data=data)

    write_fit_outputs(outs, a, out.to_json(), report)
    # a verdict on a fit that did not converge, or another pump: exit 1, as identify on this data
    # (a baseline that missed its own orders but whose one named effect accounts for them is no other pump)
    base = out.history[0].result.adequacy
    other_pump = base is not None and base.orders_missed() and not out.steps
    return unusable(out.unconverged() + ([base.reason] if other_pump else []))


def run_bench(a, cfg, outs) -> int:
    """diagnose on a bench log (the command recognised its columns): the pump-level library."""
    from ..diagnosis import tty_progress
    from ..diagnosis.pump_workflow import diagnose_bench
    from ..errors import ConfigError

    if len(a.data) > 1:
        raise ConfigError("a bench log is diagnosed on its own: give one log file")
    refuse_torque_only({"--steady": a.steady, "--resample": a.resample,
                        "--speed-tolerance": a.speed_tolerance is not None}, "diagnosed")
    if a.budget is not None and not a.budget >= 0:
        raise ConfigError(f"--budget must be >= 0 seconds (0: no limit), got {a.budget:g}")
    log = read_bench(a, a.data[0], cfg)
    out = diagnose_bench(cfg, log, resistance_known=a.resistance_known, atmosphere_known=a.atmosphere_known,
                         progress=tty_progress() if live() else None, budget=a.budget or None)
    if live():
        print(file=sys.stderr)
    print(out)

    def report(path):
        from ..report.bench_diagnosis import bench_diagnosis_report

        bench_diagnosis_report(out, path, cfg=cfg, log=log)

    write_fit_outputs(outs, a, out.to_json(), report)
    return unusable(out.unconverged())  # a verdict on a fit that did not converge: exit 1, as identify
