"""systemd's readiness and watchdog protocol (sd_notify(3)), a datagram on ``$NOTIFY_SOCKET``.

A unit of ``Type=notify`` (``creatures service``) is started once the run says ``READY=1``:
after its creatures are built, its devices opened and its first tick played. With
``WatchdogSec`` systemd expects ``WATCHDOG=1`` at least that often (``$WATCHDOG_USEC``) and
kills and restarts a run that falls silent. The pings come from the supervisor thread, and only
while the creature's ticks advance: a colony whose tick loop hangs stops pinging and is
restarted, while a busy thread that still ticks is left alone. Without ``$NOTIFY_SOCKET``
(not under systemd) every call does nothing.
"""

from __future__ import annotations

import os
import socket
from typing import Callable, Mapping


def address(environ: Mapping[str, str]) -> str | None:
    """Where to send, from ``$NOTIFY_SOCKET``: a path, or ``@name`` for an abstract socket."""
    path = environ.get("NOTIFY_SOCKET") or None
    if path is not None and path.startswith("@"):
        return "\0" + path[1:]
    return path


def watchdog_interval(environ: Mapping[str, str]) -> float | None:
    """Seconds between pings: half systemd's ``$WATCHDOG_USEC`` (as sd_watchdog_enabled(3)
    advises), or None when no watchdog is asked for (or it is meant for another process)."""
    usec, pid = environ.get("WATCHDOG_USEC"), environ.get("WATCHDOG_PID")
    if not usec or (pid and pid != str(os.getpid())):
        return None
    try:
        return max(int(usec), 1) / 2e6
    except ValueError:
        return None


class Notifier:
    """Sends ``READY=1``, ``WATCHDOG=1``, ``STATUS=...`` and ``STOPPING=1`` to systemd."""

    def __init__(self, environ: Mapping[str, str] | None = None) -> None:
        env = os.environ if environ is None else environ
        self.address = address(env)
        self.interval = watchdog_interval(env)
        self.sent = 0
        self.is_ready = False  # no ping before READY=1: systemd's watchdog counts from there
        self._last_ticks = -1

    def send(self, *fields: str) -> bool:
        """One datagram of newline-separated ``KEY=VALUE`` fields; False when there is nowhere
        to send or it could not be sent (systemd gone: the show goes on)."""
        if self.address is None:
            return False
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC) as sock:
                # Never waits: a receiver that stopped reading must not stall a tick or a job.
                sock.sendto("\n".join(fields).encode("utf-8"), socket.MSG_DONTWAIT, self.address)
        except OSError:
            return False
        self.sent += 1
        return True

    def ready(self, status: str) -> bool:
        self.is_ready = self.send("READY=1", f"STATUS={status}")
        return self.is_ready

    def stopping(self) -> bool:
        return self.send("STOPPING=1")

    def pinger(self, ticks: Callable[[], int]) -> Callable[[], None]:
        """A supervisor job: ``WATCHDOG=1`` when ``ticks()`` moved since the last ping."""

        def ping() -> None:
            now = ticks()
            if self.is_ready and now != self._last_ticks:
                self._last_ticks = now
                self.send("WATCHDOG=1")

        return ping
