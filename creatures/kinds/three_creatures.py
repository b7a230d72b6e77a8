"""*three creatures*: two creatures and a performer, each hearing the others through the
same air (thesis, "three creatures (performance)").

"Each has a simple motivational model – controlling the sound that they hear, and their
willingness to sing it back out. This is driven in part by a simple correlation metric
across what they hear and what they remember. Their memories were periodically flushed with
pre-selected samples by an external 'score providing' computer." The original creatures
were csound patches with no behaviour system: a null hypothesis. This kind keeps that
shape — a data flow, no action-selection — so the installation still asks its question.

Design:

* **Ear and mouth** are the soundcreatures' (:mod:`creatures.kinds.hearing_parts`), without
  a body: performer and creatures all reach each ear through one room (``[audio] air``), and
  the creature is deaf while it sings (half-duplex), so it only answers the others.
* **Correlation metric.** A sound's *profile* is the slope of its long-term average log-mel
  spectrum (40 bands), standardised (:func:`profile` says why the slope); the correlation
  of two sounds is the Pearson correlation of their profiles (one matrix-vector product
  against the whole memory). *Familiarity* of a heard sound is its highest correlation with
  a memory.
* **Motivational model** (:class:`Motivation`): ``interest`` grows toward 1 with time and
  is spent by remembering; a heard sound is remembered when its familiarity is below the
  current interest — an interested creature takes in even familiar sounds, a sated one only
  strange ones. A full memory forgets the memory most like the newcomer, so one rare sound
  is not pushed out by copies of a common one. ``urge`` (willingness to sing) grows by
  ``urge_gain × (1 + familiarity) / 2`` with each heard sound (any sound moves it, a
  recognised one twice as much as an unrelated one) and decays. When it reaches 1 the
  creature sings after a reaction time drawn from ``latency`` (two creatures moved by one
  sound must not sing at once, each deaf to the other). It sings a memory drawn with
  probability ∝ exp(``in_kind`` × its correlation with what it just heard) (answering in
  kind) ÷ its number of copies in memory (each kind of sound counts once); the urge is spent.
* **The score computer's flush.** Every ``flush_every`` seconds the latest ``flush_size``
  sounds of the input — sounds heard while no creature of the colony was singing (the score
  computer knows when they sing) — are remembered whatever the creature's interest.
  ``seed_model`` (an aural model saved by :func:`audio.utterance.save_aural_model`) fills
  the memory at the start: the pre-selected samples.
* **The score** (``[[creature.score]]``, :class:`ScoreFlush`): "their memories were
  periodically flushed with pre-selected samples by an external 'score providing' computer".
  At ``at`` seconds the oldest ``slots`` memories are replaced by the first ``slots`` samples
  of an aural model (origin ``score``), whatever the creature's interest: the score computer
  decides what the creatures have to sing, the input only what moves them to sing it.

Events: ``sound`` (heard: span, familiarity, remembered), ``selection`` (``remember`` /
``ignore`` / ``sing``), ``sing`` (span and the memory's origin), ``flush`` (with the memory
after it: each sound's origin and the time it was heard), and every
``REPORT_EVERY`` s ``values`` (each memory's correlation with the latest sound),
``motivation`` and ``percepts`` (memory size by origin).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal

# by name: librosa's lazy parts load at import, not at a creature's first heard word
from librosa import stft
from librosa.filters import mel
import numpy as np
from pydantic import BaseModel, Field, field_validator

from audio.utterance import Utterance, load_aural_model
from creatures.behaviour.motivation import Motivation
from creatures.kinds import register
from creatures import bounds
from creatures.bounds import FINITE, LARGEST_RATE, LONGEST_SECONDS, Seconds
from creatures.config import config_error, written_in
from creatures.kinds.base import CreatureKind, CreatureSpec, built_once
from creatures.kinds.hearing_parts import (AuralModelFile, Ear, HearingSpec, Mouth, MouthSpec, SeedModel, pack_samples,
                                              resolve_aural_model, utterance_from_state)

if TYPE_CHECKING:
    from creatures.runtime.world import World

REPORT_EVERY = 0.5
N_MELS = 40
PROFILE = N_MELS - 1
"""Length of a profile (slopes between neighbouring mel bands)."""
SAME = 0.7
"""Profiles correlated above this count as copies of one sound (same word ≈ 0.9, others ≈ 0.3).

Re-derived (``python -m bench sound_classes``; docs/hearing.md, "Sound classes on real
voices"): the threshold with the largest Youden's J (same-class pairs above it minus
other-class pairs above it) summed over the tuning corpora. Above 0.7 fall 94 % of pairs of
one espeak-ng word said by one voice at two speeds and pitches (1.3 % of other words' pairs),
every pair of one sampled instrument playing one phrase (6 % of others), and 79 % of pairs of
one synthetic word (9 % of others); alone, those corpora would put it at 0.7, 0.9 and 0.6. One
word said by two voices is a copy only 9 % of the time, and no threshold does better (J ≤
0.20): the profile tells voices apart more than words."""


@functools.lru_cache(maxsize=4)
def _mel(sample_rate: int, n_fft: int) -> np.ndarray:
    return mel(sr=sample_rate, n_fft=n_fft, n_mels=N_MELS)


def profile(samples: np.ndarray, sample_rate: int, *, n_fft: int = 512) -> np.ndarray:
    """The spectral shape of a sound: the band-to-band slope of its long-term average log-mel
    spectrum, standardised, so ``profile(a) @ profile(b) / PROFILE`` is a Pearson correlation.

    Why the slope and not the spectrum: every voiced sound falls with frequency, and that
    shared tilt made any two sounds correlate at 0.8–0.98 (measured on the formant words and
    the generated phrase); the slope keeps the peaks (formants, partials) that tell sounds
    apart — same word ≈ 0.9, different words ≈ 0.3."""
    y = np.asarray(samples, dtype=np.float32)
    if len(y) < n_fft:
        y = np.pad(y, (0, n_fft - len(y)))
    power = np.abs(stft(y, n_fft=n_fft, hop_length=n_fft // 2, center=False)) ** 2
    slope = np.diff(np.log10(_mel(sample_rate, n_fft) @ power.mean(axis=1) + 1e-10))
    return (slope - slope.mean()) / max(slope.std(), 1e-12)


def correlations(heard: np.ndarray, profiles: np.ndarray) -> np.ndarray:
    """Pearson correlation of one profile with each row of ``profiles``."""
    return profiles @ heard / PROFILE if len(profiles) else np.zeros(0)


@dataclass(eq=False)
class Memory:
    """A remembered sound: samples to sing, its profile, and where it came from."""

    utterance: Utterance
    profile: np.ndarray
    origin: str  # "seed", "heard", "flush" or "score"


MOST_MEMORIES = 256
"""Most sounds a creature may remember (``memory_size``), and read back from a saved state."""


class ScoreFlush(BaseModel):
    """One of the score computer's flushes: at ``at`` s, ``slots`` memories become the first
    ``slots`` samples of ``model`` (thesis, "three creatures (performance)": "pre-selected
    samples by an external 'score providing' computer")."""

    model_config = FINITE
    at: Seconds = Field(description="clock time of the flush, s")
    model: AuralModelFile = Field(description="aural model (save_aural_model JSON, or `creatures aural-model` "
                                              "from sound files; relative to the config) holding the pre-selected samples")
    slots: int = Field(1, ge=1, le=MOST_MEMORIES, description="memory slots flushed (the oldest memories "
                                                              "give way); at most the model's samples are used")


class ThreeCreaturesSpec(CreatureSpec):
    kind: Literal["three_creatures"]
    memory_size: int = Field(8, ge=1, le=MOST_MEMORIES, description="sounds a creature remembers")
    interest_growth: float = Field(0.08, ge=0, le=LARGEST_RATE, description="interest regained per second")
    interest_cost: float = Field(0.3, ge=0, le=LARGEST_RATE, description="interest spent by remembering a sound")
    urge_gain: float = Field(0.8, ge=0, le=LARGEST_RATE, description="urge to sing added by a fully familiar sound "
                                                    "(half as much by an unrelated one)")
    urge_decay: float = Field(0.05, ge=0, le=LARGEST_RATE, description="rate per second at which the urge to sing fades")
    flush_every: float = Field(15.0, gt=0, le=LONGEST_SECONDS, description="seconds between the score computer's flushes")
    flush_size: int = Field(2, ge=0, le=256, description="memory slots re-seeded from the input per flush")
    seed_model: SeedModel = Field(None, description="aural model (save_aural_model JSON; relative to the "
                                                    "config) seeding the memory")
    in_kind: float = Field(1.0, ge=0, le=100, description="how strongly a song answers in kind: memories weigh "
                                                   "exp(in_kind × correlation with the sound just heard)")
    latency: tuple[Seconds, Seconds] = Field((0.3, 1.5), description="range of seconds between being moved "
                                                                  "to sing and singing")
    score: list[ScoreFlush] = Field([], max_length=10_000, description="the score computer's pre-selected "
                                    "flushes, in time order")
    hearing: HearingSpec = HearingSpec(hold=0.05)
    mouth: MouthSpec = MouthSpec()
    READ_ONCE: ClassVar[dict[str, str]] = {
        **CreatureSpec.READ_ONCE,
        **built_once("interest_growth", "urge_decay", "seed_model", "score", "hearing", "mouth")}
    """What :class:`ThreeCreature` builds when it starts: its drives' growth and decay, the
    memory it is seeded with, the score computer's flushes, its ear and its mouth."""

    def check_references(self, file: Path, where: dict, prefix: tuple) -> None:
        """Tie the aural models to the directory of the file that names each (and load them)."""
        keys = [(("seed_model",), self, "seed_model")] if self.seed_model is not None else []
        keys += [(("score", i, "model"), flush, "model") for i, flush in enumerate(self.score)]
        for key, holder, attr in keys:
            at = (*prefix, *key)
            try:
                setattr(holder, attr, resolve_aural_model(getattr(holder, attr), written_in(where, at, file).parent))
            except ValueError as exc:
                raise config_error(file, where, at, str(exc)) from None

    @field_validator("score")
    @classmethod
    def _in_order(cls, score: list[ScoreFlush]) -> list[ScoreFlush]:
        for i in range(1, len(score)):
            if score[i].at <= score[i - 1].at:
                raise ValueError(f"score times must increase: flush {i} at {score[i].at} s "
                                 f"is not after flush {i - 1} at {score[i - 1].at} s")
        return score

    @field_validator("latency")
    @classmethod
    def _range(cls, latency: tuple[float, float]) -> tuple[float, float]:
        if not 0 <= latency[0] <= latency[1]:
            raise ValueError(f"latency must be [low, high] seconds with 0 <= low <= high, got {list(latency)}")
        return latency


@register("three_creatures")
class ThreeCreature(CreatureKind):
    Spec = ThreeCreaturesSpec
    DRIVES = ("interest", "urge")
    REWARDABLE = False  # a data flow with no action selection: nothing to credit

    def __init__(self, spec: ThreeCreaturesSpec, world: "World", rng: np.random.Generator) -> None:
        super().__init__(spec, world, rng)
        self.ear = Ear(spec.hearing)
        self.mouth = Mouth(spec.mouth, self.ear.singing)
        self.motivation = Motivation({"interest": 1.0, "urge": 0.0},
                                     growth={"interest": spec.interest_growth},
                                     decay={"urge": spec.urge_decay}, equilibrium={"urge": 0.0}, ceiling=1.0)
        self.memory: list[Memory] = []
        self.score: list[Utterance] = []  # the input's latest sounds, for the next flush
        self.latest: np.ndarray | None = None
        self._next_flush = spec.flush_every * (0.5 + 0.5 * rng.random())  # spread the colony's flushes
        self._next_report = 0.0
        self._sing_at = np.inf  # when the urge, once felt, becomes a song
        if spec.seed_model is not None:
            for u in load_aural_model(spec.seed_model).members[: spec.memory_size]:
                self.memory.append(Memory(u, profile(u.samples, u.samplerate), "seed"))
        # The score's samples, profiled once (each flush of one model sings the same samples).
        self._score = [(f.at, [Memory(u, profile(u.samples, u.samplerate), "score")
                               for u in load_aural_model(f.model).members[: min(f.slots, spec.memory_size)]])
                       for f in spec.score]

    def described(self) -> list[Any]:
        s = self.spec
        memory = [f"seeded from {s.seed_model}: {len(self.memory)} sounds"] if s.seed_model is not None else []
        memory.append(f"the input's latest {s.flush_size} sounds flushed in every {s.flush_every:g} s")
        score = [f"at {f.at:g} s: {len(samples)} slots ← {Path(f.model).name}" for f, (_, samples) in zip(s.score, self._score)]
        return [(f"memory [{s.memory_size} sounds]", memory), *([("score", score)] if score else [])]

    @property
    def _profiles(self) -> np.ndarray:
        return np.array([m.profile for m in self.memory]).reshape(len(self.memory), PROFILE)

    # -- hearing: what to take in, how much it moves the creature to sing ----------------
    def listen(self, t: float, block: np.ndarray, sample_rate: int) -> None:
        for u in self.ear.listen(t, block, sample_rate):
            self._heard(t, u, sample_rate)

    def _heard(self, t: float, u: Utterance, sample_rate: int) -> None:
        p = profile(u.samples, sample_rate)
        c = correlations(p, self._profiles)
        familiarity = float(c.max()) if len(c) else 0.0
        start = u.time - len(u.samples) / sample_rate
        if not any(getattr(o, "mouth", None) is not None and o.mouth.sang_during(start, u.time)
                   for o in self.world.creatures):
            self.score = [*self.score, u][-max(self.spec.flush_size, 1):]
        interest = self.motivation.level("interest", t)
        remember = familiarity < interest
        if remember:
            self._remember(Memory(u, p, "heard"))
            self.motivation.perturb(t, "interest", -self.spec.interest_cost)
        self.motivation.perturb(t, "urge", self.spec.urge_gain * (1.0 + familiarity) / 2.0)
        self.latest = p
        self.world.emit("sound", creature=self.name, start=start, end=u.time, familiarity=familiarity,
                        remembered=remember)
        self.world.emit("selection", creature=self.name, tuple="remember" if remember else "ignore",
                        value=interest - familiarity)

    def _remember(self, memory: Memory) -> None:
        """Keep ``memory``; a full memory forgets the sound most like it (so a rare sound is
        not pushed out by many copies of a common one)."""
        if len(self.memory) >= self.spec.memory_size:
            del self.memory[int(np.argmax(correlations(memory.profile, self._profiles)))]
        self.memory.append(memory)

    # -- the tick: flush, sing -----------------------------------------------------------
    def tick(self, t: float) -> None:
        self.motivation.advance(t)
        self.mouth.tick(t)
        if t >= self._next_flush:
            self._next_flush = t + self.spec.flush_every
            self._flush(t)
        while self._score and t >= self._score[0][0]:
            self._scored(t, self._score.pop(0)[1])
        if self.memory and self._sing_at == np.inf and self.motivation.level("urge") >= 1.0:
            self._sing_at = t + self.rng.uniform(*self.spec.latency)
        if t >= self._sing_at and not self.mouth.sounding(t):
            self._sing_at = np.inf
            self._sing(t)
        if t >= self._next_report:
            self._next_report = t + REPORT_EVERY
            self._report(t)

    def _flush(self, t: float) -> None:
        fresh = self.score[-self.spec.flush_size:] if self.spec.flush_size else []
        for u in fresh:
            self._remember(Memory(u, profile(u.samples, u.samplerate), "flush"))
        self.score = []
        self._emit_flush(fresh, "input")

    def _scored(self, t: float, samples: list[Memory]) -> None:
        """The score computer's flush: the oldest memories give way to ``samples``, only as many
        as the memory lacks room for (a memory not yet full keeps every sound it has room for)."""
        keep = self.spec.memory_size - len(samples)
        self.memory = [*(self.memory[max(len(self.memory) - keep, 0):] if keep > 0 else []), *samples]
        self._emit_flush([m.utterance for m in samples], "score")

    def _emit_flush(self, sounds: list[Utterance], source: str) -> None:
        self.world.emit("flush", creature=self.name, source=source, sounds=len(sounds),
                        heard_at=[u.time for u in sounds],
                        memory=[[m.origin, m.utterance.time] for m in self.memory])

    def _sing(self, t: float) -> None:
        """Sing a memory: those like what was just heard are favoured (answering in kind),
        each kind of sound counted once however many copies are remembered."""
        profiles = self._profiles
        c = correlations(self.latest, profiles) if self.latest is not None else np.zeros(len(self.memory))
        copies = ((profiles @ profiles.T / PROFILE) > SAME).sum(axis=1)
        weights = np.exp(self.spec.in_kind * c) / copies
        memory = self.memory[int(self.rng.choice(len(self.memory), p=weights / weights.sum()))]
        end = self.mouth.sing(t, memory.utterance)
        self.motivation.perturb(t, "urge", -1.0)
        self.world.emit("selection", creature=self.name, tuple="sing", value=float(weights.max()))
        self.world.emit("sing", creature=self.name, start=t, end=end, origin=memory.origin,
                        heard_at=memory.utterance.time)

    def _report(self, t: float) -> None:
        log = self.world.log
        c = correlations(self.latest, self._profiles) if self.latest is not None else np.zeros(len(self.memory))
        log.emit(t, "values", creature=self.name, values={f"memory {i}": float(x) for i, x in enumerate(c)})
        log.emit(t, "motivation", creature=self.name,
                 drives=dict(zip(self.motivation.names, self.motivation.levels_at(t).tolist())))
        origins = [m.origin for m in self.memory]
        log.emit(t, "percepts", creature=self.name, sizes={o: origins.count(o) for o in ("seed", "heard", "flush", "score")})

    def sound(self, out: np.ndarray, sample_rate: int) -> None:
        self.mouth.render(out, sample_rate)

    # -- persistence ---------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {"motivation": self.motivation.to_dict(),
                "memory": [{"samples": pack_samples(m.utterance.samples), "samplerate": m.utterance.samplerate,
                            "time": m.utterance.time, "origin": m.origin} for m in self.memory]}

    def restore(self, state: dict[str, Any]) -> None:
        try:
            memory = []
            # The config's memory_size wins: a memory saved larger keeps its first sounds.
            saved = bounds.items(state["memory"], "memory", longest=MOST_MEMORIES)[: self.spec.memory_size]
            for i, m in enumerate(saved):
                utterance = utterance_from_state(m, f"memory.{i}")
                memory.append(Memory(utterance, profile(utterance.samples, utterance.samplerate), str(m["origin"])))
            self.motivation.restore(state["motivation"], now=self.world.clock.now())
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{self.name}: malformed saved memory ({type(exc).__name__}: {exc})") from None
        self.memory = memory
