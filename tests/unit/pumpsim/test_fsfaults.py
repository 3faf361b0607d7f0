"""File-system faults are named (path, operation, remedy), temporaries by their targets; the
interruption message; output locks taken and released."""
import errno
import os
import signal
from pathlib import Path

import pytest

from pumpsim import fsfaults, interrupt, locks
from pumpsim.errors import OutputError, PumpsimError


@pytest.mark.parametrize("tmp_name, target", [
    (".o.csv.tmp-ab_3x9zq.csv", "o.csv"),         # pumpsim.io Outputs.staged
    (".fit.json.k2j4_a9q.tmp", "fit.json"),       # pumpsim.io atomic_path
    ("o.csv", "o.csv"),
    (".hidden.csv", ".hidden.csv"),
])
def test_a_temporary_is_reported_as_its_target(tmp_path, tmp_name, target):
    assert fsfaults.target_of(tmp_path / tmp_name) == str(tmp_path / target)


@pytest.mark.parametrize("code, what, fix", [
    (errno.ENOSPC, "no space left on the device", "free space there"),
    (errno.EROFS, "the file system is read-only", "writable folder"),
    (errno.EACCES, "permission denied", "change the permissions"),
    (errno.ENOTDIR, "not a folder", "through folders"),
])
def test_fixable_faults_exit_2_naming_path_operation_and_remedy(tmp_path, code, what, fix):
    err = fsfaults.error(OSError(code, os.strerror(code), str(tmp_path / ".r.csv.tmp-abcdefgh.csv")),
                         "writing", tmp_path / "r.csv", "--csv")
    assert isinstance(err, OutputError) and err.exit_status == 2
    text = str(err)
    assert text.startswith(f"writing --csv '{tmp_path / 'r.csv'}' failed: ") and what in text and fix in text
    assert "(see --csv)" in text and ".tmp-" not in text


def test_other_faults_exit_1_with_the_system_message():
    err = fsfaults.error(OSError(errno.EIO, os.strerror(errno.EIO), "/x/y"))
    assert type(err) is PumpsimError and err.exit_status == 1
    assert str(err) == f"file-system operation '/x/y' failed: {os.strerror(errno.EIO)}"


def test_guard_and_probe(tmp_path):
    with pytest.raises(OutputError, match=r"reading --x '.*' failed: no such file or folder"):
        with fsfaults.guard("reading", tmp_path / "nope", "--x"):
            open(tmp_path / "nope")
    fsfaults.probe_folder(tmp_path, "--out")
    fsfaults.probe_folder(tmp_path / "new", "--out", create=True)  # its parent is writable
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(OutputError, match="does not exist"):
        fsfaults.probe_folder(tmp_path / "a" / "b", "--out", create=True)
    (tmp_path / "f").write_text("")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        fsfaults.probe_folder(tmp_path / "f" / "b", "--out", create=True)


def test_interruption_message_and_status():
    with interrupt.handling():
        interrupt.progress("at simulated t = 0.5 s of 2 s")
        e = interrupt.Interrupted(signal.SIGTERM)
        assert e.exit_status == 143 and isinstance(e, KeyboardInterrupt)
        assert e.message() == "interrupted by SIGTERM at simulated t = 0.5 s of 2 s; no output file written"
        e.notes.append("the 5 samples computed before it are in a.csv")
        assert e.message().endswith("; the 5 samples computed before it are in a.csv")
        assert interrupt.pending() is None
        interrupt.check()  # nothing pending: no-op


def test_deferred_signal_raises_after_the_native_call():
    with interrupt.handling():
        with pytest.raises(interrupt.Interrupted) as e:
            with interrupt.deferred():
                signal.raise_signal(signal.SIGINT)  # to this thread, so handled here: only recorded
                reached = True
        assert reached and e.value.exit_status == 130 and interrupt.pending() == signal.SIGINT
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


def test_a_study_folder_lock_is_exclusive_and_leaves_a_new_folder_clean(tmp_path):
    d = tmp_path / "res"
    with locks.study_folder(d):
        info = (d / locks.INFO).read_text()
        assert f'"pid": {os.getpid()}' in info
        assert locks.holder_of(d).startswith(f"pid {os.getpid()} on host")
        with pytest.raises(OutputError, match=f"being written by another pumpsim run \\(pid {os.getpid()}"):
            with locks.study_folder(d):
                pass
    assert locks.holder_of(d) is None
    assert not d.exists()  # created for the run, left empty: removed



def test_an_interruption_after_the_outputs_are_in_place_names_them(tmp_path):
    """A signal while a command's outputs are renamed into place is raised after all of them (all
    or none), and the message names them as written and complete -- it said 'no output file
    written' with the files on disk (a sweep signalled just after its table was written)."""
    from pumpsim.io import Outputs

    a, b = tmp_path / "a.csv", tmp_path / "b.json"
    outs = Outputs()
    outs.add("--csv", a)
    outs.add("--json", b)
    with interrupt.handling():
        with pytest.raises(interrupt.Interrupted) as got:
            with outs.staged() as tmp:
                Path(tmp["--csv"]).write_text("x\n1\n")
                Path(tmp["--json"]).write_text("{}")
                os.kill(os.getpid(), signal.SIGTERM)  # while the outputs are written: raised here
        assert not a.exists() and not b.exists()  # a signal while writing: nothing put in place
        assert got.value.message().endswith("; no output file written")

    with interrupt.handling():  # a new run: its first signal
        outs2 = Outputs()
        outs2.add("--csv", a)
        outs2.add("--json", b)
        real_replace = os.replace

        def replace(src, dst):  # the signal lands between the two renames
            real_replace(src, dst)
            if Path(dst) == a:
                os.kill(os.getpid(), signal.SIGTERM)
        with pytest.raises(interrupt.Interrupted) as got:
            with pytest.MonkeyPatch.context() as mp:
                mp.setattr(os, "replace", replace)
                with outs2.staged() as tmp:
                    Path(tmp["--csv"]).write_text("x\n1\n")
                    Path(tmp["--json"]).write_text("{}")
        assert a.read_text() == "x\n1\n" and b.read_text() == "{}"  # both in place
        assert got.value.message() == f"interrupted by SIGTERM; {a}, {b} written and complete"


def test_the_signal_raised_in_a_gc_callback_is_not_printed_there(capsys):
    """Dask's GC diagnosis runs a callback the signal's exception can land in; Python would print
    'Exception ignored in ...' for it. During a run with the signal recorded it is not printed
    (the command reports the signal once, after); any other unraisable exception still is."""
    class Raises:
        def __init__(self, exc):
            self.exc = exc

        def __del__(self):
            raise self.exc

    with interrupt.handling():
        interrupt._state["signal"] = signal.SIGTERM
        Raises(interrupt.Interrupted(signal.SIGTERM))  # dropped at once: __del__ raises, unraisable
        assert "Exception ignored" not in capsys.readouterr().err
        Raises(ValueError("other"))
        assert "ValueError: other" in capsys.readouterr().err
        interrupt._state["signal"] = None
