"""Input for runs that were given none: a generated phrase, as notes and as sound.

``creatures demo`` must run on a fresh machine with no recordings and no hardware, so the
default input is made in code. Following the *exchange: listen: exchange* video (three
musical fragments injected into one creature's ear), it is three short fragments at
100 BPM; the same notes are rendered as harmonic tones so creatures that listen to audio hear
the same material.
"""

from __future__ import annotations

import numpy as np

from midi.notes import NoteEvent

FRAGMENTS: tuple[tuple[tuple[int, float], ...], ...] = (
    # (pitch, beats): a rising figure, an answer, a cadence (C major / A minor).
    ((60, 1.0), (62, 0.5), (64, 0.5), (67, 1.0), (65, 0.5), (64, 0.5), (62, 1.0), (60, 1.0)),
    ((69, 0.5), (67, 0.5), (65, 1.0), (64, 1.5), (62, 0.5), (64, 1.0), (65, 1.0)),
    ((72, 1.0), (71, 0.5), (69, 0.5), (67, 2.0), (64, 1.0), (60, 2.0)),
)


def phrase_notes(*, start: float = 1.0, gap: float = 12.0, bpm: float = 100.0,
                 rng: np.random.Generator | None = None) -> list[NoteEvent]:
    """The three fragments, ``gap`` seconds apart; ``rng`` adds small velocity variation."""
    beat = 60.0 / bpm
    notes = []
    for f, fragment in enumerate(FRAGMENTS):
        t = start + f * gap
        for pitch, beats in fragment:
            velocity = 90 if rng is None else int(rng.integers(70, 110))
            notes.append(NoteEvent(round(t, 6), pitch, velocity, 0, round(0.9 * beats * beat, 6)))
            t += beats * beat
    return notes


def render_notes(notes: list[NoteEvent], sample_rate: int, length: float) -> np.ndarray:
    """Mono float32 of harmonic tones with attack/decay envelopes for ``notes``."""
    out = np.zeros(int(round(length * sample_rate)), dtype=np.float32)
    for note in notes:
        start = int(round(note.time * sample_rate))
        n = min(int(round(note.duration * sample_rate)), len(out) - start)
        if n <= 0:
            continue
        t = np.arange(n) / sample_rate
        f0 = 440.0 * 2.0 ** ((note.pitch - 69) / 12.0)
        tone = sum(np.sin(2 * np.pi * k * f0 * t) / k for k in range(1, 5) if k * f0 < sample_rate / 2)
        envelope = np.minimum(1.0, t / 0.01) * np.exp(-3.0 * t)
        out[start:start + n] += (0.3 * note.velocity / 127.0) * envelope * tone
    return out
