"""File-system faults are named (path, operation, remedy), temporaries by their targets; the
interruption message; output locks taken and released."""
import errno
import os
import signal

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

