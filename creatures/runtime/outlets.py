"""What a live run opens to the outside besides its music: the body stream (``[stream]``),
the remote console (``[console]``) and its health (``[health]``), each only when configured.

One place builds them from the config, hooks their creature-thread parts onto the loop's tick
boundaries (:attr:`TickLoop.boundary <creatures.runtime.ticking.TickLoop.boundary>`), starts
their threads and closes them, so ``creatures run`` (:mod:`creatures.runtime.live`) only
calls :class:`Outlets` and reads its counters.
"""

from __future__ import annotations

import errno
import socket
from typing import Any, Callable

from creatures.runtime.body_stream import BodyStream
from creatures.runtime.console import ColonyHandle, Console
from creatures.runtime.health import Health, HealthServer, Heartbeat
from creatures.runtime.schema import LoadedInstallation
from creatures.runtime.session import Session
from creatures.runtime.stream_sinks import OscStreamSink
from creatures.runtime.ticking import TickLoop
from creatures.supervisor import Supervisor


def address(peer: str) -> tuple[str, int]:
    """``host:port`` (checked at load: :func:`~creatures.runtime.schema.peer_problem`) resolved."""
    host, _, port = peer.rpartition(":")
    return socket.gethostbyname(host or "127.0.0.1"), int(port)


def _bound(inst: LoadedInstallation, section: str, open_it: Callable[[], Any]) -> Any:
    """``open_it()``, a port in use said as a :class:`ConfigError` at ``[section] port``; any
    other failure to bind is the host's (the host resolved at load, so it is no address of this
    machine: another port would fail alike), said at ``[section] host``."""
    try:
        return open_it()
    except OSError as exc:
        part = getattr(inst.settings, section)
        if exc.errno == errno.EADDRINUSE:
            raise inst.error((section, "port"), f"port {part.port} is already in use; "
                                                f"choose another [{section}] port") from None
        raise inst.error((section, "host"), f"cannot listen on {part.host}:{part.port} ({exc.strerror or exc}): "
                                            f"choose another [{section}] host, an address of this machine") from None


def check_apart(inst: LoadedInstallation, view: int | None = None) -> None:
    """No two of the run's listeners on one port: the OSC listener, the console and the shared
    room (UDP), the health endpoint and the view on ``view`` (TCP, on 127.0.0.1), where their addresses meet
    (the same one, or one of them every address, 0.0.0.0). Each port's own check binds it and
    lets it go, so such a clash would first be met by the run itself, its devices open."""
    settings = inst.settings
    share = settings.room.share if settings.room is not None else None
    listeners = [("osc", socket.SOCK_DGRAM, settings.osc.host, settings.osc.port),
                 ("console", socket.SOCK_DGRAM, settings.console.host, settings.console.port),
                 ("health", socket.SOCK_STREAM, settings.health.host, settings.health.port)]
    if share is not None and share.port:  # port 0 takes any free one: it meets no other
        listeners.append(("room.share", socket.SOCK_DGRAM, share.host, share.port))
    if view is not None:  # the view's module (aiohttp) imported only for a run that has one
        from creatures.view.server import HOST as VIEW_HOST

        listeners.append(("view", socket.SOCK_STREAM, VIEW_HOST, view))
    seen: list[tuple[str, int, str, int]] = []
    for section, kind, host, port in listeners:
        if port is None:
            continue
        address = socket.gethostbyname(host)  # resolved at load: a host that does not was said there
        for other, other_kind, other_address, other_port in seen:
            meet = address == other_address or "0.0.0.0" in (address, other_address)
            if (kind, port) == (other_kind, other_port) and meet:
                raise inst.error((*section.split("."), "port"), f"port {port} is [{other}] port too: each listens "
                                                                f"on a port of its own; choose another [{section}] port")
        seen.append((section, kind, address, port))


def check_ports(inst: LoadedInstallation) -> None:
    """The console's and health endpoint's ports bound and let go: one in use is said before the run."""
    settings = inst.settings
    for section, kind in (("console", socket.SOCK_DGRAM), ("health", socket.SOCK_STREAM)):
        part = getattr(settings, section)
        if part.port is not None:
            with socket.socket(socket.AF_INET, kind) as probe:
                if kind == socket.SOCK_STREAM:  # as http.server binds: a port in TIME_WAIT is free
                    probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                _bound(inst, section, lambda: probe.bind((part.host, part.port)))


class Outlets:
    """The stream, console and health of one live run.

    ``pause(on)`` pauses or resumes the colony, ``save(t)`` saves its state now (None: no
    state directory), ``status()`` says how the run is (ticks, late ticks, underruns, …).
    """

    def __init__(self, inst: LoadedInstallation, session: Session, loop: TickLoop, supervisor: Supervisor, *,
                 pause: Callable[[bool], None], save: Callable[[float], str] | None,
                 status: Callable[[], dict[str, Any]]) -> None:
        settings = inst.settings
        self.loop = loop
        self.status = status
        self.stream: BodyStream | None = None
        self._stream_sink: OscStreamSink | None = None
        if settings.stream.targets:
            self.stream = BodyStream(session.world, settings.stream.rate, start=loop.wall.now(),
                                     queue_size=settings.stream.queue)
            self._stream_sink = OscStreamSink([address(t) for t in settings.stream.targets])
            self.stream.subscribe(self._stream_sink)
            loop.boundary.append(self.stream.advance)
        self.console: Console | None = None
        if settings.console.port is not None:
            colony = ColonyHandle(session, pause=pause, save=save, status=status)
            self.console = _bound(inst, "console", lambda: Console(settings.console, colony))
            loop.boundary.append(self.console.serve)
            self.console.start()
        self.health = Health(supervisor)
        self.server: HealthServer | None = None
        if settings.health.port is not None:
            self.server = _bound(inst, "health", lambda: HealthServer(self.health, settings.health.host,
                                                                     settings.health.port))
        self.heartbeat: Heartbeat | None = None
        if settings.health.heartbeat:
            self.heartbeat = Heartbeat(self.health, [address(t) for t in settings.health.heartbeat])
            supervisor.every(settings.health.every, self.heartbeat.beat, name="heartbeat")

    def begin(self, start: float) -> None:
        """The run's first tick is at ``start``: the stream's frames count from there."""
        if self.stream is not None:
            self.stream.begin(start)

    def publish(self) -> None:
        """The run's status to the health endpoint and heartbeat (creatures' thread, once a second)."""
        self.health.publish(**self.status())

    def counts(self) -> dict[str, Any]:
        """Stream and console counters, for the status, the log and the summary."""
        counts: dict[str, Any] = {}
        if self.stream is not None:
            counts["stream"] = {**self.stream.counts(), "send_errors": self._stream_sink.send_errors,
                                "sent_bytes": self._stream_sink.sent_bytes}
        if self.console is not None:
            counts["console"] = self.console.summary()
        return counts

    def close(self) -> None:
        if self.console is not None:
            self.console.close()
        if self.stream is not None:
            self.stream.close()
        if self.server is not None:
            self.server.close()
        if self.heartbeat is not None:
            self.heartbeat.close()
