"""A compiled reader of Standard MIDI Files into arrays, for :mod:`midi.files`.

mido builds a Python object per message; a file of 100,000 notes is 200,000 of them, and
building them was most of the time :func:`midi.files.read_notes` took. Here the chunks
are walked by one numba kernel into flat arrays (track, tick, status and data bytes per
channel message; position of every meta event), and notes are paired from the arrays
(:func:`pair_notes`) without a message object in between.

The reader accepts exactly what mido accepts and reads it the same way, or declines: any
file it is not sure of (an undefined or system status byte, a message running past its chunk,
a delta longer than four bytes, a data byte above 127, a meta event mido would not decode, a
truncated chunk…) makes :func:`parse` return None and
:mod:`midi.files` reads that file with mido as before, so every error message stays mido's
(``tests/test_midi_files.py``, ``tests/test_fuzz_parsers.py``) and every accepted file
gives what mido gives (``tests/test_midi_smf.py`` compares both on fuzzed and written files).

One fault it names itself, as :class:`TrackError`: a data byte with no status after a sysex
event. The SMF spec says sysex and meta events cancel running status; mido took the byte as
running status *of the sysex* and read the next data byte as a sysex length, which ended in
"truncated MIDI file" for a whole chunk (or, worse, in a sysex of garbage and a misaligned
track). A meta event is let through, as mido lets it: many sequencers resume running status
after a tempo or text meta, and readers (mido's among them) accept those files, so refusing
them would refuse real music for a rule no reader enforces.
Meta events are few in a file (names, tempo, time and key signatures, end of track), so
each is decoded by mido's own ``build_meta_message``: its rules need no second copy here.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numba
import numpy as np
from mido.midifiles.meta import build_meta_message

from midi.notes import LONGEST_NOTE

MAX_MESSAGE_LENGTH = 1_000_000
"""mido's limit on a meta or sysex event's length (``mido.midifiles.midifiles``)."""

_OK, _DECLINE, _NO_STATUS = 0, 1, 2


class TrackError(ValueError):
    """A track fault this reader names itself (the caller adds the file's name)."""


@dataclass
class Events:
    """A parsed file: header fields, channel messages in file order, tempo changes."""

    type: int
    ticks_per_beat: int
    n_tracks: int
    track: np.ndarray  # (n,) int64: the track of each channel message
    tick: np.ndarray  # (n,) int64: its absolute tick within its track
    status: np.ndarray  # (n,) uint8
    data1: np.ndarray  # (n,) uint8
    data2: np.ndarray  # (n,) uint8 (0 for one-data-byte messages)
    tempo_track: np.ndarray  # (m,) int64: set_tempo events, file order
    tempo_tick: np.ndarray  # (m,) int64
    tempo: np.ndarray  # (m,) int64 microseconds per beat

    def message_bytes(self, k: int) -> list[int]:
        """The bytes of channel message ``k`` (status first), as mido decodes them."""
        status = int(self.status[k])
        if status & 0xF0 in (0xC0, 0xD0):
            return [status, int(self.data1[k])]
        return [status, int(self.data1[k]), int(self.data2[k])]


@numba.njit(cache=True)
def _vlq(data, pos):
    """A variable-length quantity at ``pos``: (value, next position), or (-1, pos) if it runs
    past the data or past four bytes (mido reads longer ones; this reader declines them)."""
    value = 0
    for count in range(4):
        if pos >= data.shape[0]:
            return -1, pos
        byte = data[pos]
        pos += 1
        value = (value << 7) | (byte & 0x7F)
        if byte < 0x80:
            return value, pos
    return -1, pos


@numba.njit(cache=True)
def _byte(data, pos):
    """The byte at ``pos`` and the next position, or (-1, pos) past the end."""
    if pos >= data.shape[0]:
        return -1, pos
    return np.int64(data[pos]), pos + 1


@numba.njit(cache=True)
def _walk(data, starts, ends, track, tick, status, data1, data2, meta_track, meta_tick, meta_kind, meta_start,
          meta_length, fault):
    """Walk every track chunk as mido's ``read_track`` does, filling the arrays; returns
    (channel messages, meta events, _OK, _DECLINE or _NO_STATUS). On _NO_STATUS ``fault`` holds
    the track and the file offset of the data byte that had no status."""
    n = data.shape[0]
    k = 0
    m = 0
    for t in range(starts.shape[0]):
        pos, end = starts[t], ends[t]
        now = 0
        last = -1
        while pos != end:
            if pos > end:
                return k, m, _DECLINE  # a message ran past its chunk
            delta, pos = _vlq(data, pos)
            if delta < 0 or pos >= n:
                return k, m, _DECLINE
            now += delta
            byte = data[pos]
            pos += 1
            first = -1
            if byte < 0x80:  # running status
                if last == 0xF0 or last == 0xF7:  # a sysex cancelled it (a meta does not: see above)
                    fault[0], fault[1] = t, pos - 1
                    return k, m, _NO_STATUS
                if last < 0 or last >= 0xF0:
                    return k, m, _DECLINE
                first = byte
                byte = last
            elif byte != 0xFF:
                last = byte
            if byte == 0xFF or byte == 0xF0 or byte == 0xF7:
                kind = 0
                if byte == 0xFF:
                    kind, pos = _byte(data, pos)
                length, pos = _vlq(data, pos)
                if kind < 0 or length < 0 or length > MAX_MESSAGE_LENGTH or pos + length > n:
                    return k, m, _DECLINE
                if byte == 0xFF:
                    meta_track[m], meta_tick[m], meta_kind[m] = t, now, kind
                    meta_start[m], meta_length[m] = pos, length
                    m += 1
                else:  # a sysex: mido refuses data bytes above 127 once F0 … F7 are stripped
                    lo, hi = pos, pos + length
                    if hi > lo and data[lo] == 0xF0:
                        lo += 1
                    if hi > lo and data[hi - 1] == 0xF7:
                        hi -= 1
                    for q in range(lo, hi):
                        if data[q] > 0x7F:
                            return k, m, _DECLINE
                pos += length
                continue
            if byte >= 0xF0:
                return k, m, _DECLINE  # system common / real-time inside a file: left to mido
            if first < 0:
                first, pos = _byte(data, pos)
            second = 0
            if (byte & 0xF0) != 0xC0 and (byte & 0xF0) != 0xD0:  # two data bytes
                second, pos = _byte(data, pos)
            if not (0 <= first <= 0x7F and 0 <= second <= 0x7F):  # past the end, or not a data byte
                return k, m, _DECLINE
            track[k], tick[k], status[k], data1[k], data2[k] = t, now, byte, first, second
            k += 1
    return k, m, _OK


def parse(raw: bytes) -> Events | None:
    """The file's channel messages and tempo changes, or None where mido must read it.

    Raises :class:`TrackError` for a data byte with no running status after a sysex event.
    """
    if len(raw) < 8:
        return None
    name, size = struct.unpack(">4sL", raw[:8])
    if name != b"MThd" or size < 6 or len(raw) < 14:
        return None
    file_type, n_tracks, ticks_per_beat = struct.unpack(">hhh", raw[8:14])
    starts, ends = [], []
    pos = 8 + size
    for _ in range(max(n_tracks, 0)):
        if pos + 8 > len(raw):
            return None
        name, size = struct.unpack(">4sL", raw[pos:pos + 8])
        if name != b"MTrk":
            return None
        starts.append(pos + 8)
        ends.append(pos + 8 + size)
        pos += 8 + size
    data = np.frombuffer(raw, dtype=np.uint8)
    capacity = len(raw) // 2 + 1  # every event takes at least two bytes
    track, tick = np.empty(capacity, np.int64), np.empty(capacity, np.int64)
    status, data1, data2 = (np.empty(capacity, np.uint8) for _ in range(3))
    meta_track, meta_tick, meta_kind, meta_start, meta_length = (np.empty(capacity, np.int64) for _ in range(5))
    fault = np.zeros(2, np.int64)
    k, m, verdict = _walk(data, np.array(starts, np.int64), np.array(ends, np.int64), track, tick, status,
                          data1, data2, meta_track, meta_tick, meta_kind, meta_start, meta_length, fault)
    if verdict == _NO_STATUS:
        raise _no_status(raw, int(fault[0]), int(fault[1]))
    if verdict != _OK:
        return None
    tempos: list[tuple[int, int, int]] = []
    for t, when, meta_type, start, length in zip(meta_track[:m].tolist(), meta_tick[:m].tolist(),
                                                 meta_kind[:m].tolist(), meta_start[:m].tolist(),
                                                 meta_length[:m].tolist()):
        try:
            msg = build_meta_message(meta_type, list(raw[start:start + length]))
        except Exception:  # mido's decoders raise what they raise; mido will say it
            return None
        if msg.type == "set_tempo":
            tempos.append((t, when, msg.tempo))
    tempo_track, tempo_tick, tempo = (np.array(column, np.int64) for column in (zip(*tempos) if tempos else ([], [], [])))
    return Events(file_type, ticks_per_beat, max(n_tracks, 0), track[:k], tick[:k], status[:k], data1[:k], data2[:k],
                  tempo_track, tempo_tick, tempo)


def _no_status(raw: bytes, track: int, at: int) -> TrackError:
    """The error for data byte ``raw[at]`` of track ``track`` (from 0) left without a status."""
    return TrackError(f"track {track + 1}, byte {at}: data byte 0x{raw[at]:02X} with no running status "
                      "(a sysex event cancels it)")


@numba.njit(cache=True)
def _pair(is_on, is_off, key, start_of, end, completed):
    """FIFO pairing of note-ons with note-offs per (channel, pitch) key, as
    :class:`midi.notes.NotePairer`: ``start_of[k]`` the message index of note ``k``'s on,
    ``end[k]`` its off's message index (-1 if still sounding at the end), ``completed[k]`` its
    rank among completed notes (-1 for the ones flushed); returns the number of notes."""
    n = is_on.shape[0]
    head = np.full(2048, -1, np.int64)
    tail = np.full(2048, -1, np.int64)
    following = np.full(n, -1, np.int64)
    note_of = np.full(n, -1, np.int64)
    notes = 0
    done = 0
    for i in range(n):
        q = key[i]
        if is_on[i]:
            note_of[i] = notes
            start_of[notes] = i
            end[notes] = -1
            completed[notes] = -1
            notes += 1
            if tail[q] < 0:
                head[q] = i
            else:
                following[tail[q]] = i
            tail[q] = i
        elif is_off[i] and head[q] >= 0:
            first = head[q]
            head[q] = following[first]
            if head[q] < 0:
                tail[q] = -1
            end[note_of[first]] = i
            completed[note_of[first]] = done
            done += 1
    return notes


def pair_notes(times: np.ndarray, status: np.ndarray, data1: np.ndarray, data2: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Notes from channel messages in time order (``times`` seconds), exactly as
    :func:`midi.notes.from_messages` pairs them: FIFO per channel and pitch, velocity-0
    note-ons end notes, notes still sounding end at the last message, sorted by (time,
    channel, pitch) with ties in the order ``from_messages`` leaves them.

    Returns ``(start, pitch, velocity, channel, duration)`` arrays; a note held past
    :data:`midi.notes.LONGEST_NOTE` is held that long."""
    kind = status & 0xF0
    is_on = (kind == 0x90) & (data2 > 0)
    is_off = (kind == 0x80) | ((kind == 0x90) & (data2 == 0))
    channel = (status & 0x0F).astype(np.int64)
    key = channel * 128 + data1
    size = int(is_on.sum())
    start_of, end_index, completed = (np.empty(size, np.int64) for _ in range(3))
    _pair(is_on, is_off, key, start_of, end_index, completed)
    last = float(times[-1]) if len(times) else 0.0
    start = times[start_of]
    end = np.where(end_index >= 0, times[np.maximum(end_index, 0)], last)
    flushed = completed < 0
    # from_messages: completed notes in completion order, then the flushed ones (each key's in
    # FIFO order, i.e. message order); then a stable sort by (time, channel, pitch).
    order = np.lexsort((np.where(flushed, start_of, completed), flushed, data1[start_of], channel[start_of], start))
    start_of = start_of[order]
    return (start[order], data1[start_of].astype(np.int64), data2[start_of].astype(np.int64), channel[start_of],
            np.clip(end[order] - start[order], 0.0, LONGEST_NOTE))  # as midi.notes._held
