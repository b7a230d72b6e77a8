"""Duration percept trees (thesis: "exotic duration models": "the ability to share percept
models between action-tuples, by placing them in percept tree structures ... a coherent
pulse across action-tuples", whose hierarchy "can directly represent the hierarchical
structures that are undeniably useful for music").

A :class:`PulsePercept` holds one pulse model (a :class:`~creatures.temporal.durations.
LowIntegerRatioModel` or :class:`~creatures.temporal.durations.SimpleDurationModel`).
Every tuple whose Du is ``DoUntil(beat.model)`` samples the same pulse and teaches it
what it actually did, so the tuples keep one time. Children are metrical levels at fixed
ratios of their parent — ``beat.subdivide(2)`` is the half-beat, ``beat.group(4)`` the
bar — whose grid is the parent's pulse at that ratio, and whose models learn on their own
how the level fills that grid (:class:`Subdivision`: a swung half-beat is long-short, not
two halves), while a half-beat tuple's durations teach the beat too.

As a percept, ``evaluate(t)`` says how close ``t`` is to a point of the level's grid
(1 on the grid, falling off between), so the same node serves as a "on the (half-)beat"
trigger.
"""

from __future__ import annotations

import math
from collections import deque
from fractions import Fraction
from typing import Any

import numpy as np

from creatures.behaviour.percept import Percept
from creatures.temporal.durations import LowIntegerRatioModel, PulseModel, check_duration


def on_grid(phase: float, sharpness: float) -> float:
    """How near phase φ of a grid is to a grid point: exp(κ·(cos 2πφ − 1)), 1 on it and
    e^(−2κ) half way between (``sharpness`` κ)."""
    return math.exp(sharpness * (math.cos(2.0 * math.pi * phase) - 1.0))


class Subdivision:
    """A metrical level at ``ratio`` × a parent pulse, with a model of its own.

    **Tied to the parent.** The level's grid step (``pulse``) is always ``ratio`` × the
    parent's pulse, so every level keeps the parent's time and follows its tempo.

    **Its own model.** ``own`` (a :class:`LowIntegerRatioModel`) hears each of the level's
    durations in units of the grid step it was played against, so it learns how the level
    fills its grid: a half-beat level played swung (long-short, 2:1 within the beat) learns
    4/3 and 2/3 of its grid instead of averaging them to one grid step. Sampling draws from
    that, times the current grid step — the swing is kept, at whatever tempo the parent has
    reached since. A level that has heard nothing samples its grid step.

    **Teaching the parent.** The level's durations average to its grid step over whole
    cycles of its pattern (long + short = two half-beats), whatever the pattern, so the
    parent is taught the mean of the level's last ``CYCLES`` × (the ratio's denominator)
    durations — four cycles of a pattern that repeats every parent pulse, the last eight
    half-beats — divided by the ratio: swung half-beats of 0.4 and 0.2 s say the beat is
    0.6 s, where each alone would say 0.8 or 0.4 s. (A level that plays only the long notes
    of its pattern cannot be told from one with a longer grid; the parent's own durations
    settle that.)
    """

    CYCLES = 4  #: cycles of the level's pattern averaged when teaching the parent

    def __init__(self, parent: PulseModel, ratio: Fraction, own: LowIntegerRatioModel | None = None) -> None:
        if not ratio > 0:
            raise ValueError(f"a metrical level needs a positive ratio (got {ratio})")
        self.parent = parent
        self.ratio = Fraction(ratio)
        self.own = own if own is not None else LowIntegerRatioModel(prior_pulse=1.0)
        self._recent: deque[float] = deque(maxlen=self.CYCLES * self.ratio.denominator)

    @property
    def pulse(self) -> float:
        """The grid step: ``ratio`` × the parent's pulse."""
        return float(self.ratio) * self.parent.pulse

    def sample_pulse(self, rng: np.random.Generator) -> float:
        return float(self.ratio) * self.parent.sample_pulse(rng)

    def sample(self, rng: np.random.Generator) -> float:
        """A duration of this level: its own learned pattern (in grid steps) × the grid step."""
        if not self._recent:
            return self.sample_pulse(rng)
        return self.own.sample(rng) * self.pulse

    def update(self, duration: float) -> None:
        """Learn where ``duration`` falls on the grid, and teach the parent the pulse the
        level's recent durations imply (a half-beat of 0.31 s says the beat is 0.62 s)."""
        d = check_duration(duration)
        self.own.update(d / self.pulse)
        self._recent.append(d)
        self.parent.update(sum(self._recent) / len(self._recent) / float(self.ratio))

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

    def subdivide(self, n: int, name: str | None = None) -> "PulsePercept":
        """The level ``n`` times faster: ``beat.subdivide(2)`` is the half-beat."""
        return self.level(Fraction(1, n), name or f"{self.name}/{n}")

    def group(self, n: int, name: str | None = None) -> "PulsePercept":
        """The level ``n`` times slower: ``beat.group(4)`` is a bar of four."""
        return self.level(Fraction(n), name or f"{self.name}*{n}")

    def to_dict(self) -> dict[str, Any]:
        data = {**super().to_dict(), "pulse": self.pulse, "anchor": self.anchor, "sharpness": self.sharpness}
        if isinstance(self.model, Subdivision):
            data["ratio"] = [self.model.ratio.numerator, self.model.ratio.denominator]
            data["own"] = self.model.own.to_dict()
        elif hasattr(self.model, "to_dict"):
            data["model"] = self.model.to_dict()
        return data
