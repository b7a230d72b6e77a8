"""The colony's one beat and tempo across processes: Ableton Link (``[room.share] link``),
through aalink, the existing engine (the issue: "an existing engine: aalink or
linkpython-extern").

aalink wants an asyncio loop; a live run has none on the creature's thread, so Link lives in
a loop of its own on a daemon thread, and the creature's thread only reads two numbers from it
(Link's session state is safe to capture from any thread). :meth:`LinkBeat.beat_at` turns a
Unix time into a beat on the shared timeline: what stamps positions and notes across machines
whose clocks need not agree.
"""

from __future__ import annotations

import asyncio
import threading
import time
from typing import Any

START_TIMEOUT = 5.0
"""Seconds to wait for Link to start on its thread before the run goes on without it."""


class LinkUnavailable(RuntimeError):
    """aalink is not installed or Link would not start; the message says what to do."""


class LinkBeat:
    """A Link session at ``tempo`` BPM (joining one already on the network takes its tempo)."""

    def __init__(self, tempo: float) -> None:
        try:
            import aalink
        except ImportError:
            raise LinkUnavailable("[room.share] link = true needs the aalink package (pip install aalink); "
                                  "running without a shared beat") from None
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="ableton link", daemon=True)
        self._thread.start()

        async def start() -> Any:
            link = aalink.Link(tempo)
            link.enabled = True
            return link

        try:
            self._link = asyncio.run_coroutine_threadsafe(start(), self._loop).result(START_TIMEOUT)
        except Exception as exc:
            self.close()
            raise LinkUnavailable(f"Ableton Link did not start ({exc}); running without a shared beat") from None

    @property
    def tempo(self) -> float:
        return float(self._link.tempo)

    @property
    def peers(self) -> int:
        return int(self._link.num_peers)

    def beat_at(self, unix: float) -> float:
        """The beat of the shared timeline at Unix time ``unix`` (a moment ago or soon)."""
        beat, now = float(self._link.beat), time.time()
        return beat + (unix - now) * self.tempo / 60.0

    def close(self) -> None:
        """Leave the session and drop Link on its own loop's thread (a Link destroyed from
        another thread, or left to the interpreter's exit, may abort the process)."""
        if hasattr(self, "_link"):
            async def leave() -> None:
                self._link.enabled = False
                del self._link

            try:
                asyncio.run_coroutine_threadsafe(leave(), self._loop).result(START_TIMEOUT)
            except Exception:  # noqa: BLE001 - leaving is best effort; the process is ending
                pass
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=START_TIMEOUT)
