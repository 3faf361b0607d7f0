"""Output files: checked before any work starts, written atomically at the end, all or nothing.

A command names its outputs in an `Outputs` set; `check()` refuses (exit 2, nothing written) a path
that names a folder, sits in a missing or read-only folder, repeats another output or an input, or
has a suffix the writer cannot produce. `staged()` hands out temporary paths beside the targets and
renames them into place only when every writer has finished, so a failure leaves no file behind.
Files get the modes an ordinary `open()` would give (0666 less the umask), not mkstemp's 0600.
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

from . import interrupt
from .errors import ConfigError
from .model_spec.manifest import umask_mode


def _folder(target: Path) -> Path:
    return target.parent if str(target.parent) else Path(".")


def check_writable(path, option: str = "output", suffixes=None) -> Path:
    """Refuse (ConfigError) an output path that cannot be written: a folder, a missing or
    read-only folder, or a suffix outside `suffixes` (lower case, with the dot)."""
    target = Path(path)
    name = f"{option} '{path}'"
    if str(path).strip() == "" or str(path).endswith(("/", os.sep)):
        raise ConfigError(f"{name} names a folder; give a file name")
    if target.is_dir():
        raise ConfigError(f"{name} is a folder; give a file name (e.g. {target / 'out'}"
                          f"{(sorted(suffixes)[0] if suffixes else '')})")
    if suffixes is not None and target.suffix.lower() not in suffixes:
        raise ConfigError(f"{name}: the file type must be one of {', '.join(sorted(suffixes))}, "
                          f"got '{target.suffix or '(none)'}'")
    folder = _folder(target)
    if not folder.is_dir():
        raise ConfigError(f"{name}: output folder '{folder}' does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ConfigError(f"{name}: no permission to write in folder '{folder}'")
    _probe(folder, name)
    if target.exists() and not os.access(target, os.W_OK):
        raise ConfigError(f"{name}: the existing file is read-only")
    return target


def _probe(folder: Path, name: str) -> None:
    """Create and remove a file in `folder`: permission bits do not tell everything (root passes
    os.access; /proc, /sys and read-only mounts refuse new files)."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=".pumpsim-probe-", dir=folder)
    except OSError as e:
        raise ConfigError(f"{name}: cannot create a file in folder '{folder}' ({e.strerror})") from None
    os.close(fd)
    os.unlink(tmp)


@dataclass
class _Entry:
    option: str
    path: Path
    suffixes: frozenset | None
    kind: str | None = None  # the file type a writer infers from the name (e.g. 'png')


class Outputs:
    """The output files of one command run."""

    def __init__(self, inputs=()):
        self._entries: dict[str, _Entry] = {}
        self._inputs = [Path(p) for p in inputs if p is not None]

    def add(self, option: str, path, suffixes=None, kind=None) -> None:
        """Register `path` for `option` (e.g. '--json'); None (option not given) is ignored.
        suffixes: the allowed file suffixes (None: any); kind: callable(path) -> the file type the
        writer will infer from the name, raising ConfigError for one it cannot write."""
        if path is None:
            return
        self._entries[option] = _Entry(option, Path(path), None if suffixes is None else frozenset(suffixes),
                                       None if kind is None else kind(path))

    def __contains__(self, option):
        return option in self._entries

    def check(self) -> None:
        """Every output writable, no two the same file, none an input file."""
        seen: dict = {}
        inputs = {_identity(p): p for p in self._inputs if p.exists()}
        for e in self._entries.values():
            key = _identity(e.path)
            if key in seen:
                raise ConfigError(f"{e.option} and {seen[key]} name the same file '{e.path}'; "
                                  "give each output its own file")
            if key in inputs:
                raise ConfigError(f"{e.option} '{e.path}' is an input file of this run; writing "
                                  "it would destroy the input")
            seen[key] = e.option
        for e in self._entries.values():
            check_writable(e.path, e.option, e.suffixes)

    @contextlib.contextmanager
    def staged(self):
        """Yield {option: temporary path}; when the block ends without error every temporary
        replaces its target, otherwise all are removed and no target is touched."""
        self.check()
        tmps = {}
        try:
            for opt, e in self._entries.items():
                # the temporary keeps the type in its suffix: writers infer the format from it
                suffix = f".{e.kind}" if e.kind else e.path.suffix
                fd, tmp = tempfile.mkstemp(prefix=f".{e.path.name}.tmp-", suffix=suffix, dir=_folder(e.path))
                os.close(fd)
                tmps[opt] = tmp
            yield dict(tmps)
            mode = umask_mode()
            with interrupt.unsplit():  # all renamed or none: a signal here is raised after them
                for opt, tmp in tmps.items():
                    os.chmod(tmp, mode)
                for opt, tmp in tmps.items():
                    os.replace(tmp, self._entries[opt].path)
                interrupt.written(self._entries[opt].path for opt in tmps)
        finally:
            for tmp in tmps.values():
                if os.path.exists(tmp):
                    os.unlink(tmp)


def _identity(path: Path):
    """Same file <=> same identity, also through links and relative paths."""
    try:
        st = path.stat()
        return ("inode", st.st_dev, st.st_ino)
    except OSError:
        return ("path", str(path.resolve()))


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path; on success it replaces `path` (with the umask's mode), on failure it
    is removed."""
    target = Path(path)
    folder = _folder(target)
    if not folder.is_dir():
        raise ConfigError(f"output folder '{folder}' does not exist")
    if target.is_dir():
        raise ConfigError(f"output '{path}' is a folder; give a file name")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
    except OSError as e:
        raise ConfigError(f"cannot write in folder '{folder}': {e.strerror}") from None
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, umask_mode())
        os.replace(tmp, target)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_text(path, text: str) -> None:
    """Write `text` to `path` atomically (UTF-8)."""
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
