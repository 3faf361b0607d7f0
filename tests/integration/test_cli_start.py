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


# Each command on the bundled examples up to its first work (bench/startup.py's commands: its
# config or study read and checked, which -v says in one line); the process is ended there.
BEFORE_WORK_HEAVY = ("matplotlib", "scipy.stats", "scipy.optimize", "pandas", "dask", "distributed", "SALib", "pymoo")


def _startup():
    sys.path.insert(0, str(ROOT / "bench"))
    import startup

    return startup


def test_no_command_imports_the_heavy_stack_before_its_first_work(tmp_path):
    """The commands start side by side; each is read up to its first-work line and ended."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    procs = {name: subprocess.Popen([sys.executable, "-X", "importtime", "-m", "pumpsim", "-v", *map(str, args)],
                                    cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
             for name, args in _startup().commands(tmp_path).items()}
    heavy, unmarked = {}, []
    for name, p in procs.items():
        modules, marked = set(), False
        try:
            for line in p.stderr:
                if line.startswith(_startup().MARKERS):
                    marked = True
                    break
                if line.startswith("import time:") and line.count("|") == 2:
                    modules.add(line.rsplit("|", 1)[1].strip())
        finally:
            p.kill()
            p.wait()
            p.stderr.close()
        assert "pumpsim" in modules, name  # the importtime lines were read
        if not marked:
            unmarked.append(name)
        found = [h for h in BEFORE_WORK_HEAVY if any(m == h or m.startswith(h + ".") for m in modules)]
        if found:
            heavy[name] = found
    assert unmarked == [], f"no first-work line from {unmarked} (pumpsim -v prints 'config PATH: NAME' / 'study ...')"
    assert heavy == {}, f"imported before the command's first work: {heavy}"


def test_a_command_runs_its_blas_on_one_thread_unless_the_user_said_otherwise():
    """The command's small solves on one BLAS thread (no spinning second thread on a busy machine):
    the counts are set before NumPy loads its BLAS, and a count the user set is kept."""
    from pumpsim.blas import BLAS_THREADS, one_blas_thread
    env = {"MKL_NUM_THREADS": "4"}
    one_blas_thread(env)
    assert env == {**{n: "1" for n in BLAS_THREADS}, "MKL_NUM_THREADS": "4"}
    probe = ("import os, sys; from pumpsim.cli.app import main; import pumpsim.cli.app as a; "
             "a._main = lambda argv: print('numpy' in sys.modules, os.environ['OPENBLAS_NUM_THREADS']) or 0; "
             "main([])")
    for given, seen in ((None, "1"), ("2", "2")):
        env = {k: v for k, v in os.environ.items() if k not in BLAS_THREADS}
        env["PYTHONPATH"] = str(ROOT)
        if given:
            env["OPENBLAS_NUM_THREADS"] = given
        r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=ROOT, env=env)
        assert r.stdout.split() == ["False", seen], r.stderr[-2000:]  # set, and NumPy not loaded yet
