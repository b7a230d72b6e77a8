"""A rock's precomposed song and the ear that hears other music on the circle of fifths, for
authored creatures (thesis "sand:stone (installation)", figure 37 "synthetic chemistry for
motivational variables").

"Each creature can sing – decide to play out individual, precomposed music": :class:`Song`
holds the segments (``[pitch, beats]`` notes) and the place in them; singing resumes where it
stopped (a breath is a comma, not a new start). :class:`Singing` is the ``sing_phrases``
action: every note whose onset has come is played at the creature's internal time
(``tempo/60 · pulse`` beats a second), softened and detached by boredom ("timbre is modulated
directly by the boredom model"), and never one it cannot hold to its end on the breath it has
("singing uses 'breath', and when a creature runs out of breath it must pause": a lower bound
of breath, its level less the rate it is being drawn at, since recovery only adds).
"Singing is suppressed on hearing uncorrelated music": :class:`HeardMusic` keeps what was
heard as one decaying duration-weighted vector on the circle of fifths (:mod:`midi.fifths`),
compared with the key of the segment being sung (the ``discord`` percept).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from creatures import bounds
from creatures.behaviour.action_tuple import Action, ActionTuple
from creatures.clock import clock_gap
from midi.fifths import circular_distance, fifths_vector

if TYPE_CHECKING:
    from creatures.authored.creature import Authored

HEARD_HALF = 1.0
"""Seconds of remembered music at which heard music counts half (amount = w / (w + this))."""

PULSE_RANGE = (0.5, 2.0)
"""Slowest and fastest internal time relative to ``tempo``."""


class Song:
    """A creature's precomposed segments and its place in them."""

    def __init__(self, phrases: list[list[tuple[int, float]]]) -> None:
        self.phrases = [(np.array([p for p, _ in ph], dtype=np.int64), np.array([b for _, b in ph]))
                        for ph in phrases]
        self.keys = [fifths_vector(pitches, beats) for pitches, beats in self.phrases]
        self.phrase = 0
        self.note = 0

    def current(self) -> tuple[int, float]:
        """``(pitch, beats)`` of the next note to sing."""
        pitches, beats = self.phrases[self.phrase]
        return int(pitches[self.note]), float(beats[self.note])

    def key(self) -> np.ndarray:
        """The circle-of-fifths vector of the segment being sung."""
        return self.keys[self.phrase]

    def step(self) -> bool:
        """Move past the current note; True when that finished a segment."""
        self.note += 1
        if self.note < len(self.phrases[self.phrase][0]):
            return False
        self.phrase, self.note = (self.phrase + 1) % len(self.phrases), 0
        return True

    def state(self) -> dict[str, int]:
        return {"phrase": self.phrase, "note": self.note}

    def restore(self, state: Any, who: str) -> None:
        state = bounds.table(state, "song")
        phrase, note = int(state["phrase"]), int(state["note"])
        if not (0 <= phrase < len(self.phrases) and 0 <= note < len(self.phrases[phrase][0])):
            raise ValueError(f"{who}: song position {phrase}/{note} is not in its phrases")
        self.phrase, self.note = phrase, note


class HeardMusic:
    """What a creature heard lately: one duration-weighted circle-of-fifths vector fading
    with time constant ``memory`` (vectors add, so no list of notes is kept)."""

    def __init__(self, memory: float) -> None:
        self.memory = memory
        self.vector = np.zeros(2)
        self.weight = 0.0
        self.time = 0.0

    def fade(self, t: float) -> None:
        if t > self.time:
            factor = math.exp(-(t - self.time) / self.memory)
            self.vector *= factor
            self.weight *= factor
            self.time = t

    def hear(self, t: float, pitch: int, seconds: float) -> None:
        """A note weighs what it lasts, but no more than ``memory`` seconds: held for ever it
        would fade to that weight anyway, and the ear stays finite whatever it is told (two
        notes of 1e308 seconds once made it infinite, and the creature's state unsavable)."""
        self.fade(t)
        seconds = min(seconds, self.memory)
        self.vector += fifths_vector(np.array([pitch]), np.array([seconds]))
        self.weight += seconds

    def amount(self) -> float:
        """How much music is in the ear, 0..1."""
        return self.weight / (self.weight + HEARD_HALF)

    def distance(self, key: np.ndarray) -> float:
        """Fifths between what was heard and ``key`` (6 when nothing was heard)."""
        return circular_distance(self.vector, key)

    def state(self) -> dict[str, Any]:
        return {"vector": self.vector.tolist(), "weight": self.weight}

    def restore(self, state: Any, now: float) -> None:
        heard = bounds.table(state, "heard")
        vector = bounds.items(heard.get("vector"), "heard.vector", shortest=2, longest=2)
        self.vector = np.array([bounds.number(x, f"heard.vector.{i}") for i, x in enumerate(vector)])
        self.weight = bounds.number(heard.get("weight"), "heard.weight", low=0.0)
        self.time = now


class Singing(Action):
    """``sing_phrases``: sing the song from where it stopped while the tuple runs (see the
    module docstring); ``done`` once out of breath."""

    def __init__(self, name: str, creature: "Authored", params: Any) -> None:
        super().__init__(name)
        self.creature = creature
        self.params = params
        self.song = Song(params.phrases)
        self.breathless = False
        self.next_onset = 0.0
        self.sung = 0  # notes begun since the tuple started
        m = creature.motivation
        self._drive = {key: None if getattr(params, key) is None else m.index(getattr(params, key))
                       for key in ("breath", "boredom", "pulse")}
        creature.keep("tuples", name, self.song.state, lambda s: self.song.restore(s, f"{creature.name}: {name}"))

    def _level(self, key: str, default: float) -> float:
        i = self._drive[key]
        return default if i is None else float(self.creature.motivation.levels[i])

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.breathless = False
        self.next_onset = t
        self.sung = 0
        self.creature.feed(t)  # singing draws breath (and spends desire) from now

    def stop(self, t: float, *, interrupted: bool) -> None:
        self.creature.feed(t)

    def done(self, t: float) -> float:
        return 1.0 if self.breathless else 0.0

    def timbre(self) -> tuple[int, float]:
        """``(velocity, sounding fraction of each beat)``: boredom makes singing soft and detached."""
        dull = self.params.timbre_depth * min(1.0, self._level("boredom", 0.0))
        return max(1, round(self.params.velocity * (1.0 - dull))), 0.9 * (1.0 - dull)

    def update(self, t: float) -> None:
        """Play every note of the song whose onset has come, while breath lasts. Across a
        clock gap (a night the gallery was closed, a pause: ``creatures.clock.clock_gap``)
        the song resumes where it stopped, from now: that time was not lived, and singing
        its onsets would send a night of notes at once.

        A note longer than the breath a turn begins with (a long note, a slow tempo or pulse)
        is sung for as long as that breath lasts, singing on (drawing breath) until then:
        never begun, it stopped the song there for good, each turn ending breathless the
        moment it began."""
        m, p = self.creature.motivation, self.params
        if clock_gap(self.next_onset, t):
            self.next_onset = t
        i = self._drive["breath"]
        drawn = 0.0 if i is None else max(0.0, -float(m.inputs[i]))  # breath a second, singing
        while not self.breathless and self.next_onset <= t:
            pitch, beats = self.song.current()
            rate = p.tempo / 60.0 * min(PULSE_RANGE[1], max(PULSE_RANGE[0], self._level("pulse", 1.0)))
            velocity, legato = self.timbre()
            onset, duration, held = self.next_onset, legato * beats / rate, None
            if i is not None and self._level("breath", 1.0) - drawn * (onset + duration - m.time) <= 0.0:
                held = self._level("breath", 1.0) / drawn - (onset - m.time)  # seconds the breath lasts
                if self.sung or held <= 0.0:
                    self.breathless = True
                    self.creature.world.emit("breathless", creature=self.creature.name, phrase=self.song.phrase,
                                             note=self.song.note)
                    return
                duration = held
            self.creature.play(pitch, velocity, round(duration, 6), at=onset)
            self.sung += 1
            ended = self.song.step()
            self.next_onset = onset + (held if held is not None else (beats + (p.phrase_rest if ended else 0.0)) / rate)
