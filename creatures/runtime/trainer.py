"""The simulated clicker trainer of an offline run (``[input.trainer]``, thesis *Duncan*,
"clicker training", "simple shaping").

Offline nobody speaks to the dog or clicks, so a run with ``[input.trainer]`` has a trainer
of its own, a source polled each tick as the rehearsal files are
(:func:`creatures.runtime.offline._run`). Design decisions:

* **It speaks into what the creature hears.** Each cue is said by the project's formant
  voices (:func:`audio.formants.word` of the cue's vowels, as ``generate = "speech"`` speaks
  the poem) at a pitch, speed and level drawn by the run's seed, and mixed into the input
  audio block by block (a recording given with ``--audio`` goes on under it). Nothing is made
  ahead: a week-long run holds one cue, not a week of audio.
* **It watches as a person would.** It asks the creature what trick its body holds now
  (:meth:`CreatureKind.holding`), not what the dog has decided or is heading for: a trick
  counts when the body has got there, after the cue began, within the cue's window (seconds
  after the cue has been said; a beg gets longer, it is further from standing).
* **Its click is a clicker's.** A click is the OSC message ``click`` (``/click``) put through
  the run's ``[[input]]`` maps on the next tick (the trainer sees the end of a tick and
  reacts after it), so it rewards exactly as a real clicker's message would: remove the map
  and its clicks reward nothing (counted as unmapped, and said at load).
* **It shapes by a percentile schedule** (Galbicka 1994): the shaped trick (the beg) is
  clicked only when held at least as high as the median of the last ``bar`` offered after
  its cue, so the bar follows the dog up. (With the median of the last ones *clicked*, one
  lucky high beg early set a bar no later beg reached: tests/test_duncan.py.)
* **It says what it did**: a ``cue said`` event for each cue (word, trick, when it began and
  ended) and a ``trial`` event when a cue's window has closed or the trick was seen (held,
  clicked, a beg's height): the events log holds the training session.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np

from audio.formants import vowels_of, word
from creatures.kinds.base import CreatureKind
from creatures.runtime.input_map import InputRouter
from creatures.runtime.trainer_spec import TrainerSection

if TYPE_CHECKING:
    from creatures.runtime.schema import LoadedInstallation
    from creatures.runtime.session import Session


@dataclass
class Trial:
    """One cue and the window after it."""

    word: str
    trick: str
    at: float  # the cue began, clock seconds
    end: float  # it has been said: the window opens
    window: float
    judged: bool = False


class Trainer:
    """Says cues into a creature's hearing and clicks through the input map (module docstring)."""

    def __init__(self, spec: TrainerSection, creature: CreatureKind, router: InputRouter,
                 emit: Callable[..., None], sample_rate: int, rng: np.random.Generator) -> None:
        self.spec = spec
        self.creature = creature
        self.router = router
        self.emit = emit
        self.sample_rate = sample_rate
        self.rng = rng
        self.words = list(spec.cues)
        self.next_cue = float(rng.uniform(*spec.every))
        self.voice = np.zeros(0, dtype=np.float32)  # the cue being said
        self.voice_at = 0  # its first sample, on the run's sample clock
        self.trial: Trial | None = None
        self.offered: list[float] = []  # heights of the shaped trick held after its cue
        self.due: list[float] = []  # clicks decided, sent on the next tick
        self.clicks = 0
        self.cues = 0  # cues said
        self.seen: list[bool] = []  # per cue judged: was its trick held within its window

    @classmethod
    def of(cls, inst: "LoadedInstallation", session: "Session") -> "Trainer | None":
        """The config's trainer for ``session``, or None. Its random stream is the run seed's
        next after the creatures' and the input's, so adding a trainer changes neither."""
        spec = inst.settings.input.trainer
        if spec is None:
            return None
        creature = next(c for c in session.creatures if c.name == spec.creature)
        seed = np.random.SeedSequence(inst.settings.seed).spawn(len(inst.specs) + 2)[-1]
        return cls(spec, creature, session.inputs, session.world.emit, session.sample_rate,
                   np.random.default_rng(seed))

    def poll(self, t: float) -> int:
        """The clicks decided before ``t`` go through the input map (as a rehearsal row's would)."""
        notes = 0
        while self.due and self.due[0] < t:
            self.due.pop(0)
            self.clicks += 1
            notes += self.router.osc(self.spec.click, (), t, "trainer")
        return notes

    def heard(self, recorded: np.ndarray | None, a: int, b: int) -> np.ndarray:
        """Samples ``a``..``b`` of the run as the creature hears them: the recording (if any)
        with the trainer's voice over it. A cue due within the block is begun in it."""
        out = np.zeros(b - a, dtype=np.float32)
        if recorded is not None:
            out[: len(recorded)] += recorded[: b - a]
        start = int(round(self.next_cue * self.sample_rate))
        if start < b:
            self._say(max(start, a))
        lo, hi = max(a, self.voice_at), min(b, self.voice_at + len(self.voice))
        if lo < hi:
            out[lo - a : hi - a] += self.voice[lo - self.voice_at : hi - self.voice_at]
        return out

    def _say(self, start: int) -> None:
        cue = self.words[int(self.rng.integers(len(self.words)))]
        s = self.spec
        self.voice = word(vowels_of(cue), self.rng, self.sample_rate, stretch=float(self.rng.uniform(*s.stretch)),
                          f0=float(self.rng.uniform(*s.pitch)), rms=float(self.rng.uniform(*s.level))).astype(np.float32)
        self.voice_at = start
        at, end = start / self.sample_rate, (start + len(self.voice)) / self.sample_rate
        trick = s.cues[cue]
        if self.trial is not None and not self.trial.judged:  # its window closed within this tick (a long tick)
            self._judge(self.trial, None, at)
        self.trial = Trial(cue, trick, at, end, s.window_of(trick))
        self.cues += 1
        self.next_cue = at + float(self.rng.uniform(*s.every))
        self.emit("cue said", creature=self.creature.name, word=cue, trick=trick, at=round(at, 6), end=round(end, 6))

    def watch(self, t: float) -> None:
        """After the tick at ``t``: is the creature holding what the cue asked for?"""
        trial = self.trial
        if trial is None or trial.judged or t < trial.end:
            return
        if t > trial.end + trial.window:
            self._judge(trial, None, t)
            return
        held = self.creature.holding()
        if held is not None and held.trick == trial.trick and held.since >= trial.at:
            self._judge(trial, held.height, t, seen=True)

    def said(self) -> str:
        """The session in one line for the run's summary: a run too short to train the creature
        (the demo's 30 s give a few cues) must say so, not leave it looking untrainable."""
        third = max(len(self.seen) // 3, 1)
        early, late = self.seen[:third], self.seen[-third:]
        answered = (f"its trick held within the window after {sum(early)} of the first {len(early)} and "
                    f"{sum(late)} of the last {len(late)}" if len(self.seen) >= 6 else
                    f"{sum(self.seen)} of {len(self.seen)} answered: too few to learn from (about 40 cues "
                    f"train it: --duration {40 * sum(self.spec.every) / 2:.0f})")
        return (f"trainer: {self.cues} cues said to {self.creature.name}, {self.clicks} clicks; {answered}")

    def _judge(self, trial: Trial, height: float | None, t: float, *, seen: bool = False) -> None:
        trial.judged = True
        self.seen.append(seen)
        clicked = seen
        if seen and trial.trick == self.spec.shaping and height is not None:
            bar = float(np.median(self.offered[-self.spec.bar:])) if self.offered else -np.inf
            self.offered.append(height)
            clicked = height >= bar
        if clicked:
            self.due.append(t)
        self.emit("trial", creature=self.creature.name, word=trial.word, trick=trial.trick, held=seen,
                  clicked=clicked, height=height, waited=round(t - trial.end, 6))
