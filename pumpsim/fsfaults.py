"""File-system faults on outputs, named: which path, what operation, what to do (exit 2).

`guard(operation, path, option)` turns an OSError inside its block into OutputError; `describe`
words any OSError (the command line's last resort for one no guard caught). A temporary file's
name (pumpsim.io writes beside the target, then renames) is reported as its target's.
"""
from __future__ import annotations

import contextlib
import errno
import os
import re
import tempfile
from pathlib import Path

from .errors import OutputError, PumpsimError

# errno -> (what happened, what to do); all of them a user can fix
_FIXABLE = {
    errno.ENOSPC: ("no space left on the device", "free space there or write the output to another disk"),
    errno.EDQUOT: ("the disk quota is exceeded", "free space there or write the output to another disk"),
    errno.EROFS: ("the file system is read-only", "write the output to a writable folder"),
    errno.EACCES: ("permission denied", "change the permissions or write the output elsewhere"),
    errno.EPERM: ("operation not permitted", "change the permissions or write the output elsewhere"),
    errno.ENOENT: ("no such file or folder", "create the folder or give an existing one"),
    errno.ENOTDIR: ("a part of the path is a file, not a folder", "give a path through folders"),
    errno.EISDIR: ("it is a folder", "give a file name"),
    errno.EEXIST: ("it exists already", "remove it or give another name"),
    errno.ENAMETOOLONG: ("the name is too long", "give a shorter path"),
    errno.EMFILE: ("too many open files", "raise the open-file limit (ulimit -n)"),
    errno.EFBIG: ("the file is too large for the file system", "write the output to another disk"),
}
# the temporary names of pumpsim.io: ".NAME.tmp-XXXXXXXX[.sfx]" (staged) and ".NAME.XXXXXXXX.tmp"
_TEMPORARY = (re.compile(r"^\.(?P<name>.+)\.tmp-[A-Za-z0-9_]{8}"), re.compile(r"^\.(?P<name>.+)\.[A-Za-z0-9_]{8}\.tmp$"))


def target_of(path) -> str:
    """The output a temporary file stands for (the path itself otherwise)."""
    p = Path(str(path))
    for pattern in _TEMPORARY:
        m = pattern.match(p.name)
        if m:
            return str(p.with_name(m["name"]))
    return str(path)


def fixable(e: OSError) -> bool:
    return e.errno in _FIXABLE


def describe(e: OSError, operation: str | None = None, path=None, option: str | None = None) -> str:
    """'writing --out 'a.csv' failed: no space left on the device; free space there or ...'"""
    where = path if path is not None else (e.filename if e.filename is not None else None)
    what, fix = _FIXABLE.get(e.errno, (e.strerror or str(e), None))
    subject = " ".join(x for x in (option, f"'{target_of(where)}'" if where is not None else None) if x)
    text = f"{operation or 'file-system operation'}{' ' + subject if subject else ''} failed: {what}"
    if e.filename is not None and where is not None and target_of(e.filename) != target_of(where):
        text += f" ('{target_of(e.filename)}')"
    if fix:
        text += f"; {fix}" + (f" (see {option})" if option else "")
    return text


def error(e: OSError, operation: str | None = None, path=None, option: str | None = None) -> PumpsimError:
    """OutputError (exit 2) for a fault the user can fix, else a PumpsimError (exit 1)."""
    cls = OutputError if fixable(e) else PumpsimError
    return cls(describe(e, operation, path, option))


@contextlib.contextmanager
def guard(operation: str, path=None, option: str | None = None):
    """Name any OSError raised inside the block (see `error`)."""
    try:
        yield
    except OSError as e:
        raise error(e, operation, path, option) from None


def probe_folder(folder, option: str, create: bool = False) -> None:
    """Before any work: a file can be created in `folder` (or, create=True and it does not exist
    yet, in its parent). Permission bits do not tell everything: root passes os.access, and
    read-only mounts refuse new files."""
    folder = Path(folder)
    place = folder if folder.exists() or not create else (folder.parent if str(folder.parent) else Path("."))
    if not place.exists():
        raise OutputError(f"{option} '{folder}': folder '{place}' does not exist; create it or give an "
                          "existing one")
    if not place.is_dir():
        raise OutputError(f"{option} '{folder}': '{place}' is a file, not a folder; give a folder")
    with guard("creating a file in", place, option):
        fd, tmp = tempfile.mkstemp(prefix=".pumpsim-probe-", dir=place)
        os.close(fd)
        os.unlink(tmp)
