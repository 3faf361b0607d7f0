"""`pumpsim identify CONFIG DATA`: fit parameters to a measured torque, a run-up/coast-down, or a
bench log (voltage, current, booster pressure)."""
from __future__ import annotations

import sys

from .common import Help, REPORT_SUFFIXES, add_fit_outputs, data_options, fit_log, in_range, live, load_config, outputs, \
    positive_int, read_bench, read_data, refuse_bench_only, refuse_torque_only, warn, write_fit_outputs

BENCH_DEFAULT_PARAMS = ("mu", "booster.leak", "motor.resistance")


def register(sub):
    ip = sub.add_parser("identify", help="fit friction (and phase, speed, offsets) to measured torque",
                        formatter_class=Help,
                        description="Fit model parameters to a measured drive torque at constant speed.")
    ip.add_argument("config", help="TOML configuration (SI units)")
    ip.add_argument("data", help="CSV (or other delimited text), MATLAB .mat, NI .tdms or Apache Parquet (.parquet) file")
    ip.add_argument("--params", default=None,
                    help="comma-separated: mu, mu_slot, theta0, speed, torque_offset, delay or any "
                         "numeric config key path (e.g. housing.center.0); default mu,theta0 -- for a "
                         "bench log (columns time, voltage, current, booster_pressure) "
                         f"{','.join(BENCH_DEFAULT_PARAMS)}")
    ip.add_argument("--method", default="gauss-newton", choices=["gauss-newton", "levenberg-marquardt", "ipopt"],
                    help="least-squares solver")
    ip.add_argument("--relaxation", type=in_range(0.0, 1.0), default=1.0, help="Gauss-Newton relaxation factor f in (0, 1]")
    ip.add_argument("--start", action="append", metavar="NAME=VALUE", help="initial value of a fitted parameter")
    ip.add_argument("--max-iter", type=positive_int, default=50, dest="max_iter", help="iteration limit")
    ip.add_argument("--transient", action="store_true",
                    help="the data is a run-up/coast-down: apply the measured torque, fit the measured "
                         "speed (parameters mu, mu_slot, speed0, theta0 or config paths)")
    ip.add_argument("--limits", metavar="FILE.toml",
                    help="bench log: specification limits of the fitted parameters, [limits.NAME] tables with "
                         "lower and/or upper in SI (e.g. [limits.\"booster.leak\"] upper = 5e-5); each "
                         "estimate is reported in or out of specification")
    add_fit_outputs(ip)
    ip.set_defaults(func=run)


def parse_params(text):
    from ..errors import ConfigError

    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise ConfigError("--params names no parameter")
    return names


def parse_initial(items, params=None):
    """--start NAME=VALUE items as {name: value}; every name one of params (the fitted ones)."""
    from ..errors import ConfigError

    out = {}
    for item in items or []:
        name, sep, val = item.partition("=")
        name = name.strip()
        try:
            value = float(val)
        except ValueError:
            raise ConfigError(f"--start takes NAME=VALUE, got '{item}'") from None
        if not sep or not name:
            raise ConfigError(f"--start takes NAME=VALUE, got '{item}'")
        if value != value or abs(value) == float("inf"):
            raise ConfigError(f"--start {name} must be a finite number, got '{val}'")
        if params is not None and name not in params:
            raise ConfigError(f"--start {name}: not a fitted parameter (fitted: {', '.join(params)}); "
                              "start only what --params fits")
        out[name] = value
    return out


def unusable(problems) -> int:
    """Exit status of a finished fit: 1 with the problems named when it must not be used as is."""
    if problems:
        print("pumpsim: the fit is not a usable estimate: " + "; ".join(problems), file=sys.stderr)
        return 1
    return 0


def run(a) -> int:
    outs = outputs(a, [a.config, a.data] + ([a.limits] if a.limits else []), json=None, report=REPORT_SUFFIXES)
    cfg = load_config(a)
    from ..benchlog import is_bench_log  # (after the config: a command's first work waits for no model import)

    if is_bench_log(a.data, data_options(a)):
        return run_bench(a, cfg, outs)
    refuse_bench_only(a, a.data)
    if a.limits:
        from ..errors import ConfigError

        raise ConfigError("--limits checks the figures identified from a bench log; drop --limits for torque data")
    params = parse_params(a.params or "mu,theta0")
    initial = parse_initial(a.start, params)
    data = read_data(a, a.data, None if ("speed" in params or a.transient) else
                     (cfg.speed if cfg.mode == "speed" else None))
    if a.transient:
        from ..identification import identify_transient

        res = identify_transient(cfg, data, params=params, initial=initial, max_iter=a.max_iter, method=a.method)
    else:
        from ..api import identify

        if live():
            print(f"pumpsim: fitting {', '.join(params)} to {data.n:,} samples of {data.name}", end="",
                  file=sys.stderr, flush=True)
        res = identify(cfg, data, params=params, method=a.method, relaxation=a.relaxation,
                       initial=initial, max_iter=a.max_iter, force=a.force, log=fit_log())
        if live():
            print(file=sys.stderr)
        warn(w for w in res.warnings if w not in cfg.warnings)
    print(res)

    def report(path):
        from ..report.identification import identification_report

        identification_report(res, path, title=f"pumpsim identification: {cfg.name}", cfg=cfg, data=data)

    write_fit_outputs(outs, a, res.to_json(), report)
    return unusable(res.problems())


def run_bench(a, cfg, outs) -> int:
    """identify on a bench log (the command recognised its columns): fitted as logged."""
    from ..identification.pumpdown_fit import fitting, identify_bench
    from ..limits import read_limits

    params = parse_params(a.params or ",".join(BENCH_DEFAULT_PARAMS))
    initial = parse_initial(a.start, params)
    refuse_torque_only({"--transient": a.transient, "--steady": a.steady, "--resample": a.resample}, "fitted")
    limits = read_limits(a.limits, params) if a.limits else {}
    log = read_bench(a, a.data, cfg)
    shown = live()
    with fitting(params):
        fit = identify_bench(cfg, log, params, a.method, initial, a.max_iter, a.relaxation,
                             _bench_progress if shown else None)
    if shown:
        print(file=sys.stderr)
    print(fit)
    write_bench_outputs(a, outs, cfg, log, fit, limits)
    return unusable(fit.problems())


def write_bench_outputs(a, outs, cfg, log, fit, limits) -> None:
    """The figures against the limits on the terminal and in the JSON; --json and --report."""
    from ..limits import statuses, to_json as limits_json

    document = fit.to_json()
    if limits:
        states = statuses(fit.result.estimates, limits, usable=not fit.problems())
        print("  specification: " + "; ".join(f"{n} {s}" for n, s in states.items()))
        document["limits"] = limits_json(limits, states)

    def report(path):
        from ..presentation import provenance
        from ..report.benchlog import bench_log_report

        rows = provenance(cfg, log, kernel_key=fit.result.provenance.get("kernel_key"),
                          files=[("limits file", a.limits)] if a.limits else ())
        bench_log_report(fit, path, cfg=cfg, log=log, limits=limits, provenance_rows=rows)

    write_fit_outputs(outs, a, document, report)


def _bench_progress(entry):
    print(f"\r\033[Kpumpsim: residual RMS {entry['rms']:.6g} noise sigmas", end="", file=sys.stderr, flush=True)
