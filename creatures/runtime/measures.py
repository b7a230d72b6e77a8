"""Measures of the music of one rehearsed hour (``creatures rehearse``).

What a curator listening to a week of the piece would ask of each hour, computed from the
creatures' acts in the events log (a MIDI ``note``, a sung ``sing``, a ``read`` part of a
recording: :data:`ACTS`, so pieces that write no MIDI are measured too): how dense it was,
how much of it was silence, how much it repeated itself, how varied its pitches were, how
often it answered the visitors, how often its boredom rose and fell (the "waxing and waning"
of exchange, Downie 2001, "exchange (installation)"), and whether it ran without a crash.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Any

SOUNDS = ("sing", "read")
"""Events that are a creature sounding something other than a note: a sound sung back, a word read."""
ACTS = ("note", *SOUNDS)
"""Events that are a creature making sound (as tests/test_installations.py counts them)."""

GRAM = 4
"""Acts in a gram of :attr:`HourMeasures.repetition` (a short motif)."""

BOREDOM_SWING = 0.25
"""Rise and fall of a boredom drive that make one cycle (its drives live in 0–2)."""


def sounding(record: dict[str, Any]) -> tuple[float, float]:
    """The span of clock time an act sounds."""
    if record["kind"] == "note":
        return record["time"], record["time"] + record["duration"]
    if record["kind"] == "sing":
        return record["start"], record["end"]
    return record["t"], record["t"] + record["length"]


def token(record: dict[str, Any]) -> object:
    """What an act repeats: its pitch, or the percept (or origin) a sound was drawn from."""
    if record["kind"] == "note":
        return record["pitch"]
    return record.get("percept", record.get("origin"))


@dataclass
class HourMeasures:
    """One hour of the rehearsal, open or part-open (closed hours are not rows)."""

    day: int
    hour: int
    open_seconds: float
    acts_per_minute: float
    silence: float
    """Fraction of the open time in which no creature sounded."""
    repetition: float | None
    """Fraction of the hour's :data:`GRAM`-grams of acts heard earlier in the hour."""
    pitch_entropy: float | None
    """Shannon entropy (bits, at most log2 12) of the hour's note pitch classes; None: no notes."""
    answer_rate: float | None
    """Visitor phrases answered over phrases whose answer window closed this hour; None: none."""
    boredom_cycles: int | None
    """Rises and falls of the colony's boredom drives; None: no creature has one."""
    crashed: bool
    acts: dict[str, int] = field(default_factory=dict)
    visitors: int = 0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def entropy(counts: Counter) -> float:
    n = sum(counts.values())
    return -sum(c / n * math.log2(c / n) for c in counts.values() if c)


def repetition(tokens: list[object]) -> float | None:
    grams = [tuple(tokens[i : i + GRAM]) for i in range(len(tokens) - GRAM + 1)]
    if not grams:
        return None
    seen: set[tuple] = set()
    again = 0
    for gram in grams:
        again += gram in seen
        seen.add(gram)
    return again / len(grams)


def covered(spans: list[tuple[float, float]], a: float, b: float) -> float:
    """Seconds of ``[a, b]`` inside the union of ``spans``."""
    total, reach = 0.0, a
    for s, e in sorted(spans):
        s, e = max(s, reach), min(e, b)
        if e > s:
            total += e - s
            reach = e
    return total


class Swings:
    """Counts cycles of a signal: a rise of at least ``swing`` followed by a fall of as much."""

    def __init__(self, swing: float = BOREDOM_SWING) -> None:
        self.swing = swing
        self.rising = True
        self.extreme: float | None = None
        self.cycles = 0

    def update(self, x: float) -> None:
        if self.extreme is None:
            self.extreme = x
        elif self.rising:
            if x < self.extreme:
                self.extreme = x
            elif x >= self.extreme + self.swing:
                self.rising, self.extreme = False, x
        elif x > self.extreme:
            self.extreme = x
        elif x <= self.extreme - self.swing:
            self.rising, self.extreme = True, x
            self.cycles += 1


class HourTally:
    """The acts of one hour as they happen, and the hour's measures once it ends."""

    def __init__(self, day: int, hour: int, creatures: list[str]) -> None:
        self.day, self.hour = day, hour
        self.acts: dict[str, int] = dict.fromkeys(creatures, 0)
        self.spans: list[tuple[float, float]] = []
        self.tokens: list[object] = []
        self.pitch_classes: Counter = Counter()
        self.open: list[tuple[float, float]] = []
        self.crashed = False

    def add(self, record: dict[str, Any]) -> None:
        self.acts[record["creature"]] = self.acts.get(record["creature"], 0) + 1
        self.spans.append(sounding(record))
        self.tokens.append(token(record))
        if record["kind"] == "note":
            self.pitch_classes[record["pitch"] % 12] += 1

    def finish(self, *, answered: int, unanswered: int, cycles: int | None, visitors: int) -> HourMeasures:
        seconds = sum(b - a for a, b in self.open)
        heard = sum(covered(self.spans, a, b) for a, b in self.open)
        phrases = answered + unanswered
        return HourMeasures(
            day=self.day, hour=self.hour, open_seconds=seconds,
            acts_per_minute=sum(self.acts.values()) / (seconds / 60.0) if seconds else 0.0,
            silence=1.0 - heard / seconds if seconds else 1.0,
            repetition=repetition(self.tokens),
            pitch_entropy=entropy(self.pitch_classes) if self.pitch_classes else None,
            answer_rate=answered / phrases if phrases else None,
            boredom_cycles=cycles, crashed=self.crashed, acts=dict(self.acts), visitors=visitors)
