"""Competing metrical readings of one heard rhythm (thesis: "exotic duration models": a
duration percept tree "can be used to guide the creation of and maintain competing
hypotheses about the timing structures ... The maintenance of a population of (possibly
competing) views and interpretations is a common theme throughout the computer music
understanding literature").

A *reading* is one hypothesis about the metre: a :class:`~creatures.temporal.durations.
LowIntegerRatioModel` restricted to the ratios that metre allows. ``duple`` hears every
duration as a power-of-two multiple or division of its pulse (1/4, 1/2, 1, 2, 4); ``triple``
divides its pulse in three (1/3, 2/3, 1, 2, 3). The two sets are not scalings of each other
(triple scaled by 3/2 would need 3/2, which duple lacks), so a rhythm of eighths and quarters
is explained by one reading at every pulse and a rhythm of triplets by the other, while an
ambiguous rhythm keeps both alive. ``simple`` is the default ratio set (every ratio of one to
four), the single reading a colony keeps unless its config names others.

Every reading hears every interval and learns from it on its own (its own pulse, its own
re-anchoring). :class:`PulseReadings` scores each by how well it explained what was heard
lately — a leaky mean of the log-likelihood of each interval under the reading's learned
ratio distribution and its tolerance band, with an unexplained interval costing what the
model's own re-anchoring charges — and the best-scoring reading is the one the colony plays
by. Switching is damped by ``margin`` (nats a challenger must lead by), so a passage that
fits both readings alike does not flip the colony's metre back and forth.

Each reading is a duration percept *tree* (thesis: the tree "can directly represent
(through it's hierarchy) the hierarchical structures that are undeniably useful for
music"): its model is the root (the beat) of a :class:`~creatures.temporal.tree.PulsePercept`
whose children are the metre's levels (:data:`LEVELS`: the division of its beat and its
bar), every level a grid at a fixed ratio of the root's pulse, all anchored on the last
onset heard. A piece asks for a level by name (``division``), so a duple reading answers
with its half-beat and a triple one with its third: what a tuple keeps time with follows the
metre the colony hears. The division level learns from the heard rhythm how it fills its
grid (:meth:`~creatures.temporal.tree.Subdivision.hear`: each run of notes that fills a
beat), so a division played by the colony is straight while the visitor plays straight
eighths and long-short once the visitor swings.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any, Literal

from creatures import bounds
from creatures.temporal.durations import DEFAULT_RATIOS, LowIntegerRatioModel
from creatures.temporal.tree import PulsePercept, Subdivision

METRES: dict[str, dict[Fraction, float]] = {
    "simple": DEFAULT_RATIOS,
    "duple": {Fraction(1): 8.0, Fraction(2): 4.0, Fraction(1, 2): 4.0, Fraction(4): 2.0, Fraction(1, 4): 2.0},
    "triple": {Fraction(1): 8.0, Fraction(1, 3): 4.0, Fraction(2, 3): 4.0, Fraction(2): 2.0, Fraction(3): 2.0},
}
"""The metres a reading may take, by the name a config gives (``[pulse] readings``): the
ratios (duration : pulse) each allows, with their prior preferences."""

Level = Literal["beat", "division", "bar"]
"""The name of a level of a reading's pulse tree, as a piece gives it."""

LEVELS: dict[str, dict[Level, Fraction]] = {
    "simple": {"beat": Fraction(1), "division": Fraction(1, 2), "bar": Fraction(4)},
    "duple": {"beat": Fraction(1), "division": Fraction(1, 2), "bar": Fraction(4)},
    "triple": {"beat": Fraction(1), "division": Fraction(1, 3), "bar": Fraction(3)},
}
"""Each metre's levels (ratio to its pulse), by the name a piece gives: its beat, the
division of the beat it hears (two halves, or three thirds) and its bar (the largest ratio
of a duple reading; three beats in triple)."""

RATE = 0.05
"""Weight of each new interval in a reading's score (a memory of about twenty intervals)."""

MARGIN = 0.1
"""Nats of score a reading must lead the current best by to take its place."""


class Reading:
    """One metrical hypothesis: a named low-integer-ratio model and its running score."""

    def __init__(self, metre: str, prior_pulse: float) -> None:
        if metre not in METRES:
            raise ValueError(f"no metre named {metre!r} (metres: {', '.join(METRES)})")
        self.metre = metre
        self.model = LowIntegerRatioModel(prior_pulse, ratios=METRES[metre])
        self.score = 0.0
        self.levels: dict[Level, PulsePercept] = {}
        self.grow()
        # The model's own scoring rule: ½(residual/σ)² with σ = tolerance/2, and an
        # unexplained duration charged as the least likely ratio at twice the band's edge.
        self._inv_var = 2.0 / self.model.tolerance**2
        self._unexplained = math.log(float(self.model.prior.min())) - 4.0

    def grow(self) -> None:
        """(Re)build the reading's pulse tree on its model: the root is the beat, its children
        the metre's other levels (:data:`LEVELS`), on the anchor the tree had."""
        anchor = self.levels["beat"].anchor if self.levels else 0.0
        root = PulsePercept(f"{self.metre} beat", self.model)
        root.entrain(anchor)
        self.levels = {name: root if ratio == 1 else root.level(ratio, f"{self.metre} {name}")
                       for name, ratio in LEVELS[self.metre].items()}

    @property
    def division(self) -> Subdivision:
        """The division level's model: how this reading hears the beat filled."""
        division = self.levels["division"].model
        assert isinstance(division, Subdivision)  # every level but the beat is one (grow)
        return division

    def hear(self, interval: float) -> float:
        """Learn ``interval`` (the beat hears it, and the division if it fills a beat with
        its neighbours) and return its log-likelihood under this reading as it stood before
        hearing it (the surprise of a good reading is small)."""
        model = self.model
        log_d = math.log(interval)
        label = int(model.interpret([interval])[0])
        if label < 0:
            fit = self._unexplained
        else:
            residual = log_d - math.log(model.pulse) - math.log(float(model.ratios[label]))
            fit = math.log(float(model.ratio_distribution()[label])) - self._inv_var * residual * residual
        model.update(interval)
        self.division.hear(interval)
        return fit


class PulseReadings:
    """A population of competing metrical readings of the same heard intervals; ``best`` is
    the one the colony plays by (see the module notes)."""

    def __init__(self, metres: list[str] | tuple[str, ...] = ("simple",), prior_pulse: float = 0.5, *,
                 rate: float = RATE, margin: float = MARGIN) -> None:
        if not metres:
            raise ValueError("a pulse needs at least one reading")
        if len(set(metres)) != len(metres):
            raise ValueError(f"each metre is read once (got {list(metres)})")
        if not (0.0 < rate <= 1.0 and margin >= 0.0):
            raise ValueError(f"need 0 < rate ≤ 1 and margin ≥ 0 (got {rate!r}, {margin!r})")
        self.readings = [Reading(metre, prior_pulse) for metre in metres]
        self.rate = float(rate)
        self.margin = float(margin)
        self.best = self.readings[0]

    def hear(self, interval: float) -> None:
        """Every reading hears ``interval``; the scores move and the best may change."""
        for reading in self.readings:
            reading.score += self.rate * (reading.hear(interval) - reading.score)
        leader = max(self.readings, key=lambda r: r.score)
        if leader.score > self.best.score + self.margin:
            self.best = leader

    def entrain(self, onset: float) -> None:
        """Put a grid point of every reading's tree at ``onset`` (a note just heard)."""
        for reading in self.readings:
            reading.levels["beat"].entrain(onset)

    def level(self, name: Level) -> PulsePercept:
        """Level ``name`` (:data:`LEVELS`) of the best reading's tree: the metre the colony
        hears, at that level."""
        return self.best.levels[name]

    def scores(self) -> dict[str, float]:
        """Each reading's score, by metre."""
        return {r.metre: r.score for r in self.readings}

    def to_dict(self) -> dict[str, Any]:
        return {"best": self.best.metre,
                "readings": {r.metre: {"score": r.score, "model": r.model.to_dict(), "division": r.division.to_dict()}
                             for r in self.readings}}

    def restore(self, data: dict[str, Any]) -> None:
        """Take back what saved readings learnt. Readings the config no longer names are
        ignored and new ones start fresh; the settings stay the code's (see
        :meth:`LowIntegerRatioModel.learned`). Raises on malformed data."""
        saved = bounds.table(data["readings"], "readings")
        taken = []  # everything checked before anything is taken: a damaged file changes nothing
        for reading in self.readings:
            if reading.metre in saved:
                entry = bounds.table(saved[reading.metre], f"readings.{reading.metre}")
                model = bounds.table(entry["model"], f"readings.{reading.metre}.model")
                LowIntegerRatioModel.from_dict(model)  # refused if damaged, even in parts not read
                score = bounds.number(entry["score"], f"readings.{reading.metre}.score", low=-1e6, high=1e6)
                division = entry.get("division")  # files saved before the division learnt have none
                if division is not None:  # refused if damaged, on a scratch level
                    Subdivision(reading.model, LEVELS[reading.metre]["division"]).restore(
                        bounds.table(division, f"readings.{reading.metre}.division"))
                taken.append((reading, reading.model.learned(model), score, division))
        for reading, model, score, division in taken:
            reading.model, reading.score = model, score
            reading.grow()
            if division is not None:
                reading.division.restore(division)
        best = data.get("best")
        self.best = next((r for r in self.readings if r.metre == best), self.readings[0])
