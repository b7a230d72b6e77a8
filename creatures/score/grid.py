"""The score's beat, and following the beat the colony hears (thesis, "(void *)": "constraints,
such as beat alignment and tempo matching can be solved automatically by the output layer ...
beat alignment through time shifting ... beat alignment through time stretching").

:class:`Grid` maps beats to clock time, piecewise linear: a change of tempo or phase takes
effect from a beat on, never before one whose notes were already handed to the output, so the
music already committed keeps its time. Tiles are written in beats, so laying one at a beat
of the grid *is* the time stretch: its notes land at that tempo's times.

:class:`BeatFollower` fits the onsets heard from outside to the colony's pulse (the heard
low-integer-ratio model, :mod:`creatures.runtime.pulse`): each onset's pulse number, rounded
from the model's pulse, then a least-squares line through (number, time) gives the pulse's
exact length and its phase. The score's beat is the power-of-two multiple of that pulse
nearest its own written tempo (a pulse heard in eighths still gives a walking beat), and its
beats are moved (time shift) onto the heard pulses.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

LEAST_ONSETS = 4
"""Fewest onsets (of one tempo) the follower trusts a fit of."""

WINDOW = 8.0
"""Seconds: older onsets are not fitted."""

RECENT = 8
"""Onsets the fit looks at: enough to average, few enough to follow a change of tempo."""

FIT = 0.04
"""Largest RMS distance of the onsets from the fitted lattice, as a fraction of its unit: a
player's timing (20 ms at 120 bpm) passes, onsets of two tempi mixed do not."""

RATIOS = (2.0, 3 / 2, 4 / 3, 5 / 4, 6 / 5, 1.0, 5 / 6, 4 / 5, 3 / 4, 2 / 3, 1 / 2)
"""Units tried, as ratios to the colony's pulse, largest first (low-integer ratios: thesis
"low-integer-ratio duration models")."""


class Grid:
    """Beat number ↔ clock time: segments, each from a beat on (beat ``b`` sounds at ``t``,
    beats ``period`` apart), so a change leaves the beats before it where they were."""

    KEEP = 8
    """Segments kept: enough for the notes still being committed across recent changes."""

    def __init__(self, period: float, t0: float) -> None:
        self.segments: list[tuple[float, float, float]] = [(0.0, t0, period)]  # (beat, time, period)

    @property
    def period(self) -> float:
        return self.segments[-1][2]

    def time(self, beat: float) -> float:
        b, t, period = self._segment(beat)
        return t + (beat - b) * period

    def seconds(self, beat: float, beats: float) -> float:
        """How long ``beats`` beats from ``beat`` last at that beat's tempo (a note keeps the
        length it began with across a later change, and across a gap the score resumed over)."""
        return beats * self._segment(beat)[2]

    def _segment(self, beat: float) -> tuple[float, float, float]:
        """The segment ``beat`` falls in (the first, for a beat before it)."""
        return next((s for s in reversed(self.segments) if beat >= s[0]), self.segments[0])

    def beat(self, t: float) -> float:
        b, t0, period = next((s for s in reversed(self.segments) if t >= s[1]), self.segments[0])
        return b + (t - t0) / period

    def change(self, beat: float, period: float, at: float) -> None:
        """From ``beat`` on, beats are ``period`` apart and ``beat`` sounds at ``at``."""
        self.segments = [s for s in self.segments if s[0] < beat][-self.KEEP:] + [(beat, at, period)]


class BeatFollower:
    """Heard onsets in; the heard pulse's length and the time of one of its pulses out."""

    def __init__(self) -> None:
        self.onsets: deque[float] = deque(maxlen=64)
        self.heard = 0  # onsets heard in all
        self._fitted: tuple[tuple, tuple[float, float] | None] = ((), None)

    def hear(self, t: float) -> None:
        if not self.onsets or t - self.onsets[-1] > 0.03:  # a chord is one event (runtime/pulse.py's CHORD_GAP)
            self.onsets.append(t)
            self.heard += 1

    def fit(self, now: float, guess: float) -> tuple[float, float] | None:
        """(pulse, a pulse's time) from the most of the last :data:`RECENT` onsets (heard
        within :data:`WINDOW` seconds) that one lattice explains, at least
        :data:`LEAST_ONSETS` of them (the newest: after a change of tempo the new one wins as
        soon as four onsets show it), or None.

        The lattice unit is the largest of ``guess`` times a low-integer ratio that the onsets
        fit within :data:`FIT` of it: the colony's pulse model learns a new tempo slowly, and an
        onset rounded to the old pulse would bend the line."""
        recent = np.array([x for x in list(self.onsets)[-RECENT:] if now - x <= WINDOW])
        key = (self.heard, len(recent), guess)
        if key != self._fitted[0]:  # a new onset, one aged out, a new guess: fit again
            self._fitted = (key, self._fit(recent, guess))
        return self._fitted[1]

    @staticmethod
    def _fit(recent: np.ndarray, guess: float) -> tuple[float, float] | None:
        if not guess > 0:
            return None
        for count in range(len(recent), LEAST_ONSETS - 1, -1):  # the most onsets one tempo explains
            t = recent[-count:]
            for ratio in RATIOS:
                unit = guess * ratio
                n = np.round((t - t[-1]) / unit)
                if len(np.unique(n)) < len(n):
                    continue
                slope, intercept = np.polyfit(n, t, 1)
                residual = t - (intercept + slope * n)
                if slope > 0 and np.sqrt(np.mean(residual ** 2)) <= FIT * slope:
                    return float(slope), float(intercept)
        return None


def nearest_multiple(pulse: float, beat: float) -> float:
    """The power-of-two multiple (or fraction) of ``pulse`` nearest ``beat`` (tempo matching
    across the octave ambiguity of a heard pulse)."""
    return pulse * 2.0 ** round(math.log2(beat / pulse))
