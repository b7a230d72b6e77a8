"""*ozymandias*: sound creatures trained on a spoken text by an author's clicks, reading the
recording back out of time, and writing what they did as an edit decision list (thesis,
"ozymandias (video)"; the hearing is that of "soundcreatures" and "aural models").

"Simple creatures are trained on the text of the poem (by repeatedly playing the text at
them) … here the author controls the reward of these creatures with a simple mouse-click.
The resulting creatures act as a stimulateable delay line … becoming excited by the text of
the poem, and reading parts of the audio material back out of time. … instructions
concerning the manipulation of sound are also stored to file – equivalent in use to an Edit
Decision List (EDL) – for higher fidelity off-line manipulation."

Design decisions:

* **Training by hearing.** Every word the ear cuts from the recording joins the "any sound"
  utterance percept (the latest ``max_members`` are kept), so repeated readings of the text
  fill the repertoire. Air is off in the shipped config: the creatures hear the recording
  itself, which is what makes an EDL into the recording possible (with air on the material
  would be the room, not the source).
* **The author's click is scripted, or live.** ``clicks`` lists the seconds at which the
  author clicks; a reward from outside (an ``[[input]]`` reward route) is a live click, the
  same percept (not a value added to whatever ran: the click tuple's credit assignment
  decides what is trained). A click is a highly salient percept (``CLICK_SALIENCE``, far
  above 1, as the thesis's startling click) triggering a non-plastic, highly valued
  ``clicked`` tuple (the clicker-training pattern of the thesis), so it always wins the
  interruption it causes and whatever the creature was doing just before is credited toward
  the click's value. Valuable reading tuples cluster their percept (:class:`AuralLearning`)
  and each class of words gets its own reading tuples; the tuple reading the split percept
  gives way to them (``refine``: thesis, "aural Ac percept trees", tuples "slowly refine what
  it is that they should be playing"), so the creature's reading narrows to the classes of
  words it was clicked for. Left in place, ``read`` and ``echo`` read every class, were
  clicked whenever their word fell in a clicked class, kept a value near the clicked class's
  readers and took a third of the readings, half of them unclicked.
* **Listening grounds the values between clicks.** ``listen`` (0.3) is non-plastic, like
  ``clicked``: hearing the text again is this creature's training and the act it returns to,
  so its worth is the author's, not learnt. Reading is appetitive (thesis, "credit
  assignment": values of appetitive behaviours are related to the consummatory actions they
  lead up to), valued by what follows it: a click, or listening again. With the click as the
  only ground, a creature the author stops clicking only passes β × one reading's value to
  another, and ``read`` fell to 1.8e-4 of the click's value in 30 days (tests/test_thirty_days.py);
  grounded by listening it settles where reading followed by listening is worth β × 0.3 and
  keeps preferring what it was clicked for. (Withholding credit until a first reward would
  not help: the decay starts again after the last click.)
* **A stimulated delay line.** A drive, ``excitement``, jumps with each heard word and
  decays between (half-life ``calm``); the ``read`` tuple triggers on it, the ``echo`` tuple
  on a word just heard. Reading takes a part (``shortest`` seconds up to the whole) of an
  exemplar and plays it now, out of time, at a gain that grows with excitement.
* **Hearing while reading.** Half-duplex is off by default: a delay line keeps taking in
  the text while it reads (with air off it never hears itself anyway).
* **No body.** Ozymandias's images came from *sand:stone*; these creatures are voices only.
* **The EDL is the truth.** The voice plays exactly the heard samples, a part at a time,
  scaled by one gain, with no filter, so ``render_edl`` from the source recording reproduces
  the creature's output sample for sample (tests check it against ``out.wav``).

EDL format (``<creature>.edl.json``, written by :meth:`Ozymandias.finish`)::

    {"format": "creature-music edl", "version": 1,
     "sample_rate": 22050,            # frames below are at this rate
     "creature": "echo", "mix": {"gain": 0.8, "pan": -0.5},   # the creature's place in out.wav
     "entries": [{"source_start": 1.2345, "source_end": 1.5678,   # seconds in the recording
                  "output_time": 7.5,                              # seconds in out.wav
                  "source_start_frame": 27221, "source_end_frame": 34570,
                  "output_frame": 165375, "gain": 0.42, "creature": "echo"}, ...]}

Seconds are for people; the ``*_frame`` fields are exact. Output = Σ gain · source[start:end]
placed at output_frame, then mixed with ``mix`` (equal-power pan, :class:`audio.mixer.Mixer`).
"""

from __future__ import annotations

import bisect
import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
from pydantic import Field, field_validator

from audio.mixer import Mixer
from audio.utterance import Utterance, UtterancePercept
from creatures.behaviour.action_group import ActionGroup, grounds
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.percept import FunctionPercept
from creatures.behaviour.value import ScalarValue, value_from_dict
from creatures.kinds import register
from creatures.bounds import LARGEST_RATE, LONGEST_OFFLINE, LONGEST_SECONDS, Seconds, count
from creatures.config import config_error
from creatures.body.frames import VideoUnavailable, video_encoder
from creatures.image.spec import ImagesSpec, make_video
from creatures.kinds.base import CreatureKind, CreatureSpec, built_once
from creatures.kinds.hearing_parts import AuralLearning, Ear, HearingSpec, Singers, SingFrom, tree_from_state, tree_state
from creatures.persist import load_json, save_json

if TYPE_CHECKING:
    from creatures.runtime.world import World

logger = logging.getLogger(__name__)

EDL_KIND = "creature-music edl"
CLICK_LENGTH = 0.1
"""Seconds a click lasts as a percept."""
CLICK_SALIENCE = 10.0
"""Saliency of the click percept while it lasts: far above 1 on purpose (thesis, "what is
value?", the contrast problem: "extending the range of saliencies outward by allowing them to
be greater than 1 enables the (highly) salient 'click'" to ensure the response to it always
occurs). The interruption a click causes chooses again among every tuple; at saliency 1 the
``clicked`` tuple (3.0) lost about one draw in four to the reading it interrupted or another
(each worth about 2), and that reading was credited toward the next reading's value instead
of the click's."""
LISTEN_VALUE = 0.3
"""Worth of listening to the text again: a ground of the creature's values (see above)."""

REPORT_EVERY = 0.5


class OzymandiasSpec(CreatureSpec):
    kind: Literal["ozymandias"]
    clicks: list[Seconds] = Field(default_factory=list, max_length=100_000, description="seconds at which the author clicks "
                                                                  "(rewards the creature)")
    click_value: float = Field(3.0, gt=0, le=LARGEST_RATE, description="value of being clicked (the primary reinforcer)")
    excitement: float = Field(0.35, ge=0, le=LARGEST_RATE, description="excitement added by each heard word")
    calm: float = Field(3.0, gt=0, le=LONGEST_SECONDS, description="half-life of excitement, seconds")
    shortest: float = Field(0.15, gt=0, le=5, description="shortest part of a word read back, seconds")
    loudness: float = Field(0.6, ge=0, le=2, description="gain of a part read at full excitement")
    innovation: float = Field(0.8, gt=0, le=1e3, description="value (× mean) above which a percept is clustered")
    hearing: HearingSpec = HearingSpec(half_duplex=False, memory=0.5)
    images: ImagesSpec | None = Field(None, description="the image half: video walked out of a graph of frames "
                                                        "by this creature's EDL (thesis, \"off-line image processing\")")
    READ_ONCE: ClassVar[dict[str, str]] = {
        **CreatureSpec.READ_ONCE, **built_once("clicks", "click_value", "calm", "innovation", "hearing")}
    """What :class:`Ozymandias` builds when it starts: its tuples and their scripted clicks (a
    console ``reward`` clicks live), its excitement's half-life, its learning and its ear."""

    def check_references(self, file: Path, where: dict, prefix: tuple) -> None:
        """Tie the footage to the directory of the file that names it."""
        if self.images is not None:
            at = (*prefix, "images", "footage")
            problem = self.images.resolve(where.get(at, where.get(prefix, (file, 0)))[0].parent)
            if problem is not None:
                raise config_error(file, where, at, problem)

    @field_validator("clicks")
    @classmethod
    def _sorted(cls, clicks: list[float]) -> list[float]:
        if any(t < 0 for t in clicks) or clicks != sorted(clicks):
            raise ValueError("clicks must be non-negative seconds in increasing order")
        return clicks


class _Clicked(Action):
    """The author clicked: nothing to do but be rewarded (the value is the reward)."""

    def __init__(self, creature: "Ozymandias") -> None:
        super().__init__("clicked")
        self.creature = creature

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.creature.world.emit("reward", creature=self.creature.name, value=tuple_.value.to_float())


@register("ozymandias")
class Ozymandias(CreatureKind):
    Spec = OzymandiasSpec
    DRIVES = ("excitement",)

    def __init__(self, spec: OzymandiasSpec, world: "World", rng: np.random.Generator) -> None:
        super().__init__(spec, world, rng)
        self.ear = Ear(spec.hearing)
        self.root = UtterancePercept("any sound", radius=spec.hearing.radius, memory=spec.hearing.memory,
                                     max_members=spec.hearing.keep,
                                     max_classes=spec.hearing.classes)
        self.motivation = Motivation({"excitement": 0.0}, decay={"excitement": np.log(2.0) / spec.calm},
                                     equilibrium={"excitement": 0.0}, ceiling=1.0)
        self.readers = Singers(self.rng, self._read)
        self._queued: list[tuple[np.ndarray, float, int]] = []  # part, gain, source frame: to start
        self._playing: list[list] = []  # [part, gain, next frame]
        self._frame = 0  # frames of output rendered so far
        self.sample_rate: int | None = None
        self.edl: list[dict[str, Any]] = []
        self._until = -np.inf
        self._next_report = 0.0
        self._build_group()

    def _build_group(self) -> None:
        spec = self.spec
        self._clicks = list(spec.clicks)
        clicked = FunctionPercept("click", self._clicked)
        self.excited = FunctionPercept("excited", lambda t: self.motivation.level("excitement"))  # advanced each tick
        self.part_read = FunctionPercept("part read", lambda t: 1.0 if t >= self._until else 0.0)
        read_any = self.reader(self.root)
        self.learning = AuralLearning(self.root, self.reader, statistics=0.5, innovation=spec.innovation,
                                      min_trigger=0.5, refine=True, on_event=self._log)
        self.group = ActionGroup(
            self.name, rng=self.rng, temperature=0.5, on_event=self._log, learning=self.learning,
            tuples=[
                ActionTuple("clicked", clicked, _Clicked(self), DoUntil(0.1),
                            ScalarValue(spec.click_value, plasticity=0.0)),
                ActionTuple("read", self.excited, read_any, self._do_until(read_any), 1.0),
                ActionTuple("echo", self.root, read_any, self._do_until(read_any), 1.0),
                ActionTuple("listen", FunctionPercept("always", lambda t: 1.0), Action("listen"),
                            self._do_until(None), ScalarValue(LISTEN_VALUE, plasticity=0.0)),
            ],
        )

    def _clicked(self, t: float) -> float:
        """The click percept: ``CLICK_SALIENCE`` for the tenth of a second after each click."""
        i = bisect.bisect_right(self._clicks, t)
        return CLICK_SALIENCE if i and t < self._clicks[i - 1] + CLICK_LENGTH else 0.0

    def reward(self, amount: float, t: float, window: float, rate: float) -> list[str]:
        """A reward from outside (the input map's ``reward`` route) is the author clicking
        live: the same click percept the scripted ``clicks`` fire, so the highly valued
        ``clicked`` tuple interrupts and credit assignment carries its value back to what
        the creature was reading (thesis, clicker training). ``amount``, ``window`` and
        ``rate`` are the click tuple's own (``click_value``, one activation, α)."""
        bisect.insort(self._clicks, t)
        return [tp.name for tp in self.group.active]

    def _do_until(self, action: Action | None) -> DoUntil:
        if isinstance(action, SingFrom):
            return DoUntil(10.0, until=self.part_read)
        return DoUntil(GaussianModel(1.0, 0.3), learn=False)

    def reader(self, percept: UtterancePercept) -> SingFrom:
        """The one reading action of ``percept`` (shared by every tuple that reads it)."""
        return self.readers(percept)

    def _read(self, t: float, utterance: Utterance, percept: UtterancePercept) -> None:
        """Read a part of ``utterance`` back now, louder the more excited."""
        n = len(utterance.samples)
        shortest = min(n, max(1, int(self.spec.shortest * utterance.samplerate)))
        length = int(self.rng.integers(shortest, n + 1))
        offset = int(self.rng.integers(0, n - length + 1))
        gain = self.spec.loudness * max(self.motivation.level("excitement", t), 0.1)
        start = round(utterance.time * utterance.samplerate) - n + offset  # source frame
        self._queued.append((utterance.samples[offset : offset + length], gain, start))
        self._until = t + length / utterance.samplerate
        self.world.emit("read", creature=self.name, percept=percept.name, source_start=start / utterance.samplerate,
                        length=length / utterance.samplerate, gain=gain)

    # -- hearing: training by repetition ------------------------------------------------
    def listen(self, t: float, block: np.ndarray, sample_rate: int) -> None:
        for utterance in self.ear.listen(t, block, sample_rate):
            self.root.hear(utterance)
            self.root.update(t, 1.0)
            self.motivation.perturb(t, "excitement", self.spec.excitement)
            self.world.emit("sound", creature=self.name, end=utterance.time,
                            start=utterance.time - len(utterance.samples) / sample_rate)

    def tick(self, t: float) -> None:
        # Parts read at a tick start in that step's sound(); any still queued now were never
        # rendered (a run without audio: a rehearsal, wav = false), so nothing plays them and
        # no EDL line points at them. Kept, they grew for as long as the run (~26,000 an hour).
        self._queued.clear()
        self.motivation.advance(t)
        self.group.tick(t)
        if t >= self._next_report:
            self._next_report = t + REPORT_EVERY
            log = self.world.log
            log.emit(t, "values", creature=self.name, values={tp.name: tp.value.to_float() for tp in self.group.tuples})
            log.emit(t, "motivation", creature=self.name, drives={"excitement": self.motivation.level("excitement")})
            log.emit(t, "percepts", creature=self.name, sizes={p.name: len(p.members) for p in self.root.walk()})

    def _log(self, event: dict[str, Any]) -> None:
        event = dict(event)
        kind, t = event.pop("event"), event.pop("t")
        event.pop("group", None)
        self.world.log.emit(t, kind, creature=self.name, **event)

    # -- the voice: a delay line that writes its own edit decision list -------------------
    def sound(self, out: np.ndarray, sample_rate: int) -> None:
        self.sample_rate = sample_rate
        for part, gain, source in self._queued:
            if self.world.writes_outputs:  # only an offline run writes the EDL (finish)
                self.edl.append(edl_entry(self.name, source, source + len(part), self._frame, gain, sample_rate))
            self._playing.append([part, gain, 0])
        self._queued.clear()
        out[:] = 0.0
        for voice in self._playing:
            part, gain, at = voice
            piece = part[at : at + len(out)]
            out[: len(piece)] += gain * piece
            voice[2] += len(out)
        self._playing = [v for v in self._playing if v[2] < len(v[0])]
        self._frame += len(out)

    def finish(self, out: Path) -> dict[str, Path]:
        path = out / f"{self.name}.edl.json"
        save_json(path, {"sample_rate": self.sample_rate or 0, "creature": self.name,
                         "mix": {"gain": self.spec.gain, "pan": self.spec.pan}, "entries": self.edl},
                  kind=EDL_KIND)  # stamps "format" and "version"
        files = {f"edl {self.name}": path}
        if self.spec.images is not None:
            rate = self.sample_rate or 0
            files.update(make_video(self._images(out), self.name, self.edl, rate,
                                    self._frame / rate if rate else self.world.clock.now(), out))
        return files

    def _images(self, out: Path) -> ImagesSpec:
        """The images to make: without a video encoder, all but the video (and a warning why),
        since a run that crashed here at its end lost every output. (The events log is closed
        by now.)"""
        images = self.spec.images
        if images.video:
            try:
                video_encoder(out / f"{self.name}.mp4")
            except VideoUnavailable as exc:
                logger.warning("%s: %s; its images are made without the video", self.name, exc)
                return images.model_copy(update={"video": False})
        return images

    # -- persistence ---------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {"tree": tree_state(self.root), "motivation": self.motivation.to_dict(),
                "tuples": [[tp.trigger.name, tp.action.name, tp.name, tp.value.to_dict()] for tp in self.group.tuples]}

    def restore(self, state: dict[str, Any]) -> None:
        self.root = tree_from_state(state["tree"], like=self.root)
        self._build_group()
        percepts = {p.name: p for p in self.root.walk()}
        percepts.update({tp.trigger.name: tp.trigger for tp in self.group.tuples})
        try:
            for trigger, action, name, value in state["tuples"]:
                if name not in {tp.name for tp in self.group.tuples}:
                    act = self.reader(percepts[action.removeprefix("sing ")])
                    self.group.add(ActionTuple(name, percepts[trigger], act, self._do_until(act), 0.0))
                tuple_ = self.group.find(name)
                if not grounds(tuple_.value):  # an authored ground is a setting: the config wins
                    tuple_.value = value_from_dict(value)
        except KeyError as exc:
            raise ValueError(f"{self.name}: saved tuples name an unknown percept {exc}") from None
        saved = {name for _, _, name, _ in state["tuples"]}
        for tuple_ in [tp for tp in self.group.tuples if isinstance(tp.action, SingFrom) and tp.name not in saved]:
            self.group.remove(tuple_, self.world.clock.now())  # a reading the learning had refined away
        self.motivation.restore(state["motivation"], now=self.world.clock.now())


# -- the edit decision list ---------------------------------------------------------------------


def edl_entry(creature: str, start: int, end: int, output: int, gain: float, sample_rate: int) -> dict[str, Any]:
    """One EDL line: source frames ``[start, end)`` played from output frame ``output``."""
    return {"creature": creature, "source_start": start / sample_rate, "source_end": end / sample_rate,
            "output_time": output / sample_rate, "source_start_frame": start, "source_end_frame": end,
            "output_frame": output, "gain": gain}


def read_edl(path: str | Path) -> dict[str, Any]:
    """Load an EDL written by :meth:`Ozymandias.finish`; raises ValueError naming the entry
    that is malformed (missing field, end before start, negative frame)."""
    doc = load_json(path, kind=EDL_KIND)
    try:  # a run writes its own rate and frames within its length; a hand-edited file may not
        rate = count(doc.get("sample_rate"), "sample_rate", low=8000, high=192000)  # as [audio] sample_rate
        entries = doc.get("entries", [])
        if not isinstance(entries, list):
            raise ValueError(f"entries: must be a list, found {type(entries).__name__}")
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    last = int(LONGEST_OFFLINE * rate)  # the longest offline run's frames: a video is made as long as its EDL
    for i, e in enumerate(entries):
        try:
            ok = 0 <= e["source_start_frame"] <= e["source_end_frame"] and e["output_frame"] >= 0
            float(e["gain"])
            for key in ("source_start_frame", "source_end_frame", "output_frame"):
                count(e[key], key, high=last)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{path}: entry {i} is malformed ({type(exc).__name__}: {exc})") from None
        if not ok:
            raise ValueError(f"{path}: entry {i} has frames out of order: {e}")
    return doc


def render_edl(edls: list[dict[str, Any]], source: np.ndarray, frames: int) -> np.ndarray:
    """Re-render ``frames`` of stereo output from the ``source`` recording and the EDLs of
    every creature (in the installation's creature order): what ``out.wav`` holds."""
    voices = np.zeros((len(edls), frames))
    mixer = Mixer(len(edls), block_size=frames)
    for i, edl in enumerate(edls):
        mixer.set(i, gain=edl["mix"]["gain"], pan=edl["mix"]["pan"])
        for e in edl["entries"]:
            part = source[e["source_start_frame"] : e["source_end_frame"]]
            n = min(len(part), frames - e["output_frame"])
            if n > 0:
                voices[i, e["output_frame"] : e["output_frame"] + n] += e["gain"] * part[:n]
    return mixer.mix(voices).copy()
