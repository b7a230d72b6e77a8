"""What a path handed to a run may name, checked before anything runs.

A run writes logs, state and outputs, and rotates and renames them. Aimed at a device node,
a FIFO or a directory, that is how a log rotation came to rename ``/dev/null`` (issue 13):
so every file a run is given must be a regular file or absent, and every directory a
directory or absent. The check follows symbolic links, so a link to a regular file is fine
and a link to a device is not.
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path
from typing import BinaryIO

KINDS = {stat.S_IFDIR: "a directory", stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device",
         stat.S_IFIFO: "a FIFO (named pipe)", stat.S_IFSOCK: "a socket", stat.S_IFLNK: "a symbolic link",
         stat.S_IFREG: "a regular file"}


class UnsafePathError(OSError):
    """A path names something a run must not write to or read as a file; says what it is."""


def kind_of(mode: int) -> str:
    """``st_mode`` in words ("a character device")."""
    return KINDS.get(stat.S_IFMT(mode), "not a regular file")


def _mode(path: Path) -> int | None:
    try:
        return os.stat(path).st_mode
    except FileNotFoundError:
        return None
    except NotADirectoryError:  # a parent is a file: nothing can be made there
        raise UnsafePathError(f"{path}: a parent of it is not a directory") from None


def regular_file(path: str | os.PathLike, what: str) -> Path:
    """``path`` if it is a regular file or absent; else :class:`UnsafePathError` naming
    ``what`` (e.g. "--log") and what the path is."""
    path = Path(path)
    mode = _mode(path)
    if mode is not None and not stat.S_ISREG(mode):
        raise UnsafePathError(f"{what} {path}: is {kind_of(mode)}, not a regular file")
    return path


def directory(path: str | os.PathLike, what: str) -> Path:
    """``path`` if it is a directory or absent; else :class:`UnsafePathError`.

    A symbolic link to nothing (a state folder on a disk not mounted) is not absent: no
    directory can be made where it stands. Taken for absent, a live run went on for weeks
    with every save failing ('File exists'), and ``creatures check`` said the folder was
    writable."""
    path = Path(path)
    mode = _mode(path)
    if mode is None and os.path.islink(path):
        raise UnsafePathError(f"{what} {path}: is a symbolic link to {os.readlink(path)}, which does not exist "
                              "(a disk not mounted?)")
    if mode is not None and not stat.S_ISDIR(mode):
        raise UnsafePathError(f"{what} {path}: is {kind_of(mode)}, not a directory")
    return path


def open_regular(path: str | os.PathLike, what: str) -> BinaryIO:
    """``path`` opened for reading, if it is a regular file; else :class:`UnsafePathError`.

    A state file, manifest or events log that is a FIFO would block the run forever at
    ``open`` (and a device such as ``/dev/zero`` reads until memory runs out), so the path is
    checked before it is opened, opened non-blocking (a FIFO swapped in meanwhile does not
    hang), and checked again on the open descriptor. Missing: :class:`FileNotFoundError`."""
    path = regular_file(path, what)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise UnsafePathError(f"{what} {path}: is {kind_of(mode)}, not a regular file")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular(path: str | os.PathLike, what: str, limit: int) -> bytes:
    """The bytes of regular file ``path`` (:func:`open_regular`), reading at most ``limit``
    + 1 of them; more than ``limit`` is :class:`UnsafePathError` (a file that grew past its
    size check is not read whole)."""
    with open_regular(path, what) as handle:
        data = handle.read(limit + 1)
    if len(data) > limit:
        raise UnsafePathError(f"{what} {path}: larger than {limit} bytes; refused")
    return data


def writable_directory(path: str | os.PathLike, what: str) -> Path:
    """``path`` as a directory this process can write in, made if absent (:func:`directory`
    first). A folder on a read-only disk is found here, with ``what`` (e.g. "--frames") in the
    message, not half-way through a run by whichever file happens to be written first."""
    path = directory(path, what)
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        raise OSError(f"{what} {path}: cannot write there ({exc.strerror or exc})") from None
    return path
