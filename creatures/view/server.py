"""The view's web server: aiohttp (HTTP and websockets in one library) on a thread and an
event loop of its own, never the creature's.

It serves the page (``static/``: plain HTML, JS and CSS in the package, no build step and
nothing fetched from elsewhere) and one websocket, ``/ws``, that sends the
:mod:`~creatures.view.snapshot` messages: the hello, then frames. A :class:`LiveSource` takes
what the run's :class:`~creatures.view.feed.Feed` queued; a :class:`ReplaySource` plays an
offline run's frames at their own times (looping, so a kiosk keeps showing it). Each browser
has a bounded queue of its own: live, a slow one drops frames (counted in ``/status``) and
never holds up another, nor the creatures; a replay waits for it instead (nothing is lost).

Loopback only: the server binds 127.0.0.1 and answers only requests whose ``Host`` names a
loopback address (a web page elsewhere cannot reach it through DNS rebinding).
"""

from __future__ import annotations

import asyncio
import logging
import socket
import threading
from pathlib import Path
from typing import Protocol

import orjson
from aiohttp import WSCloseCode, WSMsgType, web

from creatures.view.feed import Feed
from creatures.view.snapshot import Message, Replay, encode, trees

_log = logging.getLogger(__name__)

STATIC = Path(__file__).with_name("static")
HOST = "127.0.0.1"
LOOPBACK_NAMES = frozenset({"127.0.0.1", "localhost", "::1"})

CLIENT_QUEUE = 16
"""Encoded frames waiting for one browser; more are dropped for it and counted."""

MAX_CLIENTS = 32
"""Browsers served at once. Each costs a queue of :data:`CLIENT_QUEUE` frames and a send per
frame on the view's thread; a local script opening sockets in a loop would otherwise take
memory and the thread's time without bound. More are refused (503) and counted in /status."""

CLOSE_WAIT = 1.0
"""Seconds a browser is given to take the closing message when the view stops: one that has
stopped reading (a frozen kiosk tab, a stalled network) would keep the close waiting for room
in its socket for ever."""


def port_problem(port: int) -> str | None:
    """Why the view cannot serve on ``port`` (in use), or None: asked before a run starts, and
    bound as the server binds (``SO_REUSEADDR``: a port whose last browser left it in TIME_WAIT
    is free, one another program listens on is not)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((HOST, port))
        except OSError as exc:
            return f"the view's port {port} on {HOST} cannot be used ({exc.strerror}): choose another with --view PORT"
    return None


class Client:
    """One connected browser: its queue of encoded messages and what it missed."""

    def __init__(self) -> None:
        self.queue: asyncio.Queue[str] = asyncio.Queue(CLIENT_QUEUE)
        self.dropped = 0

    def offer(self, text: str) -> None:
        try:
            self.queue.put_nowait(text)
        except asyncio.QueueFull:
            self.dropped += 1


class Source(Protocol):
    """Where a view's messages come from."""

    def hello(self) -> Message: ...

    def greeting(self) -> list[str]:
        """Encoded messages a new browser is sent after the hello (the latest percept trees)."""

    async def run(self, clients: set[Client]) -> None:
        """Feed every client (live: all alike, as frames arrive)."""

    async def serve(self, client: Client) -> None:
        """Feed one client (a replay starts from its beginning for each)."""


class LiveSource:
    """A live run's frames, taken from its feed twice a frame period (the latest each time, with
    the records since) and sent to every browser; its percept trees whenever new ones are copied."""

    def __init__(self, feed: Feed, fps: float) -> None:
        # The percept trees' reader brings matplotlib with it: imported here, before the run,
        # not by the view's thread mid-run (it held the interpreter for a second there: late
        # ticks, and the feed's queue full before the first take).
        from creatures.runtime.inspect import knowledge

        self.knowledge = knowledge
        self.feed = feed
        self.period = 1.0 / fps
        self.trees: str | None = None  # the latest trees message, encoded
        self._states: object = None
        self.failed = 0  # frames that could not be made or sent (said, and in /status)

    def hello(self) -> Message:
        return self.feed.hello

    def greeting(self) -> list[str]:
        return [self.trees] if self.trees is not None else []

    async def run(self, clients: set[Client]) -> None:
        while True:
            await asyncio.sleep(self.period / 2)
            try:
                self._send(clients)
            except Exception as exc:  # noqa: BLE001 - a frame the view cannot make is skipped, said and counted
                self.failed += 1
                _log.warning("view: a frame could not be sent (%s: %s); %d skipped so far", type(exc).__name__,
                             exc, self.failed)

    def _send(self, clients: set[Client]) -> None:
        """The latest frame (and new percept trees) to every browser. An error here ended the
        feeding task silently: ``/status`` went on answering and no browser got a frame again."""
        latest = self.feed.take()
        texts = [] if latest is None else [encode(latest)]
        states = self.feed.states
        if states is not None and states is not self._states:
            self._states = states
            known = [self.knowledge(name, kind, orjson.loads(state)) for name, kind, state in states[1]]
            self.trees = encode(trees(states[0], known))
            texts.append(self.trees)
        for text in texts:
            for client in clients:
                client.offer(text)

    async def serve(self, client: Client) -> None:
        pass


class ReplaySource:
    """An offline run's frames at their clock times (× ``speed``), from the start for each
    browser, again and again (a ``restart`` message tells the page to clear its history)."""

    def __init__(self, replay: Replay, speed: float = 1.0, learned: Message | None = None) -> None:
        """``learned``: a ``trees`` message of what the run's creatures knew at its end."""
        self.replay = replay
        self.speed = speed
        self.encoded = [encode(f) for f in replay.frames]
        self.learned = None if learned is None else encode(learned)

    def hello(self) -> Message:
        return self.replay.hello

    def greeting(self) -> list[str]:
        return [self.learned] if self.learned is not None else []

    async def run(self, clients: set[Client]) -> None:
        pass

    async def serve(self, client: Client) -> None:
        loop = asyncio.get_running_loop()
        frames = self.replay.frames
        while True:
            start, t0 = loop.time(), frames[0]["t"]
            for message, text in zip(frames, self.encoded):
                delay = start + (message["t"] - t0) / self.speed - loop.time()
                if delay > 0:
                    await asyncio.sleep(delay)
                await client.queue.put(text)  # no creature waits on a replay: a slow browser slows it, loses nothing
            await asyncio.sleep(1.0)
            await client.queue.put(encode({"type": "restart"}))


class ViewServer:
    """The page and its websocket on ``127.0.0.1:port`` (0: any free port), on its own thread."""

    def __init__(self, source: Source, port: int = 0) -> None:
        self.source = source
        self.port = port
        self.clients: set[Client] = set()
        self._sockets: set[web.WebSocketResponse] = set()
        self.sent = 0
        self.refused = 0
        """Browsers turned away because :data:`MAX_CLIENTS` were connected."""
        self.left_dropped = 0
        """Frames dropped for browsers since gone: /status's count of a browser's drops must not
        fall when that browser leaves (a kiosk that reloads would hide what it lost)."""
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._stop: asyncio.Event | None = None
        self._ready = threading.Event()
        self._failure: BaseException | None = None

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.port}/"

    def start(self) -> ViewServer:
        """Bind and serve; an address in use raises OSError here, before the run starts."""
        self._thread = threading.Thread(target=self._main, name="creatures-view", daemon=True)
        self._thread.start()
        self._ready.wait(30)
        if self._failure is not None:
            raise self._failure
        return self

    def _main(self) -> None:
        self._loop = asyncio.new_event_loop()
        try:
            self._loop.run_until_complete(self._serve())
        except BaseException as exc:  # reported to start() (binding) or dropped at shutdown
            self._failure = exc
            self._ready.set()
        finally:
            self._loop.close()

    async def _serve(self) -> None:
        self._stop = asyncio.Event()
        app = web.Application(middlewares=[_loopback_only])
        app.router.add_get("/", _page)
        app.router.add_get("/ws", self._socket)
        app.router.add_get("/status", self._status)
        app.router.add_get("/favicon.ico", _no_icon)
        app.router.add_static("/static/", STATIC)
        # A kiosk's browser stays connected when the run ends: its socket is closed ("going
        # away"; the page reconnects when a run serves again) and what is left is given a second.
        runner = web.AppRunner(app, access_log=None, handle_signals=False, shutdown_timeout=1.0)
        await runner.setup()
        try:
            # SO_REUSEADDR: the connections a browser left in TIME_WAIT (a minute, on the server's
            # side, which closes first) must not keep a restarted run off its port; on Linux it
            # still refuses a port another socket listens on.
            site = web.TCPSite(runner, HOST, self.port, reuse_address=True)
            await site.start()
            self.port = runner.addresses[0][1]
            self._ready.set()
            feeding = asyncio.create_task(self.source.run(self.clients))
            await self._stop.wait()
            feeding.cancel()
            await asyncio.gather(*(asyncio.wait_for(ws.close(code=WSCloseCode.GOING_AWAY, message=b"the colony stopped"),
                                                    CLOSE_WAIT)
                                   for ws in list(self._sockets)), return_exceptions=True)
        finally:
            await runner.cleanup()

    async def _status(self, _: web.Request) -> web.Response:
        feed = getattr(self.source, "feed", None)
        return web.json_response({"clients": len(self.clients), "sent": self.sent,
                                  "client_dropped": self.left_dropped + sum(c.dropped for c in self.clients),
                                  "dropped": feed.dropped if feed is not None else 0,
                                  "events_dropped": feed.events_dropped if feed is not None else 0,
                                  "failed": getattr(self.source, "failed", 0), "refused": self.refused})

    async def _socket(self, request: web.Request) -> web.WebSocketResponse:
        if len(self._sockets) >= MAX_CLIENTS:
            self.refused += 1
            raise web.HTTPServiceUnavailable(text=f"the view serves {MAX_CLIENTS} browsers at once; close one")
        ws = web.WebSocketResponse(heartbeat=20.0, compress=False)  # loopback: deflate would only cost CPU
        await ws.prepare(request)
        self._sockets.add(ws)
        client = Client()
        # The greeting goes first into the browser's own queue (room for it: the queue is new),
        # so one sender writes to it and a browser gone before its hello is let go like any other.
        for text in (encode(self.source.hello()), *self.source.greeting()):
            client.offer(text)
        self.clients.add(client)
        feeding = asyncio.create_task(self.source.serve(client))
        sending = asyncio.create_task(self._send(ws, client))
        try:
            async for message in ws:  # the page only listens; this notices it going away
                if message.type == WSMsgType.ERROR:
                    break
        finally:
            self._sockets.discard(ws)
            self.clients.discard(client)
            self.left_dropped += client.dropped
            feeding.cancel()
            sending.cancel()
        return ws

    async def _send(self, ws: web.WebSocketResponse, client: Client) -> None:
        while not ws.closed:
            text = await client.queue.get()
            try:
                await ws.send_str(text)
            except ConnectionError:  # the browser went away mid-frame: its socket handler ends it
                return
            self.sent += 1

    def close(self) -> None:
        if self._loop is not None and self._stop is not None and self._thread is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
            self._thread.join(10)


async def _page(_: web.Request) -> web.FileResponse:
    return web.FileResponse(STATIC / "index.html")


async def _no_icon(_: web.Request) -> web.Response:
    return web.Response(status=204)


@web.middleware
async def _loopback_only(request: web.Request, handler) -> web.StreamResponse:
    host = request.url.host or ""  # the Host header's name, without its port
    if host not in LOOPBACK_NAMES:
        raise web.HTTPForbidden(text=f"the creatures' view answers only on loopback, not for host {host!r}")
    return await handler(request)
