"""A live run's ``out.mid`` (``creatures run --out DIR``): the same score an offline run writes.

The score is :func:`creatures.runtime.score.write_score`'s: the input track, a named track per
creature opening with its program and pan, the heard tempo. During the show the creature's
thread only appends each message it sends, and the world each note it hears, to bounded
deques (O(1), nothing written): a run of weeks keeps the latest :data:`KEPT` of each, and the
summary says when older ones went. When the show ends the score is written and published
by a thread of its own, beside the final save, into a staging folder and then into ``DIR``
all or none, as offline outputs are (:mod:`creatures.runtime.outputs`): ``DIR`` is locked
for the run, checked before it starts (a folder that cannot be written, or an ``out.mid``
there that no run wrote, stops the run before anything plays), and a failure keeps the
previous ``out.mid``. It replaces ``out.mid`` alone: published as a whole run's outputs, it
removed what an offline run had written there (its ``events.jsonl``, ``out.wav``, ``report/``
and the learned ``state/``) when the show ended.
"""

from __future__ import annotations

import threading
from collections import deque
from pathlib import Path
from typing import Callable, Protocol

import mido

from creatures.lock import FolderLock
from creatures.runtime.outputs import OutputDirectoryError, discard, hold, publish, recover, refuse_foreign, stage
from creatures.runtime.score import write_score
from creatures.runtime.world import World
from midi.notes import TimedMessage

KEPT = 1 << 20
"""Messages (and heard notes) kept for the score: about twelve hours at 20 notes a second."""

NAME = "out.mid"


class Sink(Protocol):
    def send(self, time: float, msg: mido.Message) -> None: ...


class RecordingSink:
    """Sends on to ``sink`` and keeps each message with its due time (the latest ``keep``)."""

    def __init__(self, sink: Sink, keep: int = KEPT) -> None:
        self.sink = sink
        self.messages: deque[TimedMessage] = deque(maxlen=keep)
        self.sent = 0

    def send(self, time: float, msg: mido.Message) -> None:
        self.sink.send(time, msg)
        self.messages.append((time, msg))
        self.sent += 1


class LiveScore:
    """``DIR/out.mid`` for one live run: held and checked now, written by :meth:`finish`."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.lock: FolderLock = hold(out)
        try:
            recover(out)
            refuse_foreign(out, {NAME}, {NAME})
        except BaseException:
            self.lock.release()
            raise
        self._writer: threading.Thread | None = None

    def finish(self, world: World, recorded: RecordingSink, origin: float, say: Callable[[str], None]) -> None:
        """Start writing the score (times from ``origin``, the run's start on the creatures'
        clock) on a thread of its own; :meth:`wait` ends it."""
        self._writer = threading.Thread(target=self._write, args=(world, recorded, origin, say),
                                        name="out.mid", daemon=True)
        self._writer.start()

    def wait(self) -> None:
        """The score is published (or its failure said), and ``DIR`` let go."""
        try:
            if self._writer is not None:
                self._writer.join()
        finally:
            self.lock.release()

    def _write(self, world: World, recorded: RecordingSink, origin: float, say: Callable[[str], None]) -> None:
        try:
            staged = stage(self.out)
            try:
                write_score(staged / NAME, world, list(recorded.messages), origin)
                publish(staged, self.out, replaces={NAME})  # an offline run's other outputs there stay
            finally:
                discard(staged)
        except (OSError, OutputDirectoryError) as exc:
            say(f"could not write {self.out / NAME} ({exc}); the previous one, if any, is kept")
            return
        older = recorded.sent - len(recorded.messages)
        say(f"wrote {self.out / NAME}" + (f" (its last {len(recorded.messages)} messages: {older} older ones "
                                          f"were not kept)" if older else ""))
