"""Duration percept trees (thesis: "exotic duration models": "the ability to share percept
models between action-tuples, by placing them in percept tree structures ... a coherent
pulse across action-tuples", whose hierarchy "can directly represent the hierarchical
structures that are undeniably useful for music").

A :class:`PulsePercept` holds one pulse model (a :class:`~creatures.temporal.durations.
LowIntegerRatioModel` or :class:`~creatures.temporal.durations.SimpleDurationModel`).
Every tuple whose Du is ``DoUntil(beat.model)`` samples the same pulse and teaches it
what it actually did, so the tuples keep one time. Children are metrical levels at fixed
ratios of their parent (``beat.level(Fraction(1, 2))`` is the half-beat, ``beat.level(4)``
a bar of four) whose grid is the parent's pulse at that ratio, and whose models learn on
their own, from the heard notes that fill the level's cycles, how the level fills that grid
(:class:`Subdivision`: a swung half-beat is long-short, not two halves). The metrical
readings (:mod:`creatures.temporal.readings`) are such trees, and a piece keeps time on a
level of the best one.

As a percept, ``evaluate(t)`` says how close ``t`` is to a point of the level's grid
(1 on the grid, falling off between), so the same node serves as a "on the (half-)beat"
trigger.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import numpy as np

from creatures import bounds
from creatures.behaviour.percept import Percept
from creatures.temporal.durations import MAX_DURATION, LowIntegerRatioModel, PulseModel, check_duration


def on_grid(phase: float, sharpness: float) -> float:
    """How near phase φ of a grid is to a grid point: exp(κ·(cos 2πφ − 1)), 1 on it and
    e^(−2κ) half way between (``sharpness`` κ)."""
    return math.exp(sharpness * (math.cos(2.0 * math.pi * phase) - 1.0))


class Subdivision:
    """A metrical level at ``ratio`` × a parent pulse, with a model of its own.

    **Tied to the parent.** The level's grid step (``pulse``) is always ``ratio`` × the
    parent's pulse, so every level keeps the parent's time and follows its tempo. The parent
    learns only from what it hears itself: a level never teaches it (a reading's beat hears
    every interval already, and a level's notes taught twice would weigh twice).

    **Its own model.** ``own`` (a :class:`LowIntegerRatioModel`) hears the level's
    durations in units of the grid step they were played against, so it learns how the level
    fills its grid: a half-beat level played swung (long-short, 2:1 within the beat) learns
    4/3 and 2/3 of its grid instead of averaging them to one grid step. Sampling draws from
    that, times the current grid step — the swing is kept, at whatever tempo the parent has
    reached since. A level that has heard nothing samples its grid step. The model learns
    the proportions of the pattern, not their order: a swung level draws long and short
    notes about equally often, in no fixed order. It remembers the last :data:`MEMORY`
    durations, so a change of feel is followed within a few bars.

    **Which heard notes are the level's** (:meth:`hear`). A *cell* is a run of consecutive
    heard intervals, each shorter than one cycle of the level (its ratio's denominator in
    grid steps: the beat, for a division of it), that together fill one cycle within the
    own model's tolerance: two straight eighths or a swung long-short pair fill a beat, a
    quarter note does not. Only the notes of cells are the level's.
    """

    MEMORY = 16  #: durations of the level's own pattern remembered (eight swung pairs)
    PRIOR = 0.01  #: pseudo-counts of the ratio prior: a level plays what it heard, not the prior's ratios

    def __init__(self, parent: PulseModel, ratio: Fraction) -> None:
        if not ratio > 0:
            raise ValueError(f"a metrical level needs a positive ratio (got {ratio})")
        self.parent = parent
        self.ratio = Fraction(ratio)
        self.own = LowIntegerRatioModel(prior_pulse=1.0, size=self.MEMORY, recency=self.MEMORY,
                                        prior_strength=self.PRIOR)
        self.heard = 0  # durations the own model has learnt
        self._cell: list[float] = []

    @property
    def pulse(self) -> float:
        """The grid step: ``ratio`` × the parent's pulse."""
        return float(self.ratio) * self.parent.pulse

    def sample_pulse(self, rng: np.random.Generator) -> float:
        return float(self.ratio) * self.parent.sample_pulse(rng)

    @property
    def max_duration(self) -> float:
        """The longest duration :meth:`update` takes: one the own model takes in grid steps
        (3600 of them: 15 minutes of a quarter-second grid), and no longer than any model
        takes. A Du on this level ends longer ones without teaching them
        (:meth:`~creatures.behaviour.action_tuple.DoUntil.end`)."""
        return min(MAX_DURATION, self.own.max_duration * self.pulse)

    def sample(self, rng: np.random.Generator) -> float:
        """A duration of this level: its own learned pattern (in grid steps) × the grid step."""
        if not self.heard:
            return self.sample_pulse(rng)
        return self.own.sample(rng) * self.pulse

    def update(self, duration: float) -> None:
        """Learn ``duration`` as one of the level's notes: where it falls on the grid."""
        self.own.update(check_duration(duration) / self.pulse)
        self.heard += 1

    def hear(self, interval: float) -> None:
        """A heard inter-onset interval: learn the notes of the cell it completes, if any
        (see the class notes); a note as long as a cycle breaks the run."""
        d = check_duration(interval)
        cycle = self.ratio.denominator * self.pulse
        band = math.exp(self.own.tolerance)
        if d * band >= cycle:
            self._cell.clear()
            return
        self._cell.append(d)
        while sum(self._cell) > cycle * band:
            self._cell.pop(0)
        if sum(self._cell) * band >= cycle:
            for note in self._cell:
                self.update(note)
            self._cell.clear()

    def to_dict(self) -> dict[str, Any]:
        """What the level learnt (its own model and how much it heard), JSON-ready."""
        return {"own": self.own.to_dict(), "heard": self.heard}

    def restore(self, data: dict[str, Any]) -> None:
        """Take back what a saved level learnt (the settings stay the code's: see
        :meth:`LowIntegerRatioModel.learned`). Raises on malformed data, changing nothing."""
        own = self.own.learned(bounds.table(data["own"], "own"))
        self.heard = bounds.count(data["heard"], "heard")
        self.own = own

    def __repr__(self) -> str:
        return f"Subdivision({self.ratio} × {self.parent!r}, own={self.own!r})"


class PulsePercept(Percept):
    """A shared pulse in a percept tree: Du's reference ``.model``; Tr's ``evaluate(t)``.

    ``sharpness`` κ shapes the grid saliency exp(κ·(cos 2πφ − 1)) at phase φ of the grid:
    1 on a grid point, e^(−2κ) half way between. The grid's phase is anchored at time 0
    (a free-running pulse) until :meth:`entrain` anchors it on a heard onset; children share
    their root's anchor, so the half-beats fall between the beats.
    """

    def __init__(
        self,
        name: str,
        model: PulseModel,
        *,
        parent: Percept | None = None,
        sharpness: float = 8.0,
    ) -> None:
        if not sharpness > 0:
            raise ValueError(f"sharpness must be positive (got {sharpness!r})")
        super().__init__(name, parent=parent)
        self.model = model
        self.sharpness = float(sharpness)
        self._anchor = 0.0

    @property
    def pulse(self) -> float:
        return self.model.pulse

    @property
    def anchor(self) -> float:
        """The time of a grid point: the root pulse's last entrained onset."""
        parent = self.parent
        return parent.anchor if isinstance(parent, PulsePercept) else self._anchor

    def entrain(self, onset: float) -> None:
        """Put a grid point of this level (and so of the whole pulse tree) at ``onset``."""
        root = self
        while isinstance(root.parent, PulsePercept):
            root = root.parent
        root._anchor = float(onset)

    def phase(self, t: float) -> float:
        """Where ``t`` falls between grid points, in [0, 1)."""
        return ((t - self.anchor) / self.pulse) % 1.0

    def evaluate(self, t: float) -> float:
        return on_grid(self.phase(t), self.sharpness)

    def level(self, ratio: Fraction | int, name: str | None = None) -> "PulsePercept":
        """A child metrical level at ``ratio`` × this pulse (e.g. 1/2, 3 or 4)."""
        ratio = Fraction(ratio)
        return PulsePercept(
            name or f"{self.name}×{ratio}",
            Subdivision(self.model, ratio),
            parent=self,
            sharpness=self.sharpness,
        )
