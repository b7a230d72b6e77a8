"""*sand:stone*: rocks on a bed of sand, each holding a simple creature that sings
precomposed phrases when it wants to (thesis, "sand:stone (installation)", figure 37
"synthetic chemistry for motivational variables", and "soft state").

The thesis's description, rule by rule, and where each lives here:

* "Each rock 'contains' a simple musical creature. Each creature can sing – decide to play
  out individual, precomposed music": a creature owns a :class:`Song`, its segments as note
  lists (``phrases``), and only ever plays their notes, in order; singing resumes where it
  stopped (a breath is a comma, not a new start), so it *progresses* through its material.
* "the decision to sing is based on a simple motivation mechanism", modelled as linear
  synthetic chemistry (:class:`~creatures.behaviour.motivation.Motivation`) over four
  drives: ``desire`` (to sing), ``boredom``, ``breath`` and ``pulse``.
* "The creature's presence in the center of the sand bed increases its motivation to sing,
  the rate of increase is governed by a boredom variable": presence feeds desire at
  ``eagerness · presence · (1 − boredom)``, and presence itself breeds boredom (habituation:
  a rock left in the centre grows bored and sings less eagerly, so the music keeps asking
  visitors to move the rocks). Boredom is the one catalyst of the chemistry: the system is
  linear in its state, and the product enters as an input re-set at the *soft-state rate*
  (``SOFT_RATE``) — every other step is integrated exactly by :class:`Motivation`.
* "Singing is suppressed on hearing uncorrelated music from other creatures": what a creature
  hears is kept as one decaying vector on the circle of fifths (:class:`HeardMusic`,
  :mod:`midi.fifths`), compared with the key of the phrase it is singing. Music within
  ``correlated_within`` fifths is correlated and leaves it alone; beyond, *discord* drains
  desire (chemistry) and triggers the ``listen`` tuple, which is valued above singing and
  so can interrupt it (action selection).
* "singing uses 'breath', and when a creature runs out of breath it must pause": singing
  draws breath at ``breath_use`` per second against a recovery toward full; before each
  note the creature checks that it can hold the note to its end (a lower bound of breath:
  its level at the last soft-state step less ``breath_use`` per second, since recovery only
  adds), and if not it stops — then ``pause`` (inhaling) is the only tuple whose trigger is
  up until breath is back to ``recovered``. So no singing stretch outlasts a full breath.
* "The internal time and how this time progresses through the creatures precomposed
  segments is governed by a final piece of motivational state": ``pulse`` (rest level 1)
  is fed by desire and held back by boredom (coupling ``hurry``); internal beats pass at
  ``tempo/60 · pulse`` per second, so eager creatures press on and bored ones drag.
* "Timbre is modulated directly by the boredom model": bored creatures sing softer
  (velocity) and more detached (a shorter sounding fraction of each beat), through
  ``timbre_depth``. (The thesis's time-of-day modulation is left out: offline runs last
  minutes.)

Presence comes from the rock sensor or a script. Offline, ``presence`` is a piecewise-linear
script of ``[seconds, level]`` points (a visitor moving the rock in and out). Live, a sensor
that reports each rock as a note on ``sensor_channel`` (pitch = ``rock``, velocity =
proximity to the centre, 127 at the centre) takes over from the script once it speaks;
sensor notes are readings, never music, so no creature hears them.

Percepts name what a rock senses — ``presence``, ``heard key distance`` (fifths between the
ear and the segment being sung) and ``breath`` — and the soft state and the triggers read
them. Behaviour is three action-tuples in one :class:`ActionGroup`: ``sing`` (trigger: desire
above ``threshold`` with breath recovered; done when out of breath or desire spent),
``pause`` (trigger: breath below ``recovered``; done when recovered) and ``listen``
(trigger: discord; a fixed ``LISTEN_SECONDS``). The creatures are authored, not trained
(the thesis's "motivation based authoring"), so credit assignment is off (``alpha = 0``)
and the values stay as written: ``listen`` > ``sing`` > ``pause``, so discord can interrupt
singing, while a creature never stops singing to breathe until it must.

Time and cost (DESIGN.md, "Time"): the soft state runs at ``SOFT_RATE`` from a random phase
per creature, and so does selection, since every trigger reads soft state — except while
singing, when each tick may bring a note. Notes are scheduled at their exact onsets in
internal time (the MIDI is exact; the voice starts a note in the first audio block that
reaches it), and a silent rock renders no strings. Six rocks run 60 s offline in ~3 s.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any, Literal

import numpy as np
from pydantic import Field, field_validator

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import FunctionPercept
from creatures.kinds import register
from creatures import bounds
from creatures.bounds import FINITE, LARGEST_RATE, LONGEST_SECONDS, Seconds
from creatures.kinds.base import CreatureKind, CreatureSpec
from creatures.kinds.parts import Voice, VoiceSpec
from creatures.kinds.report_parts import report_values, selection_logger
from creatures.runtime.world import INPUT, World
from midi.fifths import STEPS, circular_distance, fifths_vector
from midi.notes import NoteEvent

SOFT_RATE = 10.0
"""Updates per second of the soft state (motivation inputs, heard music, percept levels)."""

REPORT_EVERY = 0.5
"""Seconds between the values/motivation/percepts snapshots written to the events log."""

LISTEN_SECONDS = 2.0
"""How long a creature falls silent to listen when it hears discord."""

HEARD_HALF = 1.0
"""Seconds of remembered music at which heard music counts half (amount = w / (w + this))."""

PULSE_SETTLE = 0.5
"""Per-second return of ``pulse`` to its rest level 1."""

PULSE_RANGE = (0.5, 2.0)
"""Slowest and fastest internal time relative to ``tempo``."""

CEILING = 2.0
"""Upper bound of every drive (concentrations saturate)."""

SING_VALUE, PAUSE_VALUE, LISTEN_VALUE = 1.0, 0.8, 2.0
"""Authored values: discord interrupts singing; breathing never does (see module doc)."""

DEFAULT_PHRASES: list[list[tuple[int, float]]] = [
    [(67, 1.0), (64, 0.5), (62, 0.5), (60, 1.5), (62, 0.5), (64, 2.0)],
    [(64, 0.5), (65, 0.5), (67, 1.0), (72, 1.0), (71, 0.5), (67, 0.5), (69, 2.0)],
]
"""Two short phrases in C major, sung when a config gives none."""


class SandstoneSpec(CreatureSpec):
    """``[[creature]]`` keys of a sand:stone rock (rates are per second of clock time)."""

    model_config = FINITE

    kind: Literal["sandstone"]
    phrases: list[list[tuple[int, float]]] = Field(
        DEFAULT_PHRASES, min_length=1, max_length=1024,
        description="precomposed segments, sung in order: each a list of [pitch, beats] notes "
                    "(beats from this note's onset to the next)")
    tempo: float = Field(96.0, ge=10, le=400, description="beats per minute of internal time at pulse 1 "
                                                         "(at 10, the longest note lasts under 13 minutes)")
    phrase_rest: float = Field(1.0, ge=0, le=64, description="beats of silence between the end of a segment and the next")
    presence: list[tuple[Seconds, float]] = Field(
        [(0.0, 1.0)], min_length=1, max_length=100_000,
        description="presence script: [seconds, level 0..1] points, linearly interpolated and held "
                    "beyond the ends (the rock's closeness to the centre of the sand)")
    rock: int | None = Field(None, ge=0, le=127,
                             description="pitch the rock sensor sends on sensor_channel; a reading "
                                         "(velocity/127 = presence) overrides the script from then on")
    sensor_channel: int = Field(15, ge=0, le=15,
                                description="MIDI channel of rock-sensor readings (never heard as music)")
    eagerness: float = Field(0.3, ge=0, le=LARGEST_RATE, description="desire per second at full presence and no boredom")
    threshold: float = Field(0.4, gt=0, lt=CEILING, description="desire above which the creature wants to sing")
    satiation: float = Field(0.25, ge=0, le=LARGEST_RATE, description="desire used per second of singing")
    forgetting: float = Field(0.03, ge=0, le=LARGEST_RATE, description="per-second decay of desire toward 0")
    habituation: float = Field(0.015, ge=0, le=LARGEST_RATE, description="boredom per second at full presence")
    recovery: float = Field(0.03, ge=0, le=LARGEST_RATE, description="per-second decay of boredom toward 0")
    breath_use: float = Field(0.3, gt=0, le=LARGEST_RATE, description="breath used per second of singing (full breath = 1)")
    breath_recovery: float = Field(0.1, gt=0, le=LARGEST_RATE, description="per-second return of breath toward full")
    inhale: float = Field(0.5, ge=0, le=LARGEST_RATE, description="extra breath per second while pausing")
    recovered: float = Field(0.8, gt=0, le=1, description="breath needed to start singing again")
    hurry: float = Field(0.1, ge=0, le=100, description="how strongly desire speeds, and boredom slows, internal time")
    correlated_within: float = Field(1.5, ge=0, lt=STEPS / 2,
                                     description="circle-of-fifths distance below which heard music is correlated")
    memory: float = Field(4.0, gt=0, le=LONGEST_SECONDS, description="seconds over which heard music fades from the ear")
    suppression: float = Field(0.2, ge=0, le=LARGEST_RATE, description="desire removed per second by fully uncorrelated music")
    velocity: int = Field(96, ge=1, le=127, description="loudness of a fresh (unbored) creature")
    timbre_depth: float = Field(0.5, ge=0, le=1, description="how much full boredom softens (velocity) "
                                                             "and detaches (note length) the singing")
    voice: VoiceSpec = Field(VoiceSpec(voices=3, masses=32, gain=0.8),
                             description="the scanned strings it sings with (small: one line at a time)")

    @field_validator("phrases")
    @classmethod
    def _notes(cls, phrases: list[list[tuple[int, float]]]) -> list[list[tuple[int, float]]]:
        for p, phrase in enumerate(phrases):
            if not phrase:
                raise ValueError(f"phrase {p} is empty")
            for n, (pitch, beats) in enumerate(phrase):
                if not 0 <= pitch <= 127 or not 0 < beats <= 64:
                    raise ValueError(f"phrase {p} note {n}: need pitch 0..127 and 0 < beats <= 64, "
                                     f"got [{pitch}, {beats}]")
        return phrases

    @field_validator("presence")
    @classmethod
    def _script(cls, points: list[tuple[float, float]]) -> list[tuple[float, float]]:
        times = [t for t, _ in points]
        if any(not 0.0 <= level <= 1.0 for _, level in points):
            raise ValueError("presence levels must lie in 0..1")
        if times[0] < 0 or any(b <= a for a, b in zip(times, times[1:])):
            raise ValueError(f"presence times must start at >= 0 and strictly increase, got {times}")
        return points


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


class _Activity(Action):
    """``sing`` or ``pause``: an action that draws on breath (singing) or restores it
    (inhaling) for as long as it runs."""

    def __init__(self, name: str, creature: "Sandstone") -> None:
        super().__init__(name)
        self.creature = creature

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.creature.begin_activity(t, self.name)

    def update(self, t: float) -> None:
        if self.name == "sing":
            self.creature.sing(t)

    def stop(self, t: float, *, interrupted: bool) -> None:
        self.creature.end_activity(t)


@register("sandstone")
class Sandstone(CreatureKind):
    Spec = SandstoneSpec
    DRIVES = ("desire", "boredom", "breath", "pulse")

    def __init__(self, spec: SandstoneSpec, world: World, rng: np.random.Generator) -> None:
        super().__init__(spec, world, rng)
        self.song = Song(spec.phrases)
        self.heard = HeardMusic(spec.memory)
        self._script_t = np.array([t for t, _ in spec.presence])
        self._script_level = np.array([level for _, level in spec.presence])
        self.sensed: float | None = None
        self.motivation = Motivation(
            {"desire": 0.0, "boredom": 0.0, "breath": 1.0, "pulse": 1.0},
            decay={"desire": spec.forgetting, "boredom": spec.recovery, "breath": spec.breath_recovery,
                   "pulse": PULSE_SETTLE},
            coupling={("pulse", "desire"): spec.hurry, ("pulse", "boredom"): -spec.hurry},
            ceiling=CEILING,
        )
        self.activity: str | None = None  # "sing" or "pause": what draws on breath now
        self.breathless = False
        self.next_onset = 0.0
        self.discord = 0.0
        self.drives = dict(zip(self.motivation.names, self.motivation.levels.tolist()))
        self.voice: Voice | None = None
        self._pending: deque[NoteEvent] = deque(maxlen=64)  # bounded: runs without audio never drain it

        d = self.drives
        self.percepts = {p.name: p for p in (
            FunctionPercept("presence", self.presence),
            FunctionPercept("heard key distance", lambda t: self.heard.distance(self.song.key())),
            FunctionPercept("breath", lambda t: d["breath"]),
        )}
        breath = self.percepts["breath"]
        ready = FunctionPercept("ready to sing", lambda t: max(0.0, d["desire"] - spec.threshold)
                                if breath.evaluate(t) >= spec.recovered else 0.0)
        sung_out = FunctionPercept("sung out", lambda t: 1.0 if self.breathless or d["desire"] <= 0.0 else 0.0)
        winded = FunctionPercept("winded", lambda t: max(0.0, 1.0 - breath.evaluate(t) / spec.recovered))
        recovered = FunctionPercept("recovered", lambda t: 1.0 if breath.evaluate(t) >= spec.recovered else 0.0)
        discord = FunctionPercept("discord", lambda t: self.discord)
        self.group = ActionGroup(
            self.name, rng=rng, alpha=0.0, on_event=selection_logger(world, self.name),
            tuples=[
                ActionTuple("sing", ready, _Activity("sing", self), DoUntil(until=sung_out), SING_VALUE),
                ActionTuple("pause", winded, _Activity("pause", self), DoUntil(until=recovered), PAUSE_VALUE),
                ActionTuple("listen", discord, Action("listen"), DoUntil(LISTEN_SECONDS), LISTEN_VALUE),
            ],
        )
        self._next_soft = float(rng.uniform(0.0, 1.0 / SOFT_RATE))  # spread the colony's load
        self._next_report = 0.0

    # -- perception ----------------------------------------------------------------------
    def presence(self, t: float) -> float:
        """Closeness of the rock to the centre, 0..1: the sensor's last reading, else the script."""
        if self.sensed is not None:
            return self.sensed
        return float(np.interp(t, self._script_t, self._script_level))

    def hear(self, note: NoteEvent, source: str) -> None:
        if source == INPUT and note.channel == self.spec.sensor_channel:
            if note.pitch == self.spec.rock:
                self.sensed = note.velocity / 127.0
            return
        self.heard.hear(self.world.clock.now(), note.pitch, note.duration)

    def _feel(self, t: float) -> None:
        """The soft-state step: discord from the ear, then the chemistry's inputs."""
        spec = self.spec
        self.heard.fade(t)
        distance = self.percepts["heard key distance"].evaluate(t)
        beyond = (distance - spec.correlated_within) / (STEPS / 2 - spec.correlated_within)
        self.discord = self.heard.amount() * min(1.0, max(0.0, beyond))
        self._feed(t)

    def _feed(self, t: float) -> None:
        """Set the chemistry's inputs for what the creature senses and does from ``t`` on."""
        spec, m = self.spec, self.motivation
        m.advance(t)
        boredom = m.level("boredom")
        presence = self.percepts["presence"].evaluate(t)
        singing = self.activity == "sing"
        m.set_input(t, "desire", spec.eagerness * presence * max(0.0, 1.0 - boredom)
                    - spec.suppression * self.discord - (spec.satiation if singing else 0.0))
        m.set_input(t, "boredom", spec.habituation * presence)
        m.set_input(t, "breath", -spec.breath_use if singing else spec.inhale if self.activity == "pause" else 0.0)
        self.drives.update(zip(m.names, m.levels.tolist()))

    # -- singing ----------------------------------------------------------------------------
    def begin_activity(self, t: float, activity: str) -> None:
        """Start singing (from where the song stopped) or pausing: breath now flows."""
        if activity == "sing":
            self.breathless = False
            self.next_onset = t
        self.activity = activity
        self._feed(t)

    def end_activity(self, t: float) -> None:
        self.activity = None
        self._feed(t)

    def timbre(self) -> tuple[int, float]:
        """``(velocity, sounding fraction of each beat)``: boredom makes singing soft and detached."""
        dull = self.spec.timbre_depth * min(1.0, self.drives["boredom"])
        return max(1, round(self.spec.velocity * (1.0 - dull))), 0.9 * (1.0 - dull)

    def sing(self, t: float) -> None:
        """Play every note of the song whose onset has come, while breath lasts."""
        m = self.motivation
        while not self.breathless and self.next_onset <= t:
            pitch, beats = self.song.current()
            rate = self.spec.tempo / 60.0 * min(PULSE_RANGE[1], max(PULSE_RANGE[0], self.drives["pulse"]))
            velocity, legato = self.timbre()
            onset, duration = self.next_onset, legato * beats / rate
            # A lower bound of breath at the note's end (recovery only adds to it), so a
            # note is never started that the creature cannot finish; no matrix exponential.
            if self.drives["breath"] - self.spec.breath_use * (onset + duration - m.time) <= 0.0:
                self.breathless = True
                self.world.emit("breathless", creature=self.name, phrase=self.song.phrase, note=self.song.note)
                return
            self.world.play(self, NoteEvent(round(onset, 6), pitch, velocity, self.spec.channel, round(duration, 6)))
            ended = self.song.step()
            self.next_onset = onset + (beats + (self.spec.phrase_rest if ended else 0.0)) / rate

    def played(self, note: NoteEvent) -> None:
        self._pending.append(note)

    # -- the tick ----------------------------------------------------------------------
    def tick(self, t: float) -> None:
        # Percepts change only at the soft-state rate, so selection runs at that rate too,
        # except while singing, when every tick may bring a note's onset.
        soft = t >= self._next_soft
        if soft:
            while self._next_soft <= t:
                self._next_soft += 1.0 / SOFT_RATE
            self._feel(t)
        if soft or self.activity == "sing":
            self.group.tick(t)
        if t >= self._next_report:
            self._next_report = t + REPORT_EVERY
            self._report(t)

    def _report(self, t: float) -> None:
        report_values(self.world, t, self.name, self.group, self.motivation)
        log = self.world.log
        levels = {name: p.evaluate(t) for name, p in self.percepts.items()}
        log.emit(t, "percepts", creature=self.name, phrase=self.song.phrase, note=self.song.note,
                 levels={**levels, "discord": self.discord, "heard amount": self.heard.amount()})

    # -- outputs ---------------------------------------------------------------------------
    def sound(self, out: np.ndarray, sample_rate: int) -> None:
        if self.voice is None:
            self.voice = Voice(self.spec.voice, sample_rate)
        now = self.world.clock.now()
        while self._pending and self._pending[0].time <= now:
            note = self._pending.popleft()
            self.voice.play(note.pitch, note.velocity, note.end)
        if self.voice.pool.active:
            self.voice.render(out, now)
        else:  # a silent rock costs nothing
            out[:] = 0.0

    # -- persistence -------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {
            "values": self.group.value_state(),
            "motivation": self.motivation.to_dict(),
            "song": {"phrase": self.song.phrase, "note": self.song.note},
            "heard": {"vector": self.heard.vector.tolist(), "weight": self.heard.weight, "time": self.heard.time},
            "sensed": self.sensed,
        }

    def restore(self, state: dict[str, Any]) -> None:
        for key in ("values", "motivation", "song", "heard", "sensed"):
            if key not in state:
                raise ValueError(f"sandstone state of {self.name!r} is missing {key!r}")
        phrase, note = int(state["song"]["phrase"]), int(state["song"]["note"])
        if not (0 <= phrase < len(self.song.phrases) and 0 <= note < len(self.song.phrases[phrase][0])):
            raise ValueError(f"sandstone state of {self.name!r}: song position {phrase}/{note} is not in its phrases")
        self.group.restore_values(state["values"])
        self.motivation.restore(state["motivation"], now=self.world.clock.now())
        self.song.phrase, self.song.note = phrase, note
        heard = bounds.table(state["heard"], "heard")
        vector = bounds.items(heard.get("vector"), "heard.vector", shortest=2, longest=2)
        self.heard.vector = np.array([bounds.number(x, f"heard.vector.{i}") for i, x in enumerate(vector)])
        self.heard.weight = bounds.number(heard.get("weight"), "heard.weight", low=0.0)
        self.heard.time = self.world.clock.now()
        self.sensed = None if state["sensed"] is None else bounds.number(state["sensed"], "sensed", low=0.0, high=1.0)
        self.drives.update(zip(self.motivation.names, self.motivation.levels.tolist()))
