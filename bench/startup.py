"""Command start (issue 28: "any command's start to its first work <= 0.5 s, `python -X importtime`").

Each command runs on the bundled examples as `python -X importtime -m pumpsim -v COMMAND ...` in its
own process. Its first work is the first thing it does for the user after parsing its arguments:
reading and checking its config (or study file). The marker is the debug line `-v` already prints
once that is done ("pumpsim: config PATH: NAME", "pumpsim: study PATH: ..."); -X importtime writes
each import's line to stderr as the import ends, so the lines before the marker are the imports the
command made before its first work had finished: the command's start, plus what reading and checking
the config or study took (counted in, so the figure errs on the high side). A figure is the sum of the
cumulative column of the top-level lines (module name not indented: each import counted once with
everything it pulled in). Held against the target: the imports to first work, the least of five
runs (the first run goes to the end and gives the whole run's imports and wall time; the other four
are ended at the marker). The wall time from the process's start to the marker's arrival is printed
beside it (with -X importtime's own overhead, which the import sums leave out).
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STARTUP_TARGET_S = 0.5
MARKERS = ("pumpsim: config ", "pumpsim: study ")
EX = ROOT / "examples"
STUDY = EX / "studies" / "test_rig_tolerances.toml"


def commands(out: Path) -> dict:
    """The commands of the issue's list on the bundled examples; outputs into `out`."""
    return {
        "simulate": ["simulate", EX / "test_rig.toml", "--out", out / "s.csv"],
        "identify": ["identify", EX / "test_rig.toml", EX / "data" / "test_rig_measurement.csv", "--params", "mu",
                     "--json", out / "f.json"],
        "diagnose": ["diagnose", EX / "ellipse_4vanes.toml", EX / "data" / "ellipse_hidden_effects.csv",
                     "--json", out / "d.json"],
        "pumpdown": ["pumpdown", EX / "evp_booster.toml", "--json", out / "p.json"],
        "sweep": ["sweep", STUDY, "--samples", "256", "--out", out / "mc"],
        "sensitivity": ["sensitivity", STUDY, "--samples", "64", "--json", out / "se.json"],
        "optimize": ["optimize", EX / "studies" / "ellipse_optimize.toml", "--json", out / "op.json"],
    }


def top_level(line: str):
    """(module, cumulative seconds) of a top-level `-X importtime` line, else None."""
    if not line.startswith("import time:"):
        return None
    parts = line.rstrip("\n").split("|")
    if len(parts) != 3 or not parts[2].startswith(" ") or parts[2][1:2] in (" ", ""):
        return None
    try:
        return parts[2].strip(), int(parts[1]) / 1e6
    except ValueError:  # the header line
        return None


def run_once(args: list, to_the_end: bool) -> dict:
    """One process: the imports before the marker (and after it, when run to the end), the wall
    time to the marker's arrival and to the process's end."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, "-X", "importtime", "-m", "pumpsim", "-v", *map(str, args)], cwd=ROOT,
                         env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    before, after, marker, tail = [], [], None, []
    for line in p.stderr:
        if marker is None and line.startswith(MARKERS):
            marker = time.perf_counter() - t0
            if not to_the_end:
                p.kill()
                break
            continue
        imp = top_level(line)
        if imp:
            (before if marker is None else after).append(imp)
        elif not line.startswith("import time:"):
            tail = (tail + [line])[-20:]
    p.wait()
    wall = time.perf_counter() - t0
    p.stderr.close()
    if marker is None or (to_the_end and p.returncode not in (0, 1)):
        raise RuntimeError(f"pumpsim {' '.join(map(str, args))}: exit status {p.returncode}, "
                           f"marker {'seen' if marker else 'not seen'}:\n{''.join(tail)}")
    return {"before": before, "after": after, "to_marker": marker, "wall": wall, "status": p.returncode}


def measure(repeats: int = 5) -> dict:
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeats):
            for name, args in commands(Path(tmp) / str(i)).items():
                (Path(tmp) / str(i)).mkdir(exist_ok=True)
                r = run_once(args, to_the_end=i == 0)
                first = sum(s for _, s in r["before"])
                row = rows.setdefault(name, {"runs_to_first_work": []})
                row["runs_to_first_work"].append(first)
                if i == 0:
                    row.update(status=r["status"], all_imports_s=first + sum(s for _, s in r["after"]),
                               process_wall_s=r["wall"], wall_to_first_work_s=r["to_marker"])
                row["wall_to_first_work_s"] = min(row["wall_to_first_work_s"], r["to_marker"])
                if first == min(row["runs_to_first_work"]):  # the heaviest imports of the least run
                    heavy = sorted(r["before"], key=lambda m: -m[1])[:3]
                    row["heaviest_before"] = [[m, round(s, 4)] for m, s in heavy]
    for row in rows.values():
        row["imports_to_first_work_s"] = min(row["runs_to_first_work"])
        row["target_met"] = row["imports_to_first_work_s"] <= STARTUP_TARGET_S
    return rows


def bench_startup(repeats: int = 5) -> dict:
    """Each command's imports to its first work (least of `repeats` runs) against 0.5 s, its
    whole run's imports and its process wall time (module docstring: what "first work" is)."""
    load = os.getloadavg()[0]
    rows = measure(repeats)
    print(f"\nCommand start on the bundled examples (python -X importtime, load average {load:.1f}; "
          f"imports to first work: least of {repeats} runs)")
    print(f"{'command':<12}{'to first work':>14}{'wall to it':>11}{'all imports':>12}{'process wall':>13}"
          f"  heaviest imports before first work")
    for name, r in rows.items():
        heavy = ", ".join(f"{m} {s:.2f}" for m, s in r["heaviest_before"])
        print(f"{name:<12}{r['imports_to_first_work_s']:>13.3f}s{r['wall_to_first_work_s']:>10.3f}s"
              f"{r['all_imports_s']:>11.3f}s{r['process_wall_s']:>12.2f}s  {heavy}")
    worst = max(rows, key=lambda n: rows[n]["imports_to_first_work_s"])
    met = all(r["target_met"] for r in rows.values())
    print(f"slowest start: {worst} {rows[worst]['imports_to_first_work_s']:.3f} s of imports to first work "
          f"(target <= {STARTUP_TARGET_S:g} s for every command: {'met' if met else 'MISSED'})")
    return {"load_average": load, "repeats": repeats, "target_seconds": STARTUP_TARGET_S, "target_met": met,
            "commands": rows}


if __name__ == "__main__":
    import json

    print(json.dumps(bench_startup(), indent=1))
