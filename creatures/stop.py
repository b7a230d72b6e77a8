"""Ctrl-C, SIGTERM and SIGHUP stop a command wherever it is, and only once.

SIGHUP is what a closed terminal or a dropped SSH session sends: the run stops as on SIGTERM
(state saved, outputs published), not killed where it stands with its learning since the last
save lost, as Python's default action had it. Its terminal is gone, so what the run would
print from then on goes to /dev/null (:func:`hung_up`) rather than failing on the dead tty.

Both raise an exception where the program is, so every command unwinds as on Ctrl-C:
staging folders go, locks are let go, and the CLI says so in one line (issue 13: SIGTERM
left an offline run's staging folder behind, Ctrl-C printed tracebacks). Python ignores an
exception raised inside a finaliser or a C callback, and a signal handler may happen to run
there: numba compiling a creature's kernels (llvmlite's ``__del__`` and object-cache
callbacks) swallowed about one SIGTERM in two in a measured start-up, and unwinding LLVM in
the middle of a compile crashed the process (SIGSEGV, about one Ctrl-C in five). So the
request is also kept in :data:`requested`; while numba or llvmlite code is on the stack
nothing is raised at all; and the loops that run for long (the offline ticks, the live loop)
call :func:`check` (or read it) each tick, where a deferred or swallowed stop is raised.
"""

from __future__ import annotations

import os
import signal
import stat
import sys
from contextlib import contextmanager
from typing import Any, Callable, Iterator


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised as Ctrl-C's KeyboardInterrupt is."""

    def __init__(self, signum: int = signal.SIGTERM) -> None:
        super().__init__()
        self.signum = signum


STOPPING = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""The signals that stop a command cleanly."""


def hung_up(signum: int) -> None:
    """On SIGHUP, point stdout and stderr at /dev/null where they were the lost terminal, so
    the stop's last lines (and a save's) do not fail on it with EIO; a file or pipe stays.
    A terminal is known by being a character device: a hung-up one is no longer a tty to
    ``isatty`` (its tcgetattr fails with EIO)."""
    if signum != signal.SIGHUP:
        return
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in (1, 2):
            try:
                if stat.S_ISCHR(os.fstat(fd).st_mode):
                    os.dup2(null, fd)
            except OSError:  # already closed
                continue
    finally:
        os.close(null)


def _raised(signum: int) -> KeyboardInterrupt:
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)


requested: int | None = None
"""The signal that asked the command to stop, until the stop has been handled."""


NATIVE = tuple(f"{os.sep}{name}{os.sep}" for name in ("numba", "llvmlite"))
"""Where code lives that must not be unwound by a signal (see the module docstring)."""


def _in_native(frame: Any) -> bool:
    while frame is not None:
        if any(part in frame.f_code.co_filename for part in NATIVE):
            return True
        frame = frame.f_back
    return False


def _stop(signum: int, frame: Any) -> None:
    global requested
    if requested is not None:  # a second Ctrl-C while the first unwinds: one stop is enough
        return
    requested = signum
    hung_up(signum)
    if _in_native(frame):  # compiling: raised at the next check() instead
        return
    raise _raised(signum)


def check() -> None:
    """Raise the stop a finaliser swallowed, if one was asked for."""
    if requested is not None:
        raise _raised(requested)


def install() -> Callable[[], None]:
    """Stop on SIGINT, SIGTERM and SIGHUP from now on; returns what puts the previous handlers back.
    A stop swallowed by a finaliser is not reported as "Exception ignored" with a traceback
    (it is raised again by :func:`check`); anything else unraisable still is."""
    global requested
    requested = None
    previous = {sig: signal.signal(sig, _stop) for sig in STOPPING}
    hook = sys.unraisablehook

    def unraisable(info: Any) -> None:
        if not (requested is not None and isinstance(info.exc_value, KeyboardInterrupt)):
            hook(info)

    sys.unraisablehook = unraisable

    def restore() -> None:
        global requested
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        sys.unraisablehook = hook
        requested = None

    return restore


@contextmanager
def finishing() -> Iterator[list[int]]:
    """While a stopped command finishes (a live run's final save, its devices closed), a
    further SIGINT, SIGTERM or SIGHUP is kept in the list this yields, not raised: a
    supervisor or systemd sending SIGTERM twice, or a second Ctrl-C, cut the final save
    short between two creatures' files (each written whole, persist.atomic_write), the run's
    last learning lost and its devices left open. The caller says what came once it is
    done; SIGKILL (systemd's ``TimeoutStopSec``) still ends a save that hangs. Main thread only."""
    again: list[int] = []

    def keep(signum: int, _: Any) -> None:
        again.append(signum)
        hung_up(signum)

    previous = {sig: signal.signal(sig, keep) for sig in STOPPING}
    try:
        yield again
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def named(signum: int) -> str:
    """How a stop is said: ``Ctrl-C``, ``SIGTERM``, ``SIGHUP``."""
    return "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
