"""A run's health, for whoever watches a show left alone for weeks: a JSON status over HTTP
and an OSC heartbeat.

The creatures' thread only *publishes* a status (a small dict, swapped in whole once a
housekeeping second: :meth:`Health.publish`); the HTTP server runs on a thread of its own
(stdlib ``http.server``) and the heartbeat is a supervisor job, so neither a slow client nor a
dead heartbeat target can touch a tick. ``GET /health`` answers ``200`` with the status while
the status is fresh, ``503`` once it is older than :data:`STALE` seconds (the creatures'
thread has stopped publishing: a stalled run) or once the supervisor's thread has been in one
job longer than :data:`STUCK` seconds (a stuck run: nothing is saved any more), so a watchdog
needs no parsing to act.

The heartbeat is ``/colony/heartbeat ticks:int late:int underruns:int uptime:float`` every
``[health] every`` seconds to each ``[health] heartbeat`` address.
"""

from __future__ import annotations

import json
import socket
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import TYPE_CHECKING, Any

from creatures.runtime.osc_wire import message

if TYPE_CHECKING:
    from creatures.supervisor import Supervisor

STALE = 5.0
"""Seconds after which a status not renewed means the run has stalled (``503``)."""

IDLE = 10.0
"""Seconds a connection may take to send its request before it is closed: each open one holds
a thread and a file descriptor of the run (a watchdog's machine gone mid-request, a port scan),
and a run out of descriptors cannot save its state."""

STUCK = 30.0
"""Seconds one supervisor job may run before the run is said ``stuck`` (``503``): saves, the
log's flush, device checks and the heartbeat all wait behind it (a periodic save of a large
colony takes well under a second)."""


class Health:
    """The latest status of a run, readable from any thread."""

    def __init__(self, supervisor: "Supervisor | None" = None) -> None:
        self.supervisor = supervisor
        self.started = time.monotonic()
        self._status: dict[str, Any] = {"ticks": 0, "late_ticks": 0, "underruns": 0}
        self._published = self.started

    def publish(self, **status: Any) -> None:
        """A new status (creatures' thread); replaced whole, so a reader never sees half of one."""
        self._status, self._published = status, time.monotonic()

    def status(self) -> dict[str, Any]:
        """The status with its age and the run's uptime, and ``state``: ``stalled`` when stale,
        ``stuck`` when the supervisor's thread has been in one job longer than :data:`STUCK`."""
        now = time.monotonic()
        status = dict(self._status)
        age = now - self._published
        status.setdefault("state", "running")
        stuck = self.supervisor.stuck(STUCK) if self.supervisor is not None else None
        if stuck is not None:
            status["state"] = "stuck"
            status["stuck"] = {"job": stuck[0], "seconds": round(stuck[1], 1)}
        if age > STALE:
            status["state"] = "stalled"
        return {**status, "uptime": round(now - self.started, 3), "age": round(age, 3)}


class _Handler(BaseHTTPRequestHandler):
    health: Health

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        if self.path.split("?")[0] not in ("/health", "/"):
            self.send_error(404, "only /health is here")
            return
        status = self.health.status()
        body = json.dumps(status).encode()
        self.send_response(503 if status["state"] in ("stalled", "stuck") else 200)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, format: str, *args: Any) -> None:  # a watchdog's polls are not news
        pass


class HealthServer:
    """``GET /health`` on ``host:port`` (port 0: any free one, read back as :attr:`port`)."""

    def __init__(self, health: Health, host: str, port: int) -> None:
        handler = type("HealthHandler", (_Handler,), {"health": health, "timeout": IDLE})  # IDLE read here, not at import
        self.server = ThreadingHTTPServer((host, port), handler)
        self.server.daemon_threads = True
        self.port: int = self.server.server_address[1]
        self._thread = threading.Thread(target=self.server.serve_forever, kwargs={"poll_interval": 0.2},
                                        name="health endpoint", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


class Heartbeat:
    """Sends ``/colony/heartbeat`` to ``targets``: call :meth:`beat` from a supervisor job."""

    def __init__(self, health: Health, targets: list[tuple[str, int]]) -> None:
        self.health = health
        self.targets = targets
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.setblocking(False)
        self.sent = 0
        self.send_errors = 0

    def beat(self) -> None:
        status = self.health.status()
        dgram = message("/colony/heartbeat", int(status.get("ticks", 0)), int(status.get("late_ticks", 0)),
                        int(status.get("underruns", 0)), float(status["uptime"]))
        for target in self.targets:
            try:
                self.socket.sendto(dgram, target)
                self.sent += 1
            except OSError:
                self.send_errors += 1

    def close(self) -> None:
        self.socket.close()
