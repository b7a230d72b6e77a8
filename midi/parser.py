"""Framing a raw MIDI byte stream into messages, with running status.

A live stream (a serial line, a USB-MIDI dump, a UDP relay) may leave out the status byte of
repeated channel messages ("running status"): ``90 3C 64 3E 64`` is two note-ons. mido's
``Parser`` returned only one message for that stream on this machine (ENVIRONMENT.md), so the
framing is done here and only complete, status-ful messages go to mido for decoding
(``mido.Message.from_bytes``: mido stays the one place that knows message layouts).

Bytes that cannot belong to a message — data bytes with no status, a message cut short by
the next status byte, undefined status bytes — are dropped and counted in
:attr:`StreamParser.malformed_bytes`; the parser never raises on input.
"""

from __future__ import annotations

from collections import deque
from typing import Iterable

import mido

# Data bytes that follow each status byte; None marks bytes that cannot start a message here.
_DATA_LENGTH: list[int | None] = [None] * 256
for _status in range(0x80, 0xF0):
    _DATA_LENGTH[_status] = 1 if 0xC0 <= _status < 0xE0 else 2
for _status, _length in {0xF1: 1, 0xF2: 2, 0xF3: 1, 0xF6: 0, 0xF8: 0, 0xFA: 0, 0xFB: 0,
                         0xFC: 0, 0xFE: 0, 0xFF: 0}.items():
    _DATA_LENGTH[_status] = _length

MAX_SYSEX = 65_536  # bytes; a longer "sysex" is a stuck stream, not a message


class StreamParser:
    """Feed bytes in any chunking; take whole :class:`mido.Message` s out.

    Running status holds for channel messages (0x80–0xEF) and is cancelled by system common
    messages and sysex; real-time bytes (0xF8–0xFF) may arrive anywhere, even inside another
    message, and leave the message in progress untouched.
    """

    def __init__(self, *, max_sysex: int = MAX_SYSEX) -> None:
        self.messages: deque[mido.Message] = deque()
        self.malformed_bytes = 0
        self.max_sysex = max_sysex
        self._status: int | None = None  # status of the message being collected, or running
        self._needed = 0  # data bytes still missing for the message being collected
        self._data: list[int] = []
        self._fresh = False  # an explicit status byte is waiting for its data
        self._sysex: list[int] | None = None

    def feed(self, data: bytes | bytearray | Iterable[int]) -> None:
        """Take bytes; complete messages are appended to :attr:`messages`."""
        for byte in data:
            if byte < 0x80:
                self._data_byte(byte)
            elif byte >= 0xF8:
                if _DATA_LENGTH[byte] is None:
                    self.malformed_bytes += 1
                else:
                    self._emit([byte])
            else:
                self._status_byte(byte)

    def _data_byte(self, byte: int) -> None:
        if self._sysex is not None:
            if len(self._sysex) >= self.max_sysex:
                self.malformed_bytes += len(self._sysex) + 1
                self._sysex = None
            else:
                self._sysex.append(byte)
            return
        if self._status is None:
            self.malformed_bytes += 1
            return
        self._data.append(byte)
        if len(self._data) == self._needed:
            status = self._status
            self._emit([status, *self._data])
            self._data = []
            self._fresh = False
            if status >= 0xF0:
                self._status = None  # system common messages have no running status

    def _status_byte(self, byte: int) -> None:
        self._abandon()
        if byte == 0xF7:  # end of exclusive
            if self._sysex is None:
                self.malformed_bytes += 1
            else:
                self._emit([0xF0, *self._sysex, 0xF7])
                self._sysex = None
            return
        if self._sysex is not None:  # a status byte cuts an unterminated sysex short
            self.malformed_bytes += len(self._sysex) + 1
            self._sysex = None
        self._status = None
        if byte == 0xF0:
            self._sysex = []
            return
        length = _DATA_LENGTH[byte]
        if length is None:
            self.malformed_bytes += 1
        elif length == 0:
            self._emit([byte])
        else:
            self._status, self._needed, self._fresh = byte, length, True

    def _abandon(self) -> None:
        """Drop a message left incomplete by a new status byte (its status byte too, if sent)."""
        self.malformed_bytes += len(self._data) + self._fresh
        self._data = []
        self._fresh = False

    def _emit(self, raw: list[int]) -> None:
        self.messages.append(mido.Message.from_bytes(raw))

    def pending(self) -> list[mido.Message]:
        """Take every complete message parsed so far."""
        out = list(self.messages)
        self.messages.clear()
        return out
