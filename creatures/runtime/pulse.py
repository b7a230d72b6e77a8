"""The colony's heard pulse: one low-integer-ratio duration model fed by every note onset.

Thesis, "temporal models": duration models shared by many action-tuples give the creatures
one coherent pulse. Here the world hears every note from outside the colony that starts
(from a MIDI port or file, pitch-tracked audio, another colony over OSC) and, once a tick,
turns the new
onsets into inter-onset intervals with the same helper both listening paths use
(:func:`creatures.temporal.onsets.merge_onsets`: near-simultaneous onsets, a chord,
count once) and teaches them to a :class:`LowIntegerRatioModel`. A Du that rests "in time"
samples it (:class:`PulseDuration`), so what the colony plays falls on the ratio lattice of
what it hears.

The pulse keeps competing metrical readings (:class:`~creatures.temporal.readings.
PulseReadings`, thesis: "a population of (possibly competing) views and interpretations"):
every reading hears every interval, and ``model`` is the best-scoring reading's, so every
Du, percept and tempo map of the colony follows the reading that explains the music best.
A config names its readings in ``[pulse] readings`` (one, ``simple``, by default: the
colony's pulse as it always was). :meth:`HeardPulse.next_beat` gives the colony one grid:
a phrase that starts there shares the beat of every other creature's.

Each reading is also a pulse tree (its beat, the division of the beat, the bar:
:data:`~creatures.temporal.readings.LEVELS`), entrained on every onset heard, so
:meth:`HeardPulse.phase` says where a new note falls on a level of the heard metre counted
from the note before it: the interval the readings themselves judge, whatever the
performer's slow drift against the colony's grid.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from creatures import bounds
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.temporal.durations import LowIntegerRatioModel
from creatures.temporal.onsets import merge_onsets
from creatures.temporal.readings import Level, PulseReadings
from creatures.temporal.tree import Subdivision

CHORD_GAP = 0.03
"""Seconds: onsets closer than this are one rhythmic event."""

LONGEST_INTERVAL = 3.0
"""Seconds: a longer gap between onsets is a pause, not a duration of the rhythm."""

READY_AFTER = 8
"""Intervals heard before the pulse is trusted over a Du's own fallback."""

GRID_PULL = 0.25
"""Share of a heard beat's distance from the colony's grid that moves the grid toward it."""

ON_THE_BEAT = 0.2
"""× the pulse: an onset this close to a grid point is a beat (nearer the middle it is an
off-beat note, which says nothing about where the beats are)."""


class HeardPulse:
    """Onsets in, a pulse (and rhythmic durations to sample) out."""

    def __init__(self, prior_pulse: float = 0.5, readings: list[str] | tuple[str, ...] = ("simple",)) -> None:
        self.readings = PulseReadings(readings, prior_pulse)
        self.heard = 0  # intervals taught to the model
        self.grid: float | None = None  # a point of the colony's grid (see next_beat)
        self._last: float | None = None
        self._onsets: list[float] = []

    @property
    def model(self) -> LowIntegerRatioModel:
        """The best reading's model: the pulse the colony plays by."""
        return self.readings.best.model

    def next_beat(self, t: float, subdivision: float = 1.0) -> float:
        """The first point at or after ``t`` of the colony's grid: ``subdivision`` × the pulse
        from a grid point (0 before anything is heard).

        The grid is phase-locked to what is heard: until the pulse is trusted each onset is a
        grid point; after, an onset within :data:`ON_THE_BEAT` of the grid pulls it
        :data:`GRID_PULL` of the way. So creatures starting phrases seconds apart share one
        grid, which a performer's jitter nudges but does not jolt (anchoring on the last raw
        onset put two creatures' notes 20-50 ms apart)."""
        step = subdivision * self.model.pulse
        anchor = self.grid if self.grid is not None else 0.0
        return anchor + math.ceil((t - anchor) / step - 1e-9) * step

    def _lock(self, onset: float) -> None:
        """Move the grid toward a heard onset (see :meth:`next_beat`)."""
        if self.grid is None or not self.ready:
            self.grid = onset
            return
        beat = self.model.pulse
        error = onset - (self.grid + round((onset - self.grid) / beat) * beat)
        if abs(error) <= ON_THE_BEAT * beat:
            self.grid = onset - (1.0 - GRID_PULL) * error

    def phase(self, t: float, level: Level) -> float | None:
        """Where an onset at ``t`` falls between two points of ``level`` (``beat``,
        ``division`` or ``bar``) of the best reading's tree, in [0, 1), counted from the last
        onset heard; None until the pulse is trusted, and after a pause (nothing heard for
        longer than :data:`LONGEST_INTERVAL`: the time starts afresh)."""
        grid = self.readings.level(level)
        if not self.ready or t - grid.anchor > LONGEST_INTERVAL:
            return None
        return grid.phase(t)

    def step(self, level: Level, rng: np.random.Generator) -> float:
        """One step of ``level`` of the best reading, as the level is heard to fill its grid
        (:meth:`~creatures.temporal.tree.Subdivision.sample`: a division long-short once the
        visitor swings, even while the visitor plays straight); a beat is the pulse itself."""
        model = self.readings.level(level).model
        return model.sample(rng) if isinstance(model, Subdivision) else model.sample_pulse(rng)

    @property
    def ready(self) -> bool:
        return self.heard >= READY_AFTER

    def bpm(self) -> float | None:
        """The heard tempo, beats a minute (a beat = the pulse), or None until it is trusted."""
        return 60.0 / self.model.pulse if self.ready else None

    def to_dict(self) -> dict[str, Any]:
        return {"pulse": self.model.to_dict(), "heard": self.heard, **self.readings.to_dict()}

    def restore(self, data: dict[str, Any]) -> None:
        """Take back a saved pulse in place (Du durations hold this object, not a copy). The
        last onset before the save is not kept: the gap across a restart is no duration.
        The model's settings are this pulse's (the code's); only what it learnt is taken.
        Raises KeyError/TypeError/ValueError/ArithmeticError on malformed data."""
        heard = bounds.count(data["heard"], "heard")
        saved = bounds.table(data["pulse"], "pulse")  # the best reading's model, as older files keep it alone
        LowIntegerRatioModel.from_dict(saved)  # a damaged file is refused, even in parts not read
        if "readings" in data:
            self.readings.restore(data)
        else:  # saved before the pulse kept readings: the one pulse is the first reading's
            first = self.readings.readings[0]
            first.model = first.model.learned(saved)
        self.heard = heard

    def hear(self, onset: float) -> None:
        """A note started at ``onset`` (seconds); learnt at the next :meth:`settle`."""
        self._onsets.append(onset)

    def settle(self) -> int:
        """Teach the model the intervals between the onsets heard since the last call; returns
        how many of them surprised it (:attr:`LowIntegerRatioModel.surprised`: the rhythm
        heard changed).

        An onset older than the last one learnt (a note recognised late, e.g. from audio) has
        lost its place in the rhythm and is dropped.
        """
        if not self._onsets:
            return 0
        onsets = np.array(self._onsets if self._last is None else [self._last, *self._onsets])
        self._onsets.clear()
        if self._last is not None:
            onsets = onsets[onsets >= self._last]
        self._last = float(onsets.max())
        onsets = merge_onsets(onsets, min_gap=CHORD_GAP)
        surprises = 0
        if self.grid is None:
            self._lock(float(onsets[0]))
        for onset, interval in zip(onsets[1:].tolist(), np.diff(onsets).tolist()):
            if interval <= LONGEST_INTERVAL:
                self.readings.hear(interval)
                self.heard += 1
                surprises += self.model.surprised
            self._lock(onset)
        self.readings.entrain(float(onsets[-1]))
        return surprises


class PulseDuration:
    """A Du duration: ``beats`` times a duration sampled from the heard pulse (so it lies on the
    pulse's low-integer-ratio lattice) or, with ``level``, ``beats`` steps of that level of the
    best reading's pulse tree (a bar: four beats in duple, three in triple), each step as the
    level is heard to fill its grid (:meth:`HeardPulse.step`); a fallback model's sample until
    the pulse is ready. It learns only from hearing: the length an action
    happened to last says nothing about the music, so ``update`` leaves the pulse alone."""

    def __init__(self, pulse: HeardPulse, fallback: GaussianModel, beats: int = 2, level: Level | None = None) -> None:
        self.pulse = pulse
        self.fallback = fallback
        self.beats = beats
        self.level = level

    def __repr__(self) -> str:
        of = "the heard pulse" if self.level is None else f"the heard pulse's {self.level} level"
        return f"{self.beats} steps of {of} (until heard: {self.fallback!r})"

    def sample(self, rng: np.random.Generator) -> float:
        if not self.pulse.ready:
            return self.fallback.sample(rng)
        if self.level is not None:
            return self.beats * self.pulse.step(self.level, rng)
        return self.beats * self.pulse.model.sample(rng)

    def update(self, duration: float) -> None:
        """Nothing to learn from an action's own length (see the class docstring)."""
