"""One run per folder: a lock file holding the pid of the run that uses the folder.

Two runs sharing a state folder overwrite each other's creatures at every save, and two
offline runs publishing into one output directory would interleave their outputs (issue 13).
The lock is ``DIR/.creatures.lock``: the holder writes its pid into it and holds an
``flock`` on it for as long as it runs. The kernel lets go of an ``flock`` when its process
dies, however it dies, so a lock left behind by a killed run (its pid dead) is simply taken
over by the next one; a pid alone could not tell a dead holder from a reused pid.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import stat
from pathlib import Path
from typing import Callable

from creatures.paths import UnsafePathError, kind_of

LOCK_FILE = ".creatures.lock"

_LOCKS: dict[str, "FolderLock"] = {}
"""The locks this process holds, by their folder's absolute path (for :func:`retake`, and to
tell one folder given twice from another run's)."""


class FolderLockedError(OSError):
    """Another running process holds the folder; the message names it and its pid."""


class FolderLock:
    """``with FolderLock(directory, "state folder"):`` — held while the block runs; raises
    :class:`FolderLockedError` when another live process holds it."""

    def __init__(self, directory: Path, what: str) -> None:
        self.directory = Path(directory)
        self.path = self.directory / LOCK_FILE
        self.what = what
        self.stale: int | None = None  # the dead holder whose lock was taken over, if any
        self._fd: int | None = None

    def acquire(self) -> "FolderLock":
        self.directory.mkdir(parents=True, exist_ok=True)
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, 0o644)
            try:
                mode = os.fstat(fd).st_mode
                if not stat.S_ISREG(mode):
                    raise UnsafePathError(f"{self.path}: is {kind_of(mode)}, not a regular file")
                ours = next((lock.what for lock in _LOCKS.values() if lock._fd is not None
                             and _key(lock._fd) == _key(fd)), None)
                if ours is not None:  # flock tells no holder apart: it would blame "another run", pid ours
                    raise FolderLockedError(
                        f"{self.directory}: already this run's {ours}; one folder cannot be both its {ours} and "
                        f"its {self.what}: choose another folder for one of them")
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    raise FolderLockedError(
                        f"{self.directory}: in use by another run (pid {_holder(fd) or 'unknown'}); two runs "
                        f"cannot share one {self.what}: stop the other run or choose another folder") from None
                if _same_file(fd, self.path):
                    break
            except BaseException:
                os.close(fd)
                raise
            os.close(fd)  # the holder removed it between our open and our lock: lock the new one
        self.stale = _holder(fd)
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self._fd = fd
        _LOCKS[os.path.abspath(self.directory)] = self
        return self

    def retake(self) -> bool:
        """Lock the folder again if its lock file is no longer this lock's (the folder was
        removed, or the file, while the run used it); whether it had to. A save makes a removed
        folder again, and without its lock a second run could take the folder and share it
        unnoticed; another run that took it meanwhile raises :class:`FolderLockedError`."""
        if self._fd is None or _same_file(self._fd, self.path):
            return False
        old, self._fd = self._fd, None
        os.close(old)
        self.acquire()
        return True

    def release(self) -> None:
        if _LOCKS.get(os.path.abspath(self.directory)) is self:  # a retake another run refused left it there
            del _LOCKS[os.path.abspath(self.directory)]
        fd, self._fd = self._fd, None
        if fd is None:
            return
        with contextlib.suppress(OSError):
            if _same_file(fd, self.path):  # unlinked while still locked: no one can take a ghost
                os.unlink(self.path)
        os.close(fd)

    def __enter__(self) -> "FolderLock":
        return self if self._fd is not None else self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


def _holder(fd: int) -> int | None:
    """The pid written in the lock file (None when it holds none)."""
    try:
        return int(os.pread(fd, 32, 0).decode("ascii", "replace").strip())
    except ValueError:
        return None


def _key(fd: int) -> tuple[int, int]:
    here = os.fstat(fd)
    return here.st_dev, here.st_ino


def _same_file(fd: int, path: Path) -> bool:
    try:
        here, there = os.fstat(fd), os.lstat(path)
    except FileNotFoundError:
        return False
    return (here.st_dev, here.st_ino) == (there.st_dev, there.st_ino)


def retake(directory: Path) -> bool:
    """:meth:`FolderLock.retake` for this process's lock on ``directory``, if it holds one."""
    lock = _LOCKS.get(os.path.abspath(directory))
    return lock is not None and lock.retake()


def hold(directory: Path, what: str, say: Callable[[str], None]) -> FolderLock | None:
    """Lock ``directory`` for a run that may go on without it: a folder the lock cannot be
    written in (read-only, no permission) cannot be written by the run either, so there is
    nothing two runs could overwrite; that is said and the run goes on unlocked. Another
    run's lock raises :class:`FolderLockedError`."""
    lock = FolderLock(directory, what)
    try:
        lock.acquire()
    except (FolderLockedError, UnsafePathError):
        raise
    except OSError as exc:
        say(f"could not lock {what} {directory} ({exc.strerror or exc}); going on without a lock")
        return None
    if lock.stale is not None:
        say(f"took over the lock of {what} {directory} left by pid {lock.stale}, which no longer holds it")
    return lock
