"""`pumpsim diagnose CONFIG DATA...`: the discrepancy workflow (baseline fit, residual tests,
effect library)."""
from __future__ import annotations

import sys

from .common import Help, REPORT_SUFFIXES, add_fit_outputs, live, load_config, outputs, read_data, write_fit_outputs

BUDGET_PER_5000 = 30.0  # s: the command's default time budget per 5,000 samples


def register(sub):
    dg = sub.add_parser("diagnose", help="find, name and add the effect missing from the model",
                        formatter_class=Help,
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
    add_fit_outputs(dg)
    dg.set_defaults(func=run)


def run(a) -> int:
    from ..api import diagnose
    from ..diagnosis import tty_progress
    from ..errors import ConfigError

    outs = outputs(a, [a.config, *a.data], json=None, report=REPORT_SUFFIXES)
    cfg = load_config(a)
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
    return 0
