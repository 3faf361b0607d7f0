"""Command line (spec §7). Exit status: 0 success, 2 bad input, 1 numerical failure."""
from __future__ import annotations

import argparse
import sys

from .errors import PumpsimError


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
    from . import load_config, simulate

    cfg = load_config(a.config)
    opts = {}
    if a.model == "contact" and a.initial:
        opts["initial"] = a.initial
    duration = a.duration
    progress = _progress_printer(duration) if duration else None
    res = simulate(cfg, model=a.model, duration=duration, rate=a.rate, method=a.method,
                   rtol=a.rtol, atol=a.atol, max_step=a.max_step, progress=progress, **opts)
    if a.out:
        res.to_csv(a.out)
    if a.plot:
        res.plot(a.plot)
    print(res.summary())
    for w in res.warnings:
        print(f"pumpsim: warning: {w}", file=sys.stderr)
    return 0


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
    s.add_argument("--method", choices=["cvodes", "idas", "rk"], default="cvodes",
                   help="integrator for torque drive / the contact model")
    s.add_argument("--rtol", type=float, default=1e-8)
    s.add_argument("--atol", type=float, default=1e-10)
    s.add_argument("--max-step", type=float, dest="max_step")
    s.add_argument("--initial", choices=["bottom", "rotor", "housing"],
                   help="contact model: initial vane state (default rotor)")
    s.set_defaults(func=cmd_simulate)
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
