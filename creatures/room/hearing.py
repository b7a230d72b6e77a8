"""Hearing in the room: a sound reaches an ear attenuated by a distance law and delayed by
the time sound takes to cross the room (343 m/s), and a quiet sound under a loud one is not
heard at all (masking; thesis, "hearing": an ear hears what stands out of the room's sound).

Levels are decibels relative to a sound at its ``reference`` distance (1 m). A note's MIDI
velocity maps to a level by the common 40·log10(v/127) dB curve and back, so an attenuated
note arrives as a softer note.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

SPEED_OF_SOUND = 343.0
"""Metres per second in air at 20 °C."""


def velocity_db(velocity: float) -> float:
    """A MIDI velocity as a level, dB re velocity 127 (0 dB)."""
    return 40.0 * math.log10(max(velocity, 1e-3) / 127.0)


def db_velocity(db: float) -> float:
    """A level (dB re velocity 127) as a MIDI velocity (unclipped)."""
    return 127.0 * 10.0 ** (db / 40.0)


@dataclass(frozen=True)
class DistanceLaw:
    """How a sound's level falls with distance beyond ``reference`` m (nearer is not louder):
    'inverse' (−6 dB per doubling, a point source in free field), 'inverse_square' (−12 dB per
    doubling, steeper: a damped room), or 'linear' (amplitude falls linearly to silence at
    ``silent`` m, the game-audio law)."""

    law: Literal["inverse", "inverse_square", "linear"] = "inverse"
    reference: float = 1.0
    silent: float = 20.0

    def gain(self, distance: np.ndarray | float) -> np.ndarray:
        """Amplitude gain (0..1) at ``distance`` m."""
        d = np.maximum(np.asarray(distance, dtype=float), self.reference)
        if self.law == "inverse":
            return self.reference / d
        if self.law == "inverse_square":
            return (self.reference / d) ** 2
        return np.clip(1.0 - (d - self.reference) / (self.silent - self.reference), 0.0, 1.0)

    def db(self, distance: np.ndarray | float) -> np.ndarray:
        """Level change at ``distance`` m, dB (−inf where silent)."""
        with np.errstate(divide="ignore"):
            return 20.0 * np.log10(self.gain(distance))


@dataclass(frozen=True)
class Arrival:
    """A sound as one ear receives it: when it begins and ends there, its level there (dB),
    its pitch (MIDI, or None for an unpitched sound) and what it was (the caller's token)."""

    start: float
    end: float
    db: float
    pitch: float | None
    what: object


def arrive(start: float, duration: float, db: float, pitch: float | None, what: object, distance: float,
           law: DistanceLaw, *, delay: bool = True) -> Arrival:
    """The sound emitted at ``start`` for ``duration`` s at ``db`` as heard ``distance`` m away
    (``delay`` false: at once, as if sound were instantaneous)."""
    return arrive_all(start, duration, db, pitch, what, np.array([distance], dtype=float), law, delay=delay)[0]


def arrive_all(start: float, duration: float, db: float, pitch: float | None, what: object,
               distances: np.ndarray, law: DistanceLaw, *, delay: bool = True) -> list[Arrival]:
    """:func:`arrive` at every one of ``distances`` at once: a note crossing the room reaches
    every ear, and the law's logarithm over all of them is one numpy call, not one per ear
    (element-wise, so each arrival is bit for bit what :func:`arrive` alone would give)."""
    delays = (distances / SPEED_OF_SOUND).tolist() if delay else [0.0] * len(distances)
    return [Arrival(start + d, start + d + duration, db + level, pitch, what)
            for d, level in zip(delays, law.db(distances).tolist())]


@dataclass(frozen=True)
class Masking:
    """A sound is masked when another overlapping it in time at the ear is ``margin`` dB
    louder or more and (when both are pitched) within ``band`` semitones of it, or when it
    is below the ``threshold`` of hearing (dB re velocity 127 at 1 m)."""

    margin: float = 20.0
    band: float = 12.0
    threshold: float = -60.0

    def stands_out(self, a: Arrival, arrivals: list[Arrival]) -> bool:
        """Whether ``a`` stands out among ``arrivals`` at its ear (one sound's answer in O(n):
        the stage asks only of the sound arriving, not again of every sound sounding there)."""
        if a.db < self.threshold:
            return False
        for b in arrivals:  # a plain loop, the level test first: every note at every ear asks
            if (b.db - a.db >= self.margin and b is not a and b.start < a.end and a.start < b.end
                    and (a.pitch is None or b.pitch is None or abs(a.pitch - b.pitch) <= self.band)):
                return False
        return True
