"""A command starts without the numerical stack it does not use: `pumpsim --version`, `--help`
and a bad option import neither SciPy's statistics, Matplotlib, Dask, CasADi nor pandas, and a
command loads the report module (and Matplotlib) only when a report is asked for. Behavioural:
the modules a real `python -m pumpsim` process imported (from `-X importtime`), not a timing."""
import os
import subprocess
import sys

import pytest

from tests.conftest import ROOT

HEAVY = ("matplotlib", "scipy.stats", "dask", "distributed", "casadi", "pandas")


def _imported(*args):
    """(exit status, stdout, the modules the process imported) of `python -m pumpsim ARGS`."""
    r = subprocess.run([sys.executable, "-X", "importtime", "-m", "pumpsim", *map(str, args)],
                       capture_output=True, text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    modules = {line.rsplit("|", 1)[1].strip() for line in r.stderr.splitlines()
               if line.startswith("import time:") and line.count("|") == 2}
    assert "pumpsim" in modules, r.stderr[-2000:]  # the importtime lines were read
    return r.returncode, r.stdout, modules


def _heavy(modules):
    return sorted(m for m in modules if any(m == h or m.startswith(h + ".") for h in HEAVY))


@pytest.mark.parametrize("args, status", [(["--version"], 0), (["--help"], 0), (["identify", "--help"], 0),
                                          (["sweep", "--help"], 0), (["simulate"], 2),
                                          (["identify", "a.toml", "b.csv", "--max-iter", "0"], 2)])
def test_start_imports_no_numerical_stack(args, status):
    code, out, modules = _imported(*args)
    assert code == status
    assert _heavy(modules) == [], f"pumpsim {' '.join(args)} imported {_heavy(modules)}"
    assert "numpy" not in modules
    if args == ["--version"]:
        assert out.startswith("pumpsim ")


def test_report_module_only_with_report(tmp_path):
    cfg, data = ROOT / "examples" / "test_rig.toml", ROOT / "examples" / "data" / "test_rig_measurement.csv"
    code, out, modules = _imported("identify", cfg, data, "--params", "mu", "--json", tmp_path / "fit.json")
    assert code == 0 and (tmp_path / "fit.json").is_file()
    assert "pumpsim.report" not in modules and not [m for m in modules if m.startswith("matplotlib")]
    assert not [m for m in modules if m.startswith("dask")]  # (scipy.stats it needs: the t intervals)
    code, out, modules = _imported("identify", cfg, data, "--params", "mu", "--report", tmp_path / "fit.html")
    assert code == 0 and (tmp_path / "fit.html").is_file()
    assert "pumpsim.report" in modules and "matplotlib" in modules


def test_a_sweep_loads_the_report_module_only_with_report(tmp_path):
    study = ROOT / "examples" / "studies" / "test_rig_tolerances.toml"
    code, out, modules = _imported("sweep", study, "--samples", "16", "--csv", tmp_path / "mc.csv")
    assert code == 0 and (tmp_path / "mc.csv").is_file()
    assert "pumpsim.report" not in modules and not [m for m in modules if m.startswith("matplotlib")]
