"""Parts the hearing kinds share: an ear, a mouth, and an aural model that survives a save.

Thesis, "soundcreatures": each creature has "a microphone-as-ear and a loudspeaker-as-mouth".

* :class:`Ear` — amplitude segmentation (:class:`audio.segment.Segmenter`) into cepstral
  :class:`audio.utterance.Utterance`'s, deaf while its own mouth sings (half-duplex: the
  singing flow inhibits the hearing flow's saliency, :mod:`audio.self_hearing`). The singing
  flow exists before the first block arrives (the sample rate is only known then), so it is
  made here and attached to the segmenter's hearing flow when the segmenter is made.
* :class:`Mouth` — a :class:`audio.sampler.Sampler` sung through the body: "labelled
  positions on the animated body control parameters such as amplitude modulation (e.g. rib
  cage) and a simple low-pass filter (e.g. here, back angle)". Here the rib cage is the
  distance between the elbows (arms opening as the chest fills) and the back angle is the
  angle at the chest between pelvis and head (``[creature.mouth] rib_cage`` and ``back`` name
  other joints; :class:`BodyFeatures`); each is mapped from its 5–95 % range over the body's
  own motor graph so any body sweeps the whole parameter range.
  Singing is timed from the sample's length on the clock, not from rendering, so behaviour
  is the same whether or not audio is rendered (a run without out.wav or air).
* :class:`SingFrom` and :class:`AuralLearning` — the *Ac* side of the shared aural tree
  ("aural Ac percept trees"): a tuple's action sings an exemplar drawn from one percept;
  when such a tuple becomes valuable its percept is clustered (fission) and each new child
  becomes a new, more specific action ``same Tr | sing child`` (with ``refine`` the tuple
  then gives way to them); when a tuple *triggered* by an aural percept becomes valuable,
  the same fission yields ``child | same Ac`` (new sounds incorporated as triggers, figure
  39); a tuple hearing and singing one percept may instead answer each of its classes in
  kind, ``child | sing child`` (``in_kind``). Children that fuse away take their tuples with them.
* :func:`tree_state` / :func:`tree_from_state` — an utterance percept tree as a JSON-able
  dict (samples as base64 16-bit PCM, cepstra recomputed on load) for ``state()``; the
  file format of :func:`audio.utterance.save_aural_model` stays the one for seeding.
"""

from __future__ import annotations

import base64
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Callable

import numpy as np
import soxr
from pydantic import AfterValidator, BaseModel, Field, model_validator

from audio.cepstrum import cepstra
from audio.coupling import BodyControl, joint_angle, joint_distance
from audio.sampler import Sampler
from audio.segment import Segmenter
from audio.self_hearing import SingingState
from audio.utterance import DEFAULT_RADIUS, MAX_CLASSES, Utterance, UtterancePercept, load_aural_model
from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.learning import PerceptLearning, copy_value
from creatures.behaviour.percept import Percept
from creatures import bounds
from creatures.bounds import FINITE
from creatures.clock import clock_gap
from creatures.config import nearest
from creatures.kinds.parts import shared_graph
from creatures.motor.graph import MotorGraph
from creatures.motor.pose import BodyPose
from creatures.persist import StateFileError


class HearingSpec(BaseModel):
    """``[creature.hearing]``: how the ear cuts sound into utterances and groups them."""

    model_config = FINITE

    on_db: float = Field(12.0, gt=0, le=60, description="dB above the noise floor that starts a sound")
    off_db: float = Field(6.0, gt=0, le=60, description="dB above the floor that keeps a sound going")
    hold: float = Field(0.08, ge=0, le=1, description="dips shorter than this (s) do not end a sound")
    min_length: float = Field(0.1, gt=0, le=2, description="shorter sounds are ignored (clicks), s")
    max_length: float = Field(2.0, gt=0, le=10, description="longer sounds are cut into pieces, s")
    radius: float = Field(DEFAULT_RADIUS, gt=0, le=1e5, description="cepstral cluster radius of a sound class "
                                                               "(audio.cepstrum.utterance_distance; a class spans at most twice it)")
    memory: float = Field(0.25, gt=0, le=5, description="seconds a heard sound stays perceived")
    keep: int = Field(60, ge=3, le=1000, description="most exemplars a sound percept keeps (the newest); "
                                                      "clustering compares keep²/2 pairs, five time warps each")
    classes: int = Field(MAX_CLASSES, ge=1, le=1000, description="most sound classes the tree holds below its "
                                                                   "root; tuples pair heard and sung classes, so "
                                                                   "they grow as its square")
    half_duplex: bool = Field(True, description="deaf while singing (set false only to demonstrate why)")
    release: float = Field(0.3, ge=0, le=2, description="deafness held after singing stops (room echo), s")

    @model_validator(mode="after")
    def _hysteresis(self) -> "HearingSpec":
        if self.off_db > self.on_db:
            raise ValueError(f"off_db ({self.off_db}) must not exceed on_db ({self.on_db})")
        if self.max_length < self.min_length:
            raise ValueError("max_length must not be below min_length")
        return self


def _aural_model(path: str | None) -> str | None:
    """``path`` if it names an aural model file (``.json``). Whether it exists and loads is
    asked by :func:`resolve_aural_model` once the loader knows the directory of the config
    file that wrote the key (paths in a config are relative to that file, as every path is)."""
    if path is not None and Path(path).suffix != ".json":
        raise ValueError("not an aural model (a .json file with its .npz: `creatures aural-model` makes one "
                         "from sound files)")
    return path


def resolve_aural_model(path: str, base: Path) -> str:
    """``path`` (relative to ``base``, the directory of the file that names it) made absolute,
    if it names an aural model that loads: read now, so that a wrong file (``/etc/passwd``) is
    a config error at its key, not a crash when the creature is built. Raises ValueError."""
    resolved = (base / path).resolve()
    if not resolved.is_file():
        raise ValueError(f"file not found: {path}" + ("" if Path(path).is_absolute() else f" (looked in {base})"))
    try:
        load_aural_model(resolved)
    except (StateFileError, ValueError, ArithmeticError) as exc:
        raise ValueError(f"not a loadable aural model ({exc})") from None
    return str(resolved)


SeedModel = Annotated[str | None, AfterValidator(_aural_model)]
"""A config key naming an aural model (:func:`audio.utterance.save_aural_model`'s JSON,
absolute or relative to the config file that names it) to seed a creature with: "persistent
aural models … offer an ability to seed the creatures with musical material" (soundcreatures)."""
AuralModelFile = Annotated[str, AfterValidator(_aural_model)]
"""A required key naming an aural model (as :data:`SeedModel`, never absent)."""


class Ear:
    """Blocks in, utterances out; deaf while ``singing`` is salient (if ``half_duplex``)."""

    def __init__(self, spec: HearingSpec) -> None:
        self.spec = spec
        self.singing = SingingState(release=spec.release)
        self.segmenter: Segmenter | None = None

    def listen(self, t: float, block: np.ndarray, sample_rate: int) -> list[Utterance]:
        """Feed the block ending at clock time ``t``; return the utterances that ended. A
        clock gap before the block (``Segmenter.skip``) keeps the ear on the creature's clock."""
        start = t - len(block) / sample_rate
        if self.segmenter is None:
            s = self.spec
            self.segmenter = Segmenter(sample_rate, on_db=s.on_db, off_db=s.off_db, hold=s.hold,
                                       min_length=s.min_length, max_length=s.max_length, t0=start)
            if s.half_duplex:
                self.segmenter.hearing.inhibit_by(self.singing)
        events = []
        if jump := clock_gap(self.segmenter.fed_until, start):
            events = self.segmenter.skip(jump)
        return [Utterance.from_event(e) for e in [*events, *self.segmenter.feed(block)]]


class MouthSpec(BaseModel):
    """``[creature.mouth]``: how the body shapes the sung sound."""

    model_config = FINITE

    gain: float = Field(1.0, ge=0, le=4, description="gain of sung sounds before the body's amplitude")
    quiet: float = Field(0.3, ge=0, le=1, description="amplitude with the rib cage closed")
    loud: float = Field(1.0, ge=0, le=2, description="amplitude with the rib cage open")
    dull_hz: float = Field(1500.0, ge=50, le=96000, description="low-pass cutoff with the back bent")
    bright_hz: float = Field(9000.0, ge=50, le=96000, description="low-pass cutoff with the back straight")
    rib_cage: tuple[str, str] | None = Field(None, description="the two joints whose distance is the rib cage "
                                                               "(amplitude); default elbow_l and elbow_r, else the "
                                                               "left/right pair whose distance varies most in the "
                                                               "body's material (a bird's wings)")
    back: tuple[str, str, str] | None = Field(None, description="three joints whose angle at the middle one is the "
                                                                "back (low-pass); default pelvis, chest, head")


@dataclass(frozen=True)
class BodyFeatures:
    """The labelled body positions a mouth listens to, on one body: the rib cage (a distance
    between two joints) and the back angle (at the middle of three), each with its 5th and
    95th percentile over that body's motor graph, so any body sweeps the whole range."""

    rib_cage: tuple[int, int]
    back: tuple[int, int, int]
    ranges: dict[str, tuple[float, float]]

    @classmethod
    def of(cls, graph: MotorGraph, spec: MouthSpec) -> "BodyFeatures":
        """The features of ``graph``'s body; ValueError names a joint it lacks."""
        names = graph.skeleton.names
        back = spec.back or ("pelvis", "chest", "head")
        rib = spec.rib_cage or (("elbow_l", "elbow_r") if {"elbow_l", "elbow_r"} <= set(names)
                                else _widest_pair(graph))
        for key, joints in (("rib_cage", rib), ("back", back)):
            for joint in joints:
                if joint not in names:
                    raise ValueError(f"mouth.{key}: the body has no joint {joint!r}{nearest(joint, names, 'joints')}; "
                                     f"name the body's own joints in [creature.mouth] {key}")
        a, b = (names.index(j) for j in rib)
        u, v, w = (names.index(j) for j in back)
        positions = graph.poses.positions
        values = {"rib cage": np.linalg.norm(positions[:, a] - positions[:, b], axis=-1),
                  "back angle": _angles(positions[:, u] - positions[:, v], positions[:, w] - positions[:, v])}
        return cls((a, b), (u, v, w), {k: _percentiles(x) for k, x in values.items()})

    def controls(self) -> dict[str, Callable[[np.ndarray], float]]:
        """Each feature of one pose's joint positions ``(J, 3)``."""
        return {"rib cage": joint_distance(*self.rib_cage), "back angle": joint_angle(*self.back)}


def _widest_pair(graph: MotorGraph) -> tuple[str, str]:
    """The ``x_l``/``x_r`` joints whose distance varies most over the material (a bird's wing
    tips open as its chest fills); ValueError if the body has no left/right pair."""
    names = graph.skeleton.names
    pairs = [(n, n[:-2] + "_r") for n in names if n.endswith("_l") and n[:-2] + "_r" in names]
    if not pairs:
        raise ValueError("mouth.rib_cage: the body has no left/right joint pair (x_l, x_r) to open as a rib cage; "
                         "name two joints in [creature.mouth] rib_cage")
    positions = graph.poses.positions
    spread = [np.ptp(np.linalg.norm(positions[:, names.index(a)] - positions[:, names.index(b)], axis=-1))
              for a, b in pairs]
    return pairs[int(np.argmax(spread))]


def _angles(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    cos = np.einsum("ij,ij->i", u, w) / np.maximum(np.linalg.norm(u, axis=-1) * np.linalg.norm(w, axis=-1), 1e-12)
    return np.arccos(np.clip(cos, -1.0, 1.0))


def _percentiles(values: np.ndarray) -> tuple[float, float]:
    low, high = np.percentile(values, [5.0, 95.0])
    return float(low), float(high) if high > low else float(low) + 1e-6


KEPT_SOUNDS = 64
"""Sounds a mouth keeps in its sampler, ready to sing again without copying (the oldest not
sounding go first)."""


class Mouth:
    """Sings utterances through a body; tells the ear's singing flow while it sounds."""

    def __init__(self, spec: MouthSpec, singing: SingingState, graph: MotorGraph | None = None) -> None:
        """``graph``: the body it sings through (default the shipped figure's)."""
        self.spec = spec
        self.singing = singing
        self.features = BodyFeatures.of(graph if graph is not None else shared_graph(), spec)
        controls, ranges = self.features.controls(), self.features.ranges
        self.amplitude = BodyControl(controls["rib cage"], *ranges["rib cage"], spec.quiet, spec.loud)
        self.cutoff = BodyControl(controls["back angle"], *ranges["back angle"], spec.dull_hz, spec.bright_hz)
        self.sampler: Sampler | None = None
        # the sampler's slot of each sound, by the identity of its samples; the samples are kept
        # with it, so their id cannot be another sound's (a freed array's address is reused: a
        # new utterance there played an old one's slot, a different song in a process that had
        # freed other arrays first)
        self._index: dict[int, tuple[np.ndarray, int]] = {}
        self._queue: list[tuple[np.ndarray, float, int]] = []  # samples, gain, their rate
        self.since = self.until = -np.inf  # clock times the latest song began and ends
        self._idle = False  # a whole block rendered with nothing playing

    def sing(self, t: float, utterance: Utterance, gain: float = 1.0) -> float:
        """Start singing ``utterance`` at ``t``; returns when it will have been sung."""
        if not self.sounding(t):
            self.since = t
        self.until = max(self.until, t + len(utterance.samples) / utterance.samplerate)
        self.singing.sing(t, 1.0)  # binary: a fraction would only partly deafen the ear
        slot = self._slot(utterance.samples)
        if slot is not None:
            self.sampler.play(slot, gain=gain * self.spec.gain)
        else:
            self._queue.append((utterance.samples, gain * self.spec.gain, utterance.samplerate))
        return self.until

    def _slot(self, samples: np.ndarray) -> int | None:
        """The sampler's slot holding ``samples`` (these very samples), if it has one."""
        entry = self._index.get(id(samples)) if self.sampler is not None else None
        return entry[1] if entry is not None and entry[0] is samples else None

    def _forget_old(self) -> None:
        """Keep at most :data:`KEPT_SOUNDS` stored, letting the oldest go that are not sounding.
        The sampler used to be replaced when idle with more than that kept, so a mouth that
        was never idle kept every sound it sang: a rehearsed week of three_creatures_compared
        grew to 1.8 GB."""
        if len(self._index) <= KEPT_SOUNDS:
            return
        assert self.sampler is not None
        playing = {voice[0] for voice in self.sampler.playing}
        for key, (_, slot) in list(self._index.items()):  # oldest first
            if len(self._index) <= KEPT_SOUNDS:
                break
            if slot not in playing:
                del self._index[key]
                self.sampler.forget(slot)

    def sounding(self, t: float) -> bool:
        return t < self.until

    def sang_during(self, start: float, end: float) -> bool:
        """Whether the latest song overlapped ``[start, end]`` (its echo one tick late too)."""
        return self.since <= end and start <= self.until + self.singing.release

    def tick(self, t: float) -> None:
        """End the singing flow once the last sound is over (the ear's release follows)."""
        if not self.sounding(t):
            self.singing.silence(t)

    def render(self, out: np.ndarray, sample_rate: int, pose: BodyPose | None = None, *, cutoff: float = 1.0) -> None:
        """Fill ``out`` with the sung sounds shaped by ``pose`` (no body: loud and bright), the
        low-pass cutoff ``cutoff`` times what the body sets (a skill's ``voice.cutoff``)."""
        if self.sampler is None:
            self.sampler = Sampler(sample_rate, block_size=2 * len(out) + 2)
        if not self._queue and not self.sampler.playing and self._idle:
            out[:] = 0.0  # nothing sounding and the filter's tail has died: skip the filter
            return
        self._idle = not self._queue and not self.sampler.playing
        for samples, gain, rate in self._queue:
            slot = self._slot(samples)
            if slot is None:  # a sound heard (or a model made) at another rate sounds at its own pitch
                slot = self.sampler.add(samples if rate == sample_rate else soxr.resample(samples, rate, sample_rate))
                self._index[id(samples)] = (samples, slot)
            self.sampler.play(slot, gain=gain)
        self._queue.clear()
        self._forget_old()
        if pose is None:
            self.sampler.render(out, amplitude=self.spec.loud, cutoff_hz=self.spec.bright_hz * cutoff)
        else:
            self.sampler.render(out, amplitude=self.amplitude(pose), cutoff_hz=self.cutoff(pose) * cutoff)


# -- an utterance tree as JSON ------------------------------------------------------------------


def pack_samples(samples: np.ndarray) -> str:
    """Mono float samples in [−1, 1] as base64 of little-endian 16-bit PCM."""
    pcm = np.round(np.clip(samples, -1.0, 1.0) * 32767.0).astype("<i2")
    return base64.b64encode(pcm.tobytes()).decode("ascii")


def unpack_samples(text: str) -> np.ndarray:
    return (np.frombuffer(base64.b64decode(text), dtype="<i2") / 32767.0).astype(np.float32)


def tree_state(root: UtterancePercept) -> dict[str, Any]:
    """The tree's structure, parameters and exemplars (each utterance stored once)."""
    table: dict[int, int] = {}
    utterances: list[dict[str, Any]] = []

    def index(u: Utterance) -> int:
        if id(u) not in table:
            table[id(u)] = len(utterances)
            utterances.append({"samples": pack_samples(u.samples), "samplerate": u.samplerate, "time": u.time})
        return table[id(u)]

    def node(p: UtterancePercept) -> dict[str, Any]:
        return {"name": p.name, "born": p._born, "members": [index(u) for u in p.members],
                "children": [node(c) for c in p.utterance_children()]}

    return {"radius": root.radius, "max_children": root.max_children, "min_members": root.min_members,
            "max_members": root.max_members, "max_classes": root.max_classes, "memory": root.memory,
            "root": node(root),
            "utterances": utterances}


LONGEST_UTTERANCE = 60.0
"""Seconds: the longest saved utterance taken back (the ear cuts sounds at ``max_length``,
at most 10 s)."""


def utterance_from_state(saved: Any, what: str) -> Utterance:
    """An utterance saved as ``{"samples", "samplerate", "time"}`` (cepstra recomputed), or
    ValueError naming ``what``: a rate, a length or a time no ear produces is refused here,
    not when the creature first sings it."""
    saved = bounds.table(saved, what)
    rate = bounds.count(saved.get("samplerate"), f"{what}.samplerate", low=8000, high=192000)
    if not isinstance(saved.get("samples"), str):
        raise ValueError(f"{what}.samples: must be base64 text")
    samples = unpack_samples(saved["samples"])
    if not 0 < len(samples) <= LONGEST_UTTERANCE * rate:
        raise ValueError(f"{what}.samples: must hold 1 to {LONGEST_UTTERANCE:g} s of sound, found {len(samples)} samples")
    time = bounds.number(saved.get("time"), f"{what}.time", low=0.0, high=bounds.LATEST_TIME)
    return Utterance(samples, rate, cepstra(samples, rate), time)


def tree_from_state(state: dict[str, Any], like: UtterancePercept) -> UtterancePercept:
    """Rebuild a tree saved by :func:`tree_state`; raises ValueError naming what is wrong.

    The tree's settings (radius, sizes, memory) are those of ``like``, the tree the config
    built: an edited config wins over the saved file; the classes and exemplars are learnt."""
    try:
        saved = bounds.items(state["utterances"], "tree.utterances", longest=100_000)
        table = [utterance_from_state(u, f"tree.utterances.{i}") for i, u in enumerate(saved)]
        options = {"radius": like.radius, "max_children": like.max_children, "min_members": like.min_members,
                   "max_members": like.max_members, "max_classes": like.max_classes, "memory": like.memory}

        def build(d: dict[str, Any], parent: UtterancePercept | None, where: str) -> UtterancePercept:
            p = UtterancePercept(bounds.text(d.get("name"), f"{where}.name"), parent=parent, **options)
            p._born = bounds.count(d.get("born"), f"{where}.born")
            members = bounds.items(d.get("members"), f"{where}.members", longest=len(table))
            p.members = [table[bounds.count(i, f"{where}.members", high=len(table) - 1)] for i in members]
            for k, child in enumerate(bounds.items(d.get("children"), f"{where}.children", longest=like.max_children)):
                build(bounds.table(child, f"{where}.children.{k}"), p, f"{where}.children.{k}")
            return p

        return build(bounds.table(state["root"], "tree.root"), None, "tree.root")
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise ValueError(f"malformed aural model state ({type(exc).__name__}: {exc})") from None


# -- the Ac side of the aural tree ------------------------------------------------------------


class SingFrom(Action):
    """Ac percept: sing an exemplar drawn from ``percept`` (nothing while it has none).

    ``perform(t, utterance, percept)`` is the kind's singing (mouth, EDL, log). Actions on
    one percept share a name, so credit flows between all tuples singing the same class.
    """

    def __init__(self, percept: UtterancePercept, rng: np.random.Generator,
                 perform: Callable[[float, Utterance, UtterancePercept], None]) -> None:
        super().__init__(f"sing {percept.name}")
        self.percept = percept
        self.rng = rng
        self.perform = perform

    def start(self, t: float, tuple_: ActionTuple) -> None:
        if self.percept.members:
            self.perform(t, self.percept.draw(self.rng), self.percept)


class Singers:
    """The one :class:`SingFrom` of each percept, shared by every tuple that sings it (credit
    flows between them by its name), and held only while one does.

    A plain dict kept every singer made, and each singer holds its percept, whose members hold
    their raw samples: every class that ever fused away stayed in memory for the whole run.
    Weakly held, a singer goes with its last tuple, so its id cannot be reused while it is kept.
    """

    def __init__(self, rng: np.random.Generator, perform: Callable[[float, Utterance, UtterancePercept], None]) -> None:
        self.rng = rng
        self.perform = perform
        self._of: weakref.WeakValueDictionary[int, SingFrom] = weakref.WeakValueDictionary()

    def __call__(self, percept: UtterancePercept) -> SingFrom:
        singer = self._of.get(id(percept))
        if singer is None:
            singer = self._of[id(percept)] = SingFrom(percept, self.rng, self.perform)
        return singer


class AuralLearning(PerceptLearning):
    """:class:`PerceptLearning` for a tree of utterance percepts shared by Tr and Ac.

    Clustering costs n²/2 time warps, so one percept is re-clustered at most every
    ``refission_every`` seconds however often its tuples earn credit.

    ``refine``: a tuple singing a class that has split gives way to the tuples singing its
    children (thesis, "aural Ac percept trees": "Action-tuples start at the top of the tree,
    carrying a payload that plays out a wide variety of sounds … and slowly refine what it is
    that they should be playing on the basis value propagation"). Left beside them, the
    parent tuple sings every child class in proportion to its exemplars, so its value is
    their mean: credited in full whenever its exemplar happens to fall in a rewarded class, it
    keeps a value near the best child's, and Boltzmann selection keeps choosing it and with it
    the unrewarded classes. Refined, the tuples with one Tr that sing the children of one
    class are that class's *family* and take over the refined tuple's duties: a valuable
    member reviews the class's clustering as well as its own (the children of a class are
    clustered at the class: thesis, "extending the percept tree", "the highest level percept
    in this portion of the tree"), and a class it gains later is given a member (V copied
    from the member reviewed), so the repertoire still grows with what the creature hears.

    ``in_kind``: a tuple whose Tr and Ac are one percept (it answers a sound of that percept
    by singing one) refines both sides together: each class of the percept gets a tuple
    ``class | sing class``, an answer in kind, instead of the class as a new trigger of the same
    song and as a new song on the same trigger (thesis, "soundcreatures": "This common tree is
    shared in both *Tr* and *Ac* areas"). With ``refine`` it gives way to them as a singing
    tuple does, and its family is the answers to the classes of one class.
    """

    def __init__(self, root: UtterancePercept, sing_from: Callable[[UtterancePercept], SingFrom], *,
                 refission_every: float = 10.0, refine: bool = False, in_kind: bool = False,
                 **options: Any) -> None:
        super().__init__(**options)
        self.root = root
        self.sing_from = sing_from
        self.refission_every = float(refission_every)
        self.refine = refine
        self.in_kind = in_kind
        # when each percept last split, by the percept itself (weakly: one that fused away goes,
        # and a new percept never inherits its time through a reused id)
        self._clustered: weakref.WeakKeyDictionary[UtterancePercept, float] = weakref.WeakKeyDictionary()

    def thresholds(self, group: ActionGroup) -> tuple[float, float]:
        """As :meth:`PerceptLearning.thresholds`, over the *plastic* tuples only: a fixed,
        high-valued perception action (attending a sound, being clicked) is the reward, not
        one of the hypotheses whose worth is being judged, and would otherwise set the bar
        above every one of them."""
        values = [tp.value.to_float() for tp in group.tuples if getattr(tp.value, "plasticity", 1.0) > 0]
        mean = float(np.mean(values)) if values else 0.0
        return self.statistics * mean, self.innovation * mean

    def review(self, group: ActionGroup, tuple_: ActionTuple, t: float, innovation: float | None = None) -> None:
        if innovation is None:
            _, innovation = self.thresholds(group)
        worth = tuple_.value.to_float()
        sung = tuple_.action.percept if isinstance(tuple_.action, SingFrom) else None
        for percept in (tuple_.trigger, sung, self._family(group, tuple_)):
            if not isinstance(percept, UtterancePercept) or not self._in_tree(percept):
                continue
            if t - self._clustered.get(percept, -np.inf) < self.refission_every:
                continue
            self._clustered[percept] = t
            before = {id(c) for c in self.root.walk()}
            born = percept.fission(worth, innovation)
            if born:
                self._emit("fission", t, percept=percept.name, children=[c.name for c in born],
                           members=[len(c.members) for c in born])
            if len({id(c) for c in self.root.walk()}) < len(before) + len(born):
                self.prune(group, t)
        if isinstance(tuple_.trigger, UtterancePercept) and not self._answers(tuple_):
            self.spawn_hypotheses(group, tuple_, t)
        if sung is not None:
            self.spawn_actions(group, tuple_, t)

    def _in_tree(self, percept: UtterancePercept) -> bool:
        return percept.root() is self.root  # a fused-away child is the root of its own stump

    @staticmethod
    def _sings(group: ActionGroup, trigger: Percept, percept: UtterancePercept) -> bool:
        """Whether a tuple of ``group`` with Tr ``trigger`` sings ``percept``."""
        return any(tp.trigger is trigger and getattr(tp.action, "percept", None) is percept for tp in group.tuples)

    def _answers(self, tuple_: ActionTuple) -> bool:
        """Whether ``tuple_`` answers in kind: ``in_kind``, and it sings the percept it hears."""
        return self.in_kind and isinstance(tuple_.action, SingFrom) and tuple_.trigger is tuple_.action.percept

    def _family(self, group: ActionGroup, tuple_: ActionTuple) -> UtterancePercept | None:
        """With ``refine``, the class whose family ``tuple_`` belongs to: the parent of the
        class it sings when no tuple with its Tr (an answer in kind: the parent's answer)
        sings that parent (refined away, or never made); else None."""
        if not self.refine or not isinstance(tuple_.action, SingFrom):
            return None
        parent = tuple_.action.percept.parent
        if not isinstance(parent, UtterancePercept) \
                or self._sings(group, parent if self._answers(tuple_) else tuple_.trigger, parent):
            return None
        return parent

    def spawn_actions(self, group: ActionGroup, tuple_: ActionTuple, t: float) -> list[ActionTuple]:
        """``same Tr | sing child | same Du | V`` for each child of the sung percept (an answer
        in kind: ``child | sing child``); with ``refine`` also for each class of the tuple's
        family that lacks one, and a tuple whose class has children gives way to theirs."""
        sung = tuple_.action.percept
        family = self._family(group, tuple_)
        classes = sung.utterance_children() + ([] if family is None else family.utterance_children())
        answers = self._answers(tuple_)
        made = []
        sung_by = {(id(tp.trigger), id(getattr(tp.action, "percept", None))) for tp in group.tuples}
        for child in classes:
            trigger = child if answers else tuple_.trigger
            if (id(trigger), id(child)) in sung_by:  # as _sings, once for all the classes
                continue
            sung_by.add((id(trigger), id(child)))
            du = tuple_.do_until
            action = self.sing_from(child)
            hypothesis = ActionTuple(f"{trigger.name}|{action.name}", trigger, action,
                                     DoUntil(du.duration, until=du.until, learn=du.learn),
                                     copy_value(tuple_.value))
            group.add(hypothesis)
            made.append(hypothesis)
            self._emit("hypothesis", t, tuple=hypothesis.name, parent=tuple_.name, side="in kind" if answers else "Ac")
        if self.refine and sung.utterance_children():
            group.remove(tuple_, t)
            self._emit("refinement", t, tuple=tuple_.name, percept=sung.name,
                       children=[c.name for c in sung.utterance_children()])
        return made

    def prune(self, group: ActionGroup, t: float) -> None:
        """Drop the tuples of percepts that fused away (they were detached from the tree)."""
        alive = {id(p) for p in self.root.walk()}
        gone = [tp for tp in group.tuples
                if isinstance(tp.trigger, UtterancePercept) and id(tp.trigger) not in alive
                or isinstance(tp.action, SingFrom) and id(tp.action.percept) not in alive]
        for tp in gone:
            group.remove(tp, t)
        if gone:
            self._emit("fusion", t, tuples=[tp.name for tp in gone])
