"""Fault injection (marker `faults`): signals at random points of each command, two runs on one
output, read-only and full file systems, a Dask worker killed mid-study.

Each test asserts the exit status (130 SIGINT, 143 SIGTERM, 2 a fault the user can fix), the
one-line message, and that no partial or mixed file is left: every output is absent or complete
(it parses), no temporary beside it, a study folder holds each design exactly once.

Commands run as subprocesses (a real signal, a real second process); delays come from a seeded
RNG, so a failing case repeats. A size-limited or read-only tmpfs is mounted where the machine
allows it (root); otherwise a full disk is simulated and a read-only folder is chmod 555. The
long and random ones are also `slow` (make test-all).
"""
import contextlib
import errno
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pumpsim.cli import main
from pumpsim.errors import OutputError
from tests.conftest import EXAMPLES

pytestmark = pytest.mark.faults

ROOT = Path(__file__).resolve().parents[2]
RIG = EXAMPLES / "test_rig.toml"
ELLIPSE = EXAMPLES / "ellipse_4vanes.toml"
EVP = EXAMPLES / "evp_booster.toml"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
INTERRUPTED = re.compile(r"^pumpsim: interrupted by (SIGINT|SIGTERM)( at simulated t = (\S+) s of (\S+) s"
                         r"[^;]*| with (\d+) of (\d+) designs done| in a fit of [^;]*"
                         r"| while the local Dask cluster started \(no design done\))?; (.+)$")


def _env():
    return dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")


def start(args, cwd):
    """The command in its own process group (as a terminal runs it)."""
    return subprocess.Popen([sys.executable, "-m", "pumpsim", *map(str, args)], cwd=cwd, env=_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def warm(args):
    """Run a short form of the command to its end first, so that kernels and the integrator
    driver a fresh checkout builds (in a compiler process, whose CPU `worked` does not see) are
    built before the timed run is signalled."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        subprocess.run([sys.executable, "-m", "pumpsim", *map(str, args)], cwd=d, env=_env(),
                       capture_output=True, check=True, timeout=900)


def signal_after(p, delay, sig, timeout=180, group=False):
    """Send `sig` after `delay` s (unless the run ended) to the process, or with group=True to its
    whole process group as a terminal's Ctrl-C does (Dask's workers too); (status, stdout, stderr)."""
    try:
        out, err = p.communicate(timeout=delay)
        return p.returncode, out, err
    except subprocess.TimeoutExpired:
        pass
    if group:
        os.killpg(p.pid, sig)
    else:
        p.send_signal(sig)
    out, err = p.communicate(timeout=timeout)
    return p.returncode, out, err


def wait_for(predicate, p, timeout=120):
    t0 = time.monotonic()
    while not predicate():
        assert p.poll() is None, p.communicate()
        assert time.monotonic() - t0 < timeout, "timed out"
        time.sleep(0.05)


def worked(p, cpu_seconds):
    """Wait until the run has used `cpu_seconds` of CPU: past its imports and kernel loading on
    a loaded machine too, where wall-clock delays say little."""
    import psutil

    proc = psutil.Process(p.pid)

    def cpu():
        t = proc.cpu_times()
        return t.user + t.system

    wait_for(lambda: cpu() >= cpu_seconds, p)


def the_message(err, sig):
    """stderr holds exactly one line, the interruption's, besides the kernel cache's own messages
    (a checkout whose kernels were built for other model sources rebuilds or re-records them);
    returns its match."""
    cache = ("pumpsim: building the ", "pumpsim: compiling ", "pumpsim: built ")
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith(cache)
             and "the model source changed, the generated code did not" not in ln]
    assert len(lines) == 1, err
    m = INTERRUPTED.match(lines[0])
    assert m and m[1] == signal.Signals(sig).name, err
    return m


def written_in(kept) -> set:
    """The outputs an interruption's message names as written and complete."""
    m = re.search(r"(?:^|; )([^;]*) written and complete", kept)
    return set(m[1].split(", ")) if m else set()


def temporaries(folder):
    return [p.name for p in Path(folder).rglob(".*") if ".tmp" in p.name or "probe" in p.name]


def assert_complete_or_absent(paths):
    """Every output parses in full, or does not exist."""
    for path in map(Path, paths):
        if not path.exists():
            continue
        data = path.read_bytes()
        assert data, f"{path} is empty"
        if path.suffix == ".png":
            assert data.startswith(PNG_MAGIC) and data.rstrip().endswith(b"IEND\xaeB`\x82"), path
        elif path.suffix == ".json":
            json.loads(data)
        elif path.suffix == ".csv":
            pd.read_csv(path)
        elif path.suffix == ".html":
            assert data.rstrip().endswith(b"</html>"), path


def rng(name):
    """One seeded RNG per test: a failing delay repeats."""
    return np.random.default_rng(zlib.crc32(name.encode()))


# --- a signal inside the integrators' callbacks -----------------------------------------------

def test_contact_simulate_sigint_keeps_complete_partial_files(tmp_path):
    """Ctrl-C inside CVODES (contact model) is an interruption, not CV_RHSFUNC_FAIL; with
    --keep-partial the CSV and the figure hold the samples so far, both complete."""
    out, png = tmp_path / "c.csv", tmp_path / "c.png"
    warm(["simulate", ELLIPSE, "--model", "contact", "--duration", "0.001", "-q"])
    p = start(["simulate", ELLIPSE, "--model", "contact", "--duration", "20", "--out", out, "--plot", png,
               "--keep-partial"], tmp_path)
    worked(p, 2.5)  # ~1.6 s of CPU to the first integrator call
    code, _, err = signal_after(p, rng("contact").uniform(0.2, 1.0), signal.SIGINT)
    assert code == 130, err
    m = the_message(err, signal.SIGINT)
    assert m[4] == "20" and "CV_RHSFUNC_FAIL" not in err and "Traceback" not in err
    kept = re.search(r"the (\d+) samples computed before it are in (\S+) and (\S+)$", m[7])
    assert kept, err
    df = pd.read_csv(out)
    assert len(df) == int(kept[1]) >= 2 and df.iloc[-1, 0] == pytest.approx(float(m[3]), rel=1e-6)
    assert_complete_or_absent([out, png])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.csv", "c.png"]


def test_pumpdown_sigterm_is_143_and_writes_nothing(tmp_path):
    """SIGTERM in the gas model's integration: not 'the gas model's integration failed'."""
    outs = [tmp_path / "p.csv", tmp_path / "p.json"]
    warm(["pumpdown", EVP, "--duration", "0.001", "-q"])
    # a target below the pump's ultimate pressure (~7.7 kPa): the run goes on for the whole default
    # duration (~120 s simulated), still integrating when the signal comes
    p = start(["pumpdown", EVP, "--until", "1000", "--out", outs[0], "--json", outs[1]], tmp_path)
    worked(p, 2.5)
    code, _, err = signal_after(p, rng("pumpdown").uniform(0.2, 1.0), signal.SIGTERM)
    assert code == 143, err
    m = the_message(err, signal.SIGTERM)
    assert m[2] and "booster" in m[2] and m[7] == "no output file written", err
    assert list(tmp_path.iterdir()) == []


def sweep_study(folder, samples=300, batch=10):
    st = folder / "st.toml"
    st.write_text(f'[study]\nconfig = "{RIG}"\nsampler = "random"\nsamples = {samples}\nseed = 3\n'
                  f'batch_size = {batch}\n[vary."vane.mass"]\ndistribution = "normal"\nsd = 0.05\n'
                  'relative = true\n')
    return st


def designs_in(folder):
    from pumpsim.design.store import read_results

    return read_results(folder)["design"].to_numpy()


def test_sweep_ctrl_c_mid_study_keeps_whole_parts(tmp_path):
    """Ctrl-C (SIGINT to the process group: the Dask workers get it too) mid-study: 130, one line
    (no worker tracebacks), the designs done are named and kept as whole parts, the summary says
    which are missing; nothing else written."""
    st, res, csv = sweep_study(tmp_path), tmp_path / "res", tmp_path / "t.csv"
    p = start(["sweep", st, "--out", res, "--csv", csv, "--workers", "1"], tmp_path)
    wait_for(lambda: any(res.glob("part-*.parquet")), p)
    code, _, err = signal_after(p, rng("sweep").uniform(0.0, 0.5), signal.SIGINT, group=True)
    assert code == 130, err
    m = the_message(err, signal.SIGINT)
    done = int(m[5])
    assert int(m[6]) == 300 and (done == 0 or f"the {done} designs done are kept in '{res}'" in m[7]), err
    ids = designs_in(res)
    assert len(ids) == done and len(set(ids)) == done  # every part whole, each design once
    assert not csv.exists() and temporaries(tmp_path) == []
    if done < 300:
        code = main(["sweep", str(st), "--out", str(res), "--summary"])
        assert code == 0


# --- two runs on one output ------------------------------------------------------------------

@contextlib.contextmanager
def held_elsewhere(kind, path):
    """Another process holds `path` (a study folder or an output file) until the block ends."""
    take = (f"locks.study_folder({str(path)!r})" if kind == "folder" else f"locks.file_lock({str(path)!r}, '--out')")
    p = subprocess.Popen([sys.executable, "-c", f"import sys\nfrom pumpsim import locks\nwith {take}:\n"
                          "    print('held', flush=True)\n    sys.stdin.read()"],
                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=_env())
    try:
        assert p.stdout.readline().strip() == "held"
        yield p.pid
    finally:
        p.stdin.close()
        p.wait(timeout=30)


def test_second_run_on_a_held_output_exits_2_naming_the_first(tmp_path, capsys):
    st, res = sweep_study(tmp_path, samples=6), tmp_path / "res"
    with held_elsewhere("folder", res) as pid:
        t0 = time.perf_counter()
        assert main(["sweep", str(st), "--out", str(res), "--workers", "1"]) == 2
        err = capsys.readouterr().err
        assert time.perf_counter() - t0 < 5  # refused before the cluster starts
        assert f"--out '{res}' is being written by another pumpsim run (pid {pid} on host" in err
        assert f"kill {pid}" in err and not list(res.glob("part-*"))
    out = tmp_path / "o.csv"
    with held_elsewhere("file", out) as pid:
        assert main(["simulate", str(RIG), "--duration", "0.002", "--out", str(out)]) == 2
        assert f"--out '{out}' is being written by another pumpsim run (pid {pid}" in capsys.readouterr().err
        assert not out.exists()
    # the lock is free again: the run proceeds
    assert main(["simulate", str(RIG), "--duration", "0.002", "--out", str(out)]) == 0
    assert_complete_or_absent([out])


def test_two_concurrent_sweeps_on_one_folder(tmp_path):
    """The second exits 2 naming the first; the first completes with each design once."""
    st, res = sweep_study(tmp_path, samples=60), tmp_path / "res"
    first = start(["sweep", st, "--out", res, "--workers", "1"], tmp_path)
    wait_for(lambda: (res / ".pumpsim.lock.info").exists(), first)
    second = start(["sweep", st, "--out", res, "--workers", "1"], tmp_path)
    _, err2 = second.communicate(timeout=60)
    out1, err1 = first.communicate(timeout=180)
    code1, code2 = first.returncode, second.returncode
    assert code2 == 2 and f"(pid {first.pid} on host" in err2, err2
    assert code1 == 0, err1
    assert "status complete" in out1 and "60 designs, 60 rows" in out1
    assert sorted(designs_in(res)) == list(range(60))


def test_summary_names_gaps_and_duplicates_and_resume_keeps_the_layout(tmp_path, capsys):
    from pumpsim import design

    st = tmp_path / "i.toml"
    st.write_text('[study]\nfunction = "ishigami"\nsampler = "random"\nsamples = 40\nseed = 2\nbatch_size = 8\n'
                  + "".join(f'[vary.{k}]\ndistribution = "uniform"\nlow = -3.14\nhigh = 3.14\n' for k in ("x1", "x2", "x3")))
    res = tmp_path / "res"
    study = design.load_study(st)
    design.sweep(study, out=res, workers=0)
    assert main(["sweep", str(st), "--out", str(res), "--summary"]) == 0
    assert "status complete" in capsys.readouterr().out
    shutil.copy(res / "part-00001.parquet", res / "part-00009.parquet")  # a part of another run
    (res / "part-00002.parquet").unlink()
    assert main(["sweep", str(st), "--out", str(res), "--summary"]) == 1
    out, err = capsys.readouterr()
    assert "NOT complete: 8 designs missing (16, 17, 18, 19, 20, 21, 22, 23); 8 designs appear more than once (8, 9" in out
    assert "status complete" not in out and "holds designs more than once" in err
    # resuming with another batch layout would mix parts: refused
    (res / "part-00009.parquet").unlink()
    with pytest.raises(design.study.ConfigError, match="batches of 8 designs"):
        design.sweep(study, out=res, workers=0, batch_size=5)
    df, stats = design.sweep(study, out=res, workers=0)
    assert stats.batches_skipped == 4 and sorted(df["design"]) == list(range(40))


# --- read-only and full file systems ----------------------------------------------------------

@contextlib.contextmanager
def tmpfs(folder, options):
    """A tmpfs mounted on `folder` (root only); skips the test where mounting is refused."""
    folder.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.decode().strip()})")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


@pytest.fixture
def read_only(tmp_path):
    ro = tmp_path / "ro"
    if os.geteuid() != 0:
        ro.mkdir()
        ro.chmod(0o555)
        yield ro
        ro.chmod(0o755)
        return
    with tmpfs(ro, "size=64k,ro") as d:
        yield d


def test_sweep_into_a_read_only_folder_exits_2_before_the_cluster(tmp_path, read_only, capsys):
    st = sweep_study(tmp_path, samples=6)
    for args, where in ((["--out", str(read_only / "res")], read_only),
                        (["--out", str(tmp_path / "r"), "--csv", str(read_only / "t.csv")], read_only)):
        t0 = time.perf_counter()
        assert main(["sweep", str(st), *args, "--workers", "1"]) == 2
        err = capsys.readouterr().err
        assert time.perf_counter() - t0 < 5 and "Traceback" not in err and "internal error" not in err
        assert f"'{where}'" in err and ("read-only" in err or "permission" in err), err
    assert not (tmp_path / "r").exists()
    assert main(["pumpdown", str(EVP), "--json", str(read_only / "p.json")]) == 2
    assert str(read_only) in capsys.readouterr().err


def test_full_disk_while_writing_is_named_and_leaves_nothing(tmp_path, capsys, monkeypatch):
    """ENOSPC in the middle of a write (simulated): exit 2 naming the output and the remedy; the
    half-written temporary is removed and no other output is renamed into place."""
    import pumpsim.result

    def fills_the_disk(self, path):
        Path(path).write_text("time,angle\n0,")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(pumpsim.result.SimulationResult, "to_csv", fills_the_disk)
    out, png = tmp_path / "o.csv", tmp_path / "o.png"
    assert main(["simulate", str(RIG), "--duration", "0.002", "--out", str(out), "--plot", str(png)]) == 2
    err = capsys.readouterr().err
    assert "no space left on the device; free space there or write the output to another disk" in err
    assert f"'{out}'" in err and list(tmp_path.iterdir()) == []


def test_full_tmpfs(tmp_path, capsys):
    """A real 64 KiB file system: a CSV that does not fit, and a study whose parts fill it."""
    with tmpfs(tmp_path / "small", "size=64k") as small:
        out = small / "o.csv"
        assert main(["simulate", str(RIG), "--duration", "0.2", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert f"writing --out '{out}' failed: no space left on the device" in err
        assert list(small.iterdir()) == []
        from pumpsim import design

        st = tmp_path / "i.toml"
        st.write_text('[study]\nfunction = "ishigami"\nsampler = "random"\nsamples = 20000\nseed = 2\n'
                      'batch_size = 1000\n' + "".join(f'[vary.{k}]\ndistribution = "uniform"\nlow = -3.14\n'
                                                     'high = 3.14\n' for k in ("x1", "x2", "x3")))
        with pytest.raises(OutputError) as e:
            design.sweep(design.load_study(st), out=small / "res", workers=0)
        assert "no space left on the device" in str(e.value) and "--out" in str(e.value)
        assert "designs done are kept in" in str(e.value) and "the same command resumes there" in str(e.value)
        assert e.value.exit_status == 2
        ids = designs_in(small / "res")
        assert len(ids) == len(set(ids)) and len(ids) % 1000 == 0 and temporaries(small) == []


# --- a worker killed mid-study; random interrupts of every command ------------------------------

@pytest.mark.slow
def test_killed_worker_mid_study_completes_each_design_once(tmp_path):
    import psutil

    st, res = sweep_study(tmp_path, samples=300, batch=5), tmp_path / "res"
    p = start(["sweep", st, "--out", res, "--workers", "2"], tmp_path)
    wait_for(lambda: len(list(res.glob("part-*.parquet"))) >= 2, p)
    workers = [c for c in psutil.Process(p.pid).children(recursive=True)
               if "spawn_main" in " ".join(c.cmdline()) or "forkserver" in " ".join(c.cmdline())]
    assert workers
    workers[0].send_signal(signal.SIGKILL)
    out, err = p.communicate(timeout=300)
    assert p.returncode == 0, err
    assert "status complete" in out and "300 designs, 300 rows" in out
    assert sorted(designs_in(res)) == list(range(300))


def _commands(tmp):
    """Each command with its outputs, sized to run several seconds."""
    st = sweep_study(tmp, samples=400, batch=10)
    return {
        "simulate": (["simulate", RIG, "--duration", "2", "--out", tmp / "s.csv", "--plot", tmp / "s.png"],
                     [tmp / "s.csv", tmp / "s.png"]),
        "simulate-contact": (["simulate", ELLIPSE, "--model", "contact", "--duration", "3", "--out",
                              tmp / "c.csv", "--keep-partial"], [tmp / "c.csv"]),
        # (the ellipse: on the concentric rig the speed is not identifiable, a refused fit, exit 1)
        "identify": (["identify", ELLIPSE, EXAMPLES / "data" / "ellipse_hidden_effects.csv", "--params",
                      "mu,theta0,speed", "--json", tmp / "i.json",
                      "--report", tmp / "i.html"], [tmp / "i.json", tmp / "i.html"]),
        "diagnose": (["diagnose", ELLIPSE, EXAMPLES / "data" / "ellipse_hidden_effects.csv", "--json",
                      tmp / "d.json"], [tmp / "d.json"]),
        "pumpdown": (["pumpdown", EVP, "--out", tmp / "p.csv", "--json", tmp / "p.json"],
                     [tmp / "p.csv", tmp / "p.json"]),
        "sweep": (["sweep", st, "--out", tmp / "res", "--csv", tmp / "t.csv", "--workers", "1"], [tmp / "t.csv"]),
    }


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("command", ["simulate", "simulate-contact", "identify", "diagnose", "pumpdown", "sweep"])
def test_random_interrupts_of_every_command(tmp_path, command, sig):
    """Three signals at random points of each command: 128 + signal (or 0 if it ended first),
    one line, every output complete or absent, no temporary left, a study folder's designs once."""
    draw = rng(command + sig.name)
    for i in range(3):
        tmp = tmp_path / str(i)
        tmp.mkdir()
        args, outputs = _commands(tmp)[command]
        p = start(args, tmp)
        code, _, err = signal_after(p, draw.uniform(0.5, 8.0), sig)
        assert code in (0, 128 + sig), (code, err)
        if code:
            m = the_message(err, sig)
            if not re.search(r"samples computed before it are in", m[7]):
                # only the outputs the message names as written (a signal after they were put in place)
                assert all(not o.exists() or str(o) in written_in(m[7]) for o in outputs), err
        assert_complete_or_absent(outputs)
        assert temporaries(tmp) == []
        if (tmp / "res").exists():
            ids = designs_in(tmp / "res")
            assert len(ids) == len(set(ids))


@pytest.mark.slow
def test_interrupted_kernel_build_leaves_no_temporary(tmp_path, monkeypatch):
    """SIGINT while a kernel is generated/compiled: 130 and no half-built variant in the cache."""
    cache = tmp_path / "cache"
    cache.mkdir()
    monkeypatch.setenv("PUMPSIM_GENERATED", str(cache))
    p = start(["simulate", RIG, "--duration", "0.002"], tmp_path)
    wait_for(lambda: any(cache.iterdir()), p)
    code, _, err = signal_after(p, rng("build").uniform(0.2, 2.0), signal.SIGINT)
    assert code == 130, err
    the_message(err, signal.SIGINT)
    # (a variant's build lock file stays, empty: deleting it on release would race another process
    # taking it; it is no half-built variant)
    assert [f.name for f in cache.iterdir() if f.name.startswith(".") and not f.name.endswith(".build.lock")] == []


def test_a_signal_after_the_study_names_the_designs_kept(tmp_path, monkeypatch, capsys):
    """A signal once every design is done (while the CSV is written, say): 130, the CSV not written,
    and the message names the designs kept in the results folder -- not "no output file written"
    (a race the Ctrl-C test above can lose: the study may finish before its signal lands)."""
    import pandas as pd

    from pumpsim import interrupt
    from pumpsim.cli import main

    st, res, csv = sweep_study(tmp_path, samples=20), tmp_path / "res", tmp_path / "t.csv"

    def stopped(*a, **kw):
        raise interrupt.Interrupted(signal.SIGINT)
    monkeypatch.setattr(pd.DataFrame, "to_csv", stopped)
    code = main(["sweep", str(st), "--out", str(res), "--csv", str(csv), "--workers", "1"])
    err = capsys.readouterr().err
    assert code == 130, err
    assert f"the 20 designs done are kept in '{res}'" in err, err
    assert not csv.exists() and len(designs_in(res)) == 20


def run_as_program(setup: str):
    """`python -m pumpsim` after the Python code `setup` (in the same process)."""
    code = setup + "import runpy\nrunpy.run_module('pumpsim', run_name='__main__')\n"
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=_env(), capture_output=True, text=True,
                          timeout=60)


@pytest.mark.parametrize("when", ["starting", "exiting"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_outside_the_commands_handling_still_gives_its_status(sig, when):
    """`python -m pumpsim` (and the console script, cli.console) has a handler from before the
    command line imports until the process exits: a signal just before the command's own handling starts, or just after it ended, gives
    128 + signal and one line (the default action was a silent kill, status -signal)."""
    probe = ("import os, signal, runpy, sys, time\n"
             "import pumpsim.cli.app as app\n"
             "real = app.main\n"
             "def main(argv=None):\n"
             f"    if {when!r} == 'starting':\n"
             f"        os.kill(os.getpid(), {int(sig)}); time.sleep(5)\n"
             "    status = real(['--version'])\n"
             f"    os.kill(os.getpid(), {int(sig)}); time.sleep(5)\n"
             "    return status\n"
             "app.main = main\n"
             "sys.argv = ['pumpsim']\n")
    r = run_as_program(probe)
    assert r.returncode == 128 + sig, (r.returncode, r.stderr)
    said = {"starting": "while starting; nothing was written",
            "exiting": "while exiting; the run had ended, its outputs are written"}[when]
    assert r.stderr.splitlines() == [f"pumpsim: interrupted by {sig.name} {said}"]


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_in_the_interpreters_last_teardown_leaves_the_runs_status(sig):
    """After the atexit functions Python resets the signal handlers to the default action: a signal
    there killed the finished run silently (status -signal; make test-all under load, a sweep and a
    diagnose). It is ignored now and the run's own status stands. The signal comes from an object
    torn down with the modules, after the handlers' reset, with another thread alive (a Dask loop's:
    blocking the signal in the main thread alone let that thread take it)."""
    probe = ("import os, sys, threading, time, types\n"
             "threading.Thread(target=time.sleep, args=(60,), daemon=True).start()\n"
             "class Late:\n"
             "    def __del__(self):\n"
             f"        os.kill(os.getpid(), {int(sig)}); time.sleep(1)\n"
             "m = types.ModuleType('pumpsim_late_probe'); m.late = Late(); sys.modules[m.__name__] = m\n"
             "del m\n"
             "sys.argv = ['pumpsim', '--version']\n")
    r = run_as_program(probe)
    assert (r.returncode, r.stderr) == (0, ""), (r.returncode, r.stderr)
    assert r.stdout.startswith("pumpsim ")
