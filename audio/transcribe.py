"""Heard audio → note events, as it streams: how audio-only installations hear notes.

A creature that listens to notes (exchange, listen, sand:stone) should hear a flute or a voice
as readily as a MIDI keyboard. The recording (or microphone) is cut into sound events by the
same :class:`audio.segment.Segmenter` the cepstral ear uses, and each event that ends is
pitch-tracked into notes (:func:`audio.pitch.note_events`); unpitched sounds give none. A note
is known only once its sound event has ended, so it reaches the creatures up to
``max_length`` seconds after it began (events longer than that are cut).

A decaying note can fall below the segmenter's threshold, or lose voicing for a frame, and
come back as a second run of the same pitch that starts where the first ended. Without a new
attack that is the same note's tail, so it is not heard again (measured on rendered phrases:
3 of 21 notes were otherwise heard twice).
"""

from __future__ import annotations

import numpy as np

from audio.pitch import note_events
from audio.segment import Segmenter, SoundEvent
from midi.notes import NoteEvent

TAIL_GAP = 0.05
"""Seconds: a same-pitch run starting this close to the previous note's end is its tail."""


class Transcriber:
    """Streams audio blocks in, gives the notes of every sound event that ended."""

    def __init__(self, samplerate: int, *, t0: float = 0.0, max_length: float = 2.0) -> None:
        self.segmenter = Segmenter(samplerate, t0=t0, max_length=max_length, name="transcription")
        self.events = 0  # sound events heard
        self.notes = 0  # notes found in them
        self._end = -float("inf")  # when the last note (with its tails) ended
        self._pitch = -1

    def feed(self, block: np.ndarray) -> list[NoteEvent]:
        """The notes of the sound events that ended within ``block``, in time order."""
        return self._notes(self.segmenter.feed(block))

    def _notes(self, events: list[SoundEvent]) -> list[NoteEvent]:
        notes = []
        for note in (note for event in events for note in note_events(event)):
            tail = note.pitch == self._pitch and note.time - self._end < TAIL_GAP
            self._end, self._pitch = note.time + note.duration, note.pitch
            if not tail:
                notes.append(note)
        self.events += len(events)
        self.notes += len(notes)
        return notes
