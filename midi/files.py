"""Standard MIDI files in and out as :class:`~midi.notes.NoteEvent` lists.

Times inside a file are ticks whose length changes with every tempo change; creatures live
in seconds. :class:`TempoMap` converts both ways (``mido.tick2second`` applied to arrays, segment by
segment). Files are written as type 1 — a tempo-map
track, then one track per channel (or one merged track) — which every DAW opens, and saved
atomically through :func:`creatures.persist.atomic_write`. A track sounds one note per key at a
time (:func:`midi.notes.restrike`), so overlapping notes of one pitch come back with the
earlier one ending where the later one starts.

mido raises an assortment of exceptions on bad files (``OSError``, ``EOFError``,
``ValueError``, ``KeyError``, ``IndexError``); :func:`read_notes` turns every one of them into
a :class:`MidiFileError` that names the file.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Iterable

import mido
import numpy as np

from creatures.bounds import LATEST_TIME
from creatures.persist import atomic_write
from midi import smf
from midi.notes import NoteEvent, TimedMessage, from_messages, restrike, to_messages

DEFAULT_TEMPO = 500_000  # microseconds per beat: 120 bpm, the MIDI file default

MAX_MIDI_BYTES = 64 * 1024 * 1024
"""Largest MIDI file read (a long performance is a few megabytes)."""


class MidiFileError(Exception):
    """A MIDI file is missing, truncated or malformed; the message names the file."""


TICKS_PER_BEAT = 960
"""Ticks a beat of the files written: a note is placed within half a tick, 0.5 ms at 60 bpm and
0.8 ms at 40 (at 480, a slow heard pulse put notes up to 1.6 ms off where they were played)."""


class TempoMap:
    """Piecewise-linear map between ticks and seconds.

    ``changes`` are ``(tick, tempo)`` pairs (tempo in microseconds per beat); before the first
    change the tempo is 120 bpm, as the MIDI file standard says.
    """

    def __init__(self, ticks_per_beat: int, changes: Iterable[tuple[int, int]] = ()) -> None:
        if ticks_per_beat <= 0:
            raise ValueError(f"ticks_per_beat must be positive, got {ticks_per_beat}")
        self.ticks_per_beat = ticks_per_beat
        points: dict[int, int] = {0: DEFAULT_TEMPO}
        for tick, tempo in sorted(changes, key=lambda c: c[0]):
            if not tempo > 0 or not tick >= 0:
                raise ValueError(f"tempo change ({tick}, {tempo}): tick must be >= 0 and tempo > 0")
            points[int(tick)] = int(tempo)  # the last change at a tick wins
        self.ticks = np.array(sorted(points), dtype=np.int64)
        self.tempos = np.array([points[t] for t in self.ticks], dtype=np.float64)
        spans = np.diff(self.ticks) * self.tempos[:-1] * 1e-6 / ticks_per_beat
        self.seconds = np.concatenate([[0.0], np.cumsum(spans)])

    @classmethod
    def from_seconds(
        cls, ticks_per_beat: int, changes: Iterable[tuple[float, float]]
    ) -> TempoMap:
        """Build a map from ``(seconds, bpm)`` changes, each placed on the nearest tick."""
        built = cls(ticks_per_beat)
        for seconds, bpm in sorted(changes):
            if not bpm > 0:
                raise ValueError(f"tempo change at {seconds} s: bpm must be > 0, got {bpm}")
            tick = int(built.to_ticks(np.array([seconds]))[0])
            built = cls(ticks_per_beat, [*built.changes(), (tick, mido.bpm2tempo(bpm))])
        return built

    def changes(self) -> list[tuple[int, int]]:
        return [(int(t), int(q)) for t, q in zip(self.ticks, self.tempos)]

    def to_seconds(self, ticks: np.ndarray) -> np.ndarray:
        ticks = np.asarray(ticks, dtype=np.float64)
        i = np.searchsorted(self.ticks, ticks, side="right") - 1
        return self.seconds[i] + mido.tick2second(ticks - self.ticks[i], self.ticks_per_beat, self.tempos[i])

    def to_ticks(self, seconds: np.ndarray) -> np.ndarray:
        """Nearest whole tick for each time in ``seconds``."""
        seconds = np.asarray(seconds, dtype=np.float64)
        i = np.searchsorted(self.seconds, seconds, side="right") - 1
        # mido.second2tick rounds to a Python int, so its formula is inlined for arrays.
        seconds_per_tick = self.tempos[i] * 1e-6 / self.ticks_per_beat
        return np.rint(self.ticks[i] + (seconds - self.seconds[i]) / seconds_per_tick).astype(np.int64)


def _read_capped(path: Path) -> bytes:
    """The file's bytes, refused past :data:`MAX_MIDI_BYTES` having read at most one byte more.

    Both readers take these bytes: :mod:`midi.smf` read the whole file by itself, so a valid
    header and track followed by gigabytes (a runaway recorder, a sparse file) were read into
    memory, and accepted, past the cap mido's path kept.
    """
    try:
        with open(path, "rb") as handle:
            raw = handle.read(MAX_MIDI_BYTES + 1)
    except FileNotFoundError:
        raise MidiFileError(f"{path}: MIDI file not found") from None
    except OSError as exc:
        raise MidiFileError(f"{path}: cannot read the MIDI file ({exc.strerror or exc})") from None
    if (kind := _sound_kind(raw)) is not None:  # a long recording is past the cap: said as what it is
        raise MidiFileError(f"{path}: a {kind} sound file, not a MIDI file (an offline run takes sound with --audio)")
    if len(raw) > MAX_MIDI_BYTES:
        raise MidiFileError(f"{path}: MIDI file larger than {MAX_MIDI_BYTES} bytes; refused")
    if not raw:  # mido says "truncated … inside a chunk" of a file that has no chunk
        raise MidiFileError(f"{path}: empty file (0 bytes)")
    return raw


def _open(path: Path, data: bytes) -> mido.MidiFile:
    """``data`` (the file's bytes) read by mido, every error of its turned into a MidiFileError."""
    try:
        return mido.MidiFile(file=io.BytesIO(data))
    except EOFError:
        raise MidiFileError(f"{path}: truncated MIDI file (ended inside a chunk)") from None
    except (OSError, ValueError, KeyError, IndexError, TypeError) as exc:
        raise MidiFileError(f"{path}: malformed MIDI file ({exc or type(exc).__name__})") from None


SOUND_FILES = ((b"RIFF", b"WAVE", "WAV"), (b"RF64", b"WAVE", "WAV"), (b"FORM", b"AIFF", "AIFF"),
               (b"FORM", b"AIFC", "AIFF"), (b"fLaC", b"", "FLAC"), (b"OggS", b"", "Ogg"), (b"ID3", b"", "MP3"))
"""How sound files begin (their first bytes, the form at byte 8, their name): a render given
where its MIDI file belongs was a "malformed MIDI file (MThd not found…)", as if damaged."""


def _sound_kind(raw: bytes) -> str | None:
    """The kind of sound file ``raw`` begins as, or None."""
    return next((name for magic, form, name in SOUND_FILES if raw.startswith(magic) and raw[8:12].startswith(form)),
                None)


def _load(path: Path) -> smf.Events | mido.MidiFile:
    """The file parsed by :mod:`midi.smf` (arrays, no message objects), or by mido where that
    reader declines it (then every error is mido's, turned into a MidiFileError as before).
    The one fault :mod:`midi.smf` names itself (:class:`midi.smf.TrackError`) is told with the path."""
    raw = _read_capped(path)
    try:
        events = smf.parse(raw)
    except smf.TrackError as exc:
        raise MidiFileError(f"{path}: {exc}") from None
    midi = _open(path, raw) if events is None else events
    _check_division(path, midi.ticks_per_beat)
    return midi


def _check_division(path: Path, division: int) -> None:
    """Refuse a header division no tick can be timed by, saying which of two faults it is.

    Both readers unpack the division as a signed short: SMPTE time codes (top bit set) come out
    negative. A division of 0 is not SMPTE but a broken header (0 ticks per beat), and saying
    "SMPTE" sent its author looking for the wrong fault.
    """
    if division < 0:
        raise MidiFileError(f"{path}: SMPTE time division is not supported")
    if division == 0:
        raise MidiFileError(f"{path}: ticks per beat 0 in the header (must be 1..32767)")


def _tempo_map(path: Path, ticks_per_beat: int, changes: Iterable[tuple[int, int]]) -> TempoMap:
    try:
        return TempoMap(ticks_per_beat, changes)
    except ValueError as exc:
        raise MidiFileError(f"{path}: bad tempo map ({exc})") from None


def _timed_groups(path: Path, events: smf.Events) -> Iterable[tuple[np.ndarray, np.ndarray]]:
    """Per tempo group (the whole file, or each track of a type 2 file): the indices of its
    channel messages in time order and their times in seconds."""
    groups = [np.arange(events.n_tracks)] if events.type != 2 else [np.array([t]) for t in range(events.n_tracks)]
    for tracks in groups:
        # Channel messages are in file order (track by track), as read_messages' stable sort wants.
        chosen = np.flatnonzero(np.isin(events.track, tracks))
        order = chosen[np.argsort(events.tick[chosen], kind="stable")]
        tempos = np.flatnonzero(np.isin(events.tempo_track, tracks))
        tempos = tempos[np.argsort(events.tempo_tick[tempos], kind="stable")]
        tempo = _tempo_map(path, events.ticks_per_beat, zip(events.tempo_tick[tempos].tolist(), events.tempo[tempos].tolist()))
        yield order, tempo.to_seconds(events.tick[order])


def _events_in_time(path: Path, events: smf.Events) -> tuple[np.ndarray, np.ndarray]:
    """All channel messages' indices and times, in time order (type 2 tracks interleaved)."""
    parts = list(_timed_groups(path, events))
    order = np.concatenate([o for o, _ in parts] or [np.zeros(0, np.int64)])
    seconds = np.concatenate([t for _, t in parts] or [np.zeros(0)])
    by_time = np.argsort(seconds, kind="stable")
    _check_latest(path, seconds[by_time])
    return order[by_time], seconds[by_time]


def _check_latest(path: Path, seconds: np.ndarray) -> None:
    """Refuse a file with a message past :data:`creatures.bounds.LATEST_TIME` (``seconds`` in
    time order), saying when it falls.

    Deltas of up to 2^28 ticks at one tick a beat and 16.7 s a beat reach 4.5e9 s each, and
    :class:`midi.notes.NoteEvent` refused such a note with a ValueError that no caller of
    :func:`read_notes` expects: ``creatures offline --midi`` ended in a traceback.
    """
    if len(seconds) and not seconds[-1] <= LATEST_TIME:
        late = int(np.argmax(~(seconds <= LATEST_TIME)))
        raise MidiFileError(f"{path}: {len(seconds) - late} messages fall past {LATEST_TIME:g} s, the latest time a "
                            f"run can hear (the first at {seconds[late]:.4g} s): a damaged delta time or tempo?")


def read_messages(path: str | os.PathLike) -> list[TimedMessage]:
    """All channel messages of a ``.mid`` file with their times in seconds, in time order.

    Type 0/1 files share one tempo map (set-tempo events on any track); each track of a type 2
    file keeps its own.
    """
    path = Path(path)
    midi = _load(path)
    if isinstance(midi, smf.Events):
        order, seconds = _events_in_time(path, midi)
        return [(t, mido.Message.from_bytes(midi.message_bytes(k))) for t, k in zip(seconds.tolist(), order.tolist())]
    return _mido_messages(path, midi)


def _mido_messages(path: Path, midi: mido.MidiFile) -> list[TimedMessage]:
    """read_messages for a file only mido reads."""
    groups = [midi.tracks] if midi.type != 2 else [[track] for track in midi.tracks]
    timed: list[TimedMessage] = []
    for group in groups:
        # mido.merge_tracks copies every message twice; a stable sort of absolute ticks gives
        # the same order (track by track at equal ticks) without copies.
        messages = [msg for track in group for msg in track]
        ticks = np.concatenate([np.cumsum([m.time for m in track], dtype=np.int64) for track in group] or [[]])
        order = np.argsort(ticks, kind="stable")
        tempo = _tempo_map(path, midi.ticks_per_beat,
                           [(ticks[i], messages[i].tempo) for i in order if messages[i].type == "set_tempo"])
        seconds = tempo.to_seconds(ticks[order])
        for t, i in zip(seconds.tolist(), order.tolist()):
            msg = messages[i]
            if not msg.is_meta and msg.type != "sysex":
                msg.time = 0  # the time is the pair's first element; the file's own copy is ours
                timed.append((t, msg))
    timed.sort(key=lambda item: item[0])  # stable: type 2 tracks interleave by time only
    _check_latest(path, np.array([t for t, _ in timed]))
    return timed


def read_notes(path: str | os.PathLike) -> list[NoteEvent]:
    """The notes of a ``.mid`` file, sorted by start time (see :func:`read_messages`).

    Raises :class:`MidiFileError` naming the file when it is missing or malformed.
    """
    path = Path(path)
    midi = _load(path)
    if not isinstance(midi, smf.Events):
        return from_messages(_mido_messages(path, midi))
    order, seconds = _events_in_time(path, midi)
    columns = smf.pair_notes(seconds, midi.status[order], midi.data1[order], midi.data2[order])
    return [NoteEvent(*note) for note in zip(*(column.tolist() for column in columns))]


def write_messages(
    path: str | os.PathLike,
    timed: Iterable[TimedMessage],
    *,
    tempo: TempoMap | None = None,
    split_channels: bool = True,
) -> None:
    """Write timed channel messages to a type 1 ``.mid`` file, atomically.

    Track 0 holds the tempo map; then one track per channel used (``split_channels``) or one
    track with everything.
    """
    tracks: dict[int, list[TimedMessage]] = {}
    for item in timed:
        tracks.setdefault(getattr(item[1], "channel", 0) if split_channels else 0, []).append(item)
    write_tracks(path, [(f"channel {key + 1}" if split_channels else "notes", tracks[key]) for key in sorted(tracks)],
                 tempo=tempo)


def write_tracks(
    path: str | os.PathLike,
    tracks: Iterable[tuple[str, list[TimedMessage]]],
    *,
    tempo: TempoMap | None = None,
) -> None:
    """Write named tracks of timed messages to a type 1 ``.mid`` file, atomically, after a
    first track holding the tempo map.

    Each track is put in time order, keeping the given order at equal times: a sink keeps
    messages in the order they were sent, and a note a creature played in the past (sent late,
    stamped with its own time) came after later ones, a negative delta mido refused when
    saving, so the whole ``out.mid`` of the run was lost.

    A key struck again while it sounds is re-struck (:func:`midi.notes.restrike`: note-off then
    note-on at the same tick), on the ticks written: the ``input`` track's overlapping notes of
    one key were written on, on, off, off, which synths and DAWs play as a second note cut
    short by the first's end (or a hanging note), and two times that round to one tick (a
    note starting a hair before the previous one of its key ends) must keep the new note."""
    tempo = tempo or TempoMap(TICKS_PER_BEAT)
    midi = mido.MidiFile(type=1, ticks_per_beat=tempo.ticks_per_beat)
    midi.tracks.append(_track("tempo", [(t, mido.MetaMessage("set_tempo", tempo=q)) for t, q in tempo.changes()]))
    for name, timed in tracks:
        ticks = tempo.to_ticks(np.array([t for t, _ in timed], dtype=np.float64))
        order = np.argsort(ticks, kind="stable").tolist()
        midi.tracks.append(_track(name, restrike([(int(ticks[i]), timed[i][1]) for i in order])))
    atomic_write(Path(path), lambda handle: midi.save(file=handle), "wb")


def write_notes(
    path: str | os.PathLike,
    notes: Iterable[NoteEvent],
    *,
    tempo: TempoMap | None = None,
    split_channels: bool = True,
) -> None:
    """Write notes to a type 1 ``.mid`` file, atomically (see :func:`write_messages`)."""
    write_messages(path, to_messages(notes), tempo=tempo, split_channels=split_channels)


MAX_DELTA = 0x0FFFFFFF
"""The longest delta time a Standard MIDI File can say: a variable-length quantity of at most
four bytes (some 39 hours at 960 ticks a beat and 120 bpm)."""


def _track(name: str, events: list[tuple[int, mido.Message]]) -> mido.MidiTrack:
    """A track from absolute-tick events (already in time order), with delta times.

    A longer pause than :data:`MAX_DELTA` is bridged by empty text events, each that far
    apart: mido wrote the delta in five bytes, which the SMF standard does not allow (a track
    of a live run silent over a long weekend, then playing, was unreadable to a DAW).
    """
    track = mido.MidiTrack([mido.MetaMessage("track_name", name=name)])
    previous = 0
    for tick, msg in events:
        while tick - previous > MAX_DELTA:
            track.append(mido.MetaMessage("text", text="", time=MAX_DELTA))
            previous += MAX_DELTA
        track.append(msg.copy(time=tick - previous))
        previous = tick
    track.append(mido.MetaMessage("end_of_track", time=0))
    return track
