"""Where creatures' notes go: a live port, a ``.mid`` file, or a list in memory.

Every sink has ``send(time, msg)``: the :class:`midi.scheduler.NoteScheduler` calls it when a
message falls due, with the clock time it was due at. The same creature can therefore play to
a synthesizer, record a ``.mid`` for a DAW, or be checked note by note in a test.
"""

from __future__ import annotations

import os
from typing import Protocol

import mido

from midi.files import TempoMap, write_messages
from midi.notes import NoteEvent, TimedMessage, from_messages
from midi.ports import ResilientPort


class NoteSink(Protocol):
    def send(self, time: float, msg: mido.Message) -> None: ...


class MemorySink:
    """Keeps every timed message it is sent, in order."""

    def __init__(self) -> None:
        self.messages: list[TimedMessage] = []

    def send(self, time: float, msg: mido.Message) -> None:
        self.messages.append((time, msg))

    def notes(self) -> list[NoteEvent]:
        return from_messages(self.messages)


class PortSink:
    """A live output port: an open mido port, or a :class:`ResilientPort` that drops (and
    counts) messages while its device is away."""

    def __init__(self, port: mido.ports.BaseOutput | ResilientPort) -> None:
        self.port = port

    def send(self, time: float, msg: mido.Message) -> None:
        self.port.send(msg)

    def close(self) -> None:
        self.port.close()


class FileSink(MemorySink):
    """Records to a type 1 ``.mid`` file, written atomically on :meth:`close`."""

    def __init__(
        self, path: str | os.PathLike, *, tempo: TempoMap | None = None, split_channels: bool = True
    ) -> None:
        super().__init__()
        self.path = path
        self.tempo = tempo
        self.split_channels = split_channels

    def close(self) -> None:
        write_messages(self.path, self.messages, tempo=self.tempo, split_channels=self.split_channels)

    def __enter__(self) -> FileSink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
