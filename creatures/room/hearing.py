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

import numba
import numpy as np

SPEED_OF_SOUND = 343.0
"""Metres per second in air at 20 °C."""


def velocity_db(velocity: float) -> float:
    """A MIDI velocity as a level, dB re velocity 127 (0 dB)."""
    return 40.0 * math.log10(max(velocity, 1e-3) / 127.0)


def db_velocity(db: float | np.ndarray) -> float | np.ndarray:
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
    starts, ends, dbs = arrivals(start, duration, db, np.array([distance], dtype=float), law, delay=delay)
    return Arrival(float(starts[0]), float(ends[0]), float(dbs[0]), pitch, what)


def arrivals(start: float, duration: float, db: float, distances: np.ndarray, law: DistanceLaw, *,
             delay: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """When a sound emitted at ``start`` begins and ends at every one of ``distances``, and its
    level there: a note crossing the room reaches every ear, so each is one array operation,
    not one per ear (element-wise, so each ear's numbers are what one ear alone would get)."""
    starts = start + distances / SPEED_OF_SOUND if delay else np.full(len(distances), float(start))
    return starts, starts + duration, db + law.db(distances)


@dataclass(frozen=True)
class Masking:
    """A sound is masked when another overlapping it in time at the ear is ``margin`` dB
    louder or more and (when both are pitched) within ``band`` semitones of it, or when it
    is below the ``threshold`` of hearing (dB re velocity 127 at 1 m)."""

    margin: float = 20.0
    band: float = 12.0
    threshold: float = -60.0


class Ears:
    """What is sounding at each of ``n`` ears, and whether each sound arriving stands out there.

    Sounds must be given in the order they arrive (their start, then the order they were
    emitted): a sound is judged against those that reached its ear before it and still sound
    when it begins, and it joins them (masked or not, it can mask the next). Each ear keeps
    its sounds in a row of one array, so a tick's arrivals at the whole crowd are judged in
    one compiled pass rather than a Python loop over every note at every ear.
    """

    def __init__(self, n: int, masking: Masking) -> None:
        self.masking = masking
        self._count = np.zeros(n, dtype=np.int64)
        self._sounding = np.zeros((4, n, 4))  # (start, end, dB, pitch or NaN) × ear × slot

    def hear(self, ear: np.ndarray, start: np.ndarray, end: np.ndarray, db: np.ndarray,
             pitch: np.ndarray) -> np.ndarray:
        """Whether each arriving sound stands out at its ``ear`` (arrays in arrival order;
        ``pitch`` NaN for an unpitched sound)."""
        ear = np.asarray(ear, dtype=np.int64)
        most = int((self._count + np.bincount(ear, minlength=len(self._count))).max(initial=0))
        if most > self._sounding.shape[2]:  # room for every ear's sounds, were none to end
            grown = np.zeros((4, len(self._count), max(most, 2 * self._sounding.shape[2])))
            grown[:, :, :self._sounding.shape[2]] = self._sounding
            self._sounding = grown
        m = self.masking
        return _stand_out(ear, np.asarray(start, float), np.asarray(end, float), np.asarray(db, float),
                          np.asarray(pitch, float), self._sounding, self._count, m.margin, m.band, m.threshold)


@numba.njit(cache=True)
def _stand_out(ear, start, end, db, pitch, sounding, count, margin, band, threshold):  # pragma: no cover - compiled
    """:meth:`Ears.hear`: for each sound in turn, its ear keeps what still sounds when it
    begins (in order), takes the sound, and hears it unless it is below ``threshold`` or an
    earlier sound there overlaps it ``margin`` dB louder within ``band`` semitones."""
    heard = np.empty(len(ear), dtype=np.bool_)
    for k in range(len(ear)):
        e = ear[k]
        a_start, a_end, a_db, a_pitch = start[k], end[k], db[k], pitch[k]
        n = 0
        for j in range(count[e]):
            if sounding[1, e, j] > a_start:
                for f in range(4):
                    sounding[f, e, n] = sounding[f, e, j]
                n += 1
        sounding[0, e, n], sounding[1, e, n], sounding[2, e, n], sounding[3, e, n] = a_start, a_end, a_db, a_pitch
        count[e] = n + 1
        out = not a_db < threshold
        j = 0
        while out and j < n:
            b_pitch = sounding[3, e, j]
            if (sounding[2, e, j] - a_db >= margin and sounding[0, e, j] < a_end and a_start < sounding[1, e, j]
                    and (np.isnan(a_pitch) or np.isnan(b_pitch) or abs(a_pitch - b_pitch) <= band)):
                out = False
            j += 1
        heard[k] = out
    return heard
