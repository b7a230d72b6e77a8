"""Polyphony for scanned strings: note events → voices, the oldest voice stolen when full.

A creature's motor system emits note events (thesis NoteObjects); each sounding note needs
its own string because the string's shape *is* the note's timbre. :class:`VoicePool` keeps
a fixed set of :class:`~audio.scanned.ScannedString` voices (allocated once, so a live
block never allocates) and hands a note-on to a free voice, or steals one: the quietest
already fading, else the one that started longest ago. A note's end starts a linear release
so an ended note does not click. A stolen voice's string is the new note's, so what it was
sounding moves to one more string kept aside (its shape, motion and scan copied), which fades
it out over :data:`STEAL_FADE`: cut where it stood, its last sample stepped to the new note's
first, a click at every steal of a full pool.
The voices are one :class:`~audio.string_bank.StringBank`: a block renders, envelopes and
mixes every sounding voice in one compiled call.
"""

from __future__ import annotations

import numpy as np

from audio.scanned import StringParameters
from audio.string_bank import StringBank


STEAL_FADE = 0.005
"""Seconds over which a stolen note fades out on the string kept aside for it."""


def midi_to_hz(pitch: float) -> float:
    """Equal-tempered frequency of a MIDI pitch (A4 = 69 = 440 Hz)."""
    return 440.0 * 2.0 ** ((pitch - 69.0) / 12.0)


class VoicePool:
    """``n_voices`` scanned strings sharing one parameter set; render sums them.

    Parameters
    ----------
    n_voices : int
        Maximum simultaneous notes.
    parameters : StringParameters
        String physics of every voice.
    sample_rate : float
        Audio rate.
    release : float
        Seconds of the linear fade after note-off (and when a voice is stolen).
    block_size : int
        Largest block :meth:`render` will be asked for (sizes the scratch buffer).
    """

    def __init__(self, n_voices: int = 8, parameters: StringParameters | None = None, *,
                 sample_rate: float = 48000.0, release: float = 0.2, block_size: int = 1024) -> None:
        if n_voices < 1:
            raise ValueError(f"n_voices must be ≥ 1, got {n_voices}")
        if not release > 0:
            raise ValueError(f"release must be > 0 seconds, got {release!r}")
        # one string more than the voices: the last sounds a stolen note out (STEAL_FADE)
        self.bank = StringBank(n_voices + 1, parameters, sample_rate=sample_rate, block_size=block_size)
        self.n_voices = int(n_voices)
        self.voices = self.bank.strings[:n_voices]
        self.sample_rate = float(sample_rate)
        self.pitch = np.full(n_voices + 1, -1.0)  # -1: free
        self.started = np.full(n_voices + 1, -np.inf)  # note-on order stamp
        self.level = np.zeros(n_voices + 1)  # envelope now
        self.slope = np.zeros(n_voices + 1)  # envelope change per sample (negative while releasing)
        self._release_step = 1.0 / (release * sample_rate)
        self._steal_step = 1.0 / (STEAL_FADE * sample_rate)
        self._count = 0

    def note_on(self, pitch: float, velocity: float = 1.0) -> int:
        """Start a note (MIDI pitch, velocity 0..1); returns the voice index used."""
        n = self.n_voices
        free = np.flatnonzero(self.pitch[:n] < 0)
        fading = np.flatnonzero(self.slope[:n] < 0)
        if len(free):
            index = int(free[0])
        elif len(fading):  # the quietest of the notes already ending: the smallest step to silence
            index = int(fading[np.argmin(self.level[fading])])
        else:
            index = int(np.argmin(self.started[:n]))
        if self.pitch[index] >= 0:
            self._set_aside(index)
        voice = self.voices[index]
        voice.silence()
        hz = midi_to_hz(pitch)
        while hz >= self.sample_rate / 2:  # MIDI 124+ at 22050 Hz: sounds octaves down rather than raise
            hz /= 2
        voice.note_on(hz, velocity)
        self._count += 1
        self.pitch[index], self.started[index] = pitch, self._count
        self.level[index], self.slope[index] = 1.0, 0.0
        return index

    def release(self, index: int, started: float) -> None:
        """Release voice ``index`` if it still sounds the note it started at stamp ``started``
        (``started[index]`` just after its :meth:`note_on`): one note's end, which leaves any
        other note of the same pitch sounding (thesis "exchange": every note is independent of
        every other, even of the same pitch), and a voice stolen since alone."""
        if self.started[index] == started and self.pitch[index] >= 0 and self.slope[index] == 0:
            self.slope[index] = -self._release_step

    def _set_aside(self, index: int) -> None:
        """Move what voice ``index`` sounds to the string kept aside, fading out from its level
        now (a note stolen while the last one still fades there ends it there, as before)."""
        aside, bank = self.n_voices, self.bank
        for array in (bank.x, bank.v, bank.x_prev, bank.force, bank.state):
            array[aside] = array[index]
        self.pitch[aside], self.started[aside] = self.pitch[index], -np.inf  # no note's release reaches it
        self.level[aside], self.slope[aside] = self.level[index], -self._steal_step

    @property
    def active(self) -> int:
        """Voices sounding a note (the string kept aside, fading a stolen one out, is none)."""
        return int((self.pitch[: self.n_voices] >= 0).sum())

    def render(self, out: np.ndarray) -> np.ndarray:
        """Sum all sounding voices into ``out`` (raw, before any limiter); frees finished voices.

        A block longer than ``block_size`` (a coarse behaviour tick at a high sample rate) is
        rendered in ``block_size`` pieces, so the scratch buffers stay preallocated and small."""
        out[:] = 0.0
        size = self.bank.block_size
        for start in range(0, len(out), size):
            sounding = np.flatnonzero(self.pitch >= 0)
            self.bank.render(out[start:start + size], sounding, self.level, self.slope)
            self.pitch[sounding[self.level[sounding] <= 0.0]] = -1.0
        return out
