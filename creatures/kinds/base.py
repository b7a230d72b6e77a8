"""What every creature kind provides to the runtime.

A creature kind (exchange, listen, soundcreatures, …) composes behaviour, perception, motor
and voice parts; the runtime only talks to it through :class:`CreatureKind`, so live and
offline runs, tests and the inspector treat every kind alike (py_trees' lesson: one life
cycle for everything).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Sequence

import numpy as np
from pydantic import BaseModel, Field

from creatures.bounds import FINITE
from creatures.room.spec import VehicleSpec

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.unplaced import Unplaced

if TYPE_CHECKING:
    from pathlib import Path

    from creatures.room.stage import Stage

    from creatures.runtime.world import World
    from midi.notes import NoteEvent


@dataclass(frozen=True, slots=True)
class Holding:
    """A trick a body holds, as someone watching it sees it: which, since when (clock
    seconds) and, for a trick held at a height (a beg), how high (metres, the body's units)."""

    trick: str
    since: float
    height: float | None = None


class CreatureSpec(BaseModel):
    """Keys every ``[[creature]]`` table accepts; kinds subclass this with their own keys."""

    model_config = FINITE

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_\-]+$", description="unique name (ASCII letters, digits, _ and -: it goes into OSC addresses and file names)")
    kind: str = Field(description="which creature kind (the sections below)")
    channel: int = Field(0, ge=0, le=15, description="MIDI channel this creature plays on")
    gain: float = Field(0.8, ge=0.0, le=4.0, description="linear gain of its voice in the audio mix (out.wav, the "
                                                         "loudspeakers; MIDI velocities are the notes' own)")
    pan: float = Field(0.0, ge=-1.0, le=1.0, description="stereo position of its voice (and MIDI pan, CC 10, "
                                                          "sent on its channel at start and when it changes)")
    program: int | None = Field(None, ge=0, le=127, description="General MIDI program sent on its channel at start, "
                                                                "and again when a console set or a zone changes it "
                                                                "(default: [midi] program)")
    bank: int | None = Field(None, ge=0, le=16383, description="bank sent before the program (default: [midi] bank)")
    volume: int | None = Field(None, ge=0, le=127, description="channel volume, CC 7, sent at start and when it changes "
                                                               "(default: [midi] volume)")
    bend_range: float | None = Field(None, ge=0, le=24, description="pitch-bend range in semitones sent at start and when it changes "
                                                                    "(default: [midi] bend_range)")
    hears_input: bool = Field(True, description="hear what comes from outside the colony (MIDI, OSC, the input "
                                                "map's notes, the input audio and its notes); else only other "
                                                "creatures (and, with [audio] air, the room)")
    vehicle: VehicleSpec = Field(VehicleSpec(), description="[creature.vehicle]: its place, body and steering in the "
                                                           "installation's [room] (ignored without one)")

    READ_ONCE: ClassVar[dict[str, str]] = {
        "vehicle": "[creature.vehicle] is read once, when the room is built (a [[room.zones]] spec changes "
                   "max_speed, max_force, mass, radius or max_turn while the creature stands in it)"}
    """Keys a running creature's spec keeps but nothing reads again, with why: the console's
    ``set`` and a zone refuse them (:func:`creatures.kinds.spec_keys.with_key`), since a set
    there would be taken and change nothing (``set vehicle.max_speed`` was answered and the
    creature kept its speed). A kind's spec adds the keys it builds its parts from
    (:func:`built_once`); a dotted entry (``voice.masses``) is that key of a table."""


def built_once(*keys: str) -> dict[str, str]:
    """``READ_ONCE`` entries for the keys a kind builds its parts from when the creature starts
    (its action-group's temperature, its ear, its body …), saying so."""
    return {key: f"{key} is read once, when the creature starts: the running creature keeps what it was built "
                 "from (change the config and restart the run)" for key in keys}


class CreatureKind(ABC):
    """A creature in a run. Subclasses set ``Spec`` and implement :meth:`tick`.

    The runtime calls, in order, every behaviour tick: :meth:`hear` for notes that fell due,
    :meth:`listen` for audio input, :meth:`tick`; then :meth:`sound` for each audio block and
    :meth:`figure` for each video frame. Creatures play by calling ``world.play(self, note)``.
    Outside input reaches every kind alike through the parts it is composed of (an
    :class:`ActionGroup` as ``group``, a :class:`Motivation` as ``motivation``):
    :meth:`reward` and :meth:`drive`, which the config checks before a run through
    :meth:`rewardable` and :meth:`drive_names`.
    """

    Spec: ClassVar[type[CreatureSpec]] = CreatureSpec
    DRIVES: ClassVar[tuple[str, ...]] = ()
    """The drives of the kind's ``motivation`` (a test checks them against a built creature)."""
    REWARDABLE: ClassVar[bool] = True
    """Whether the kind has an action-group (``group``) a reward can reach."""

    @classmethod
    def body_problem(cls, spec: CreatureSpec, labels: frozenset[str], joints: tuple[str, ...]) -> str | None:
        """What the kind needs of a body from files that this one lacks (a motor label, a joint),
        checked once the body is built (its labels and joint names); None: it will do."""
        return None

    def __init__(self, spec: CreatureSpec, world: "World", rng: np.random.Generator) -> None:
        self.spec = spec
        self.name = spec.name
        self.world = world
        self.rng = rng
        self.unplaced_parts = Unplaced()
        """What :meth:`restore` was given under names this config has none of (a group, percept
        or tuple renamed or removed): kept, carried into :meth:`state`, said at load."""

    @classmethod
    def drive_names(cls, spec: CreatureSpec) -> tuple[str, ...]:
        """The drives a creature of this spec will have (kinds whose drives depend on the
        spec override this)."""
        return cls.DRIVES

    @classmethod
    def rewardable(cls, spec: CreatureSpec) -> bool:
        """Whether a creature of this spec has an action-group to reward."""
        return cls.REWARDABLE

    @classmethod
    def tricks(cls, spec: CreatureSpec) -> tuple[str, ...]:
        """The tricks a trainer can cue and see a creature of this spec hold (``[input.trainer]``
        names them): none for kinds that do no tricks."""
        return ()

    @classmethod
    def graded_tricks(cls, spec: CreatureSpec) -> tuple[str, ...]:
        """Those of :meth:`tricks` held at a height a trainer can shape (``[input.trainer] shaping``)."""
        return ()

    def holding(self) -> "Holding | None":
        """The trick the body holds now, as a trainer watching it sees it; None while it holds
        none (and always, for kinds that do no tricks)."""
        return None

    @classmethod
    def has_body(cls, spec: CreatureSpec) -> bool:
        """Whether a creature of this spec has a body (``[[output.cc]]`` may read its
        features): a kind that draws a :meth:`figure` has one (kinds whose body depends on
        the spec override this)."""
        return cls.figure is not CreatureKind.figure

    def reward_groups(self) -> list[ActionGroup]:
        """The action-groups a reward from outside reaches: ``group`` where the kind has one
        (a group tuple passes it on to its own group; kinds with several top-level groups
        override this)."""
        group = getattr(self, "group", None)
        return [group] if isinstance(group, ActionGroup) else []

    def reward(self, amount: float, t: float, window: float, rate: float) -> list[str]:
        """A reward from outside at ``t`` (the clicker), given to the tuples of
        :meth:`reward_groups` active within ``window`` seconds before, blended at ``rate``
        (:meth:`ActionGroup.reward`); logged as ``reward``. Returns the credited tuples."""
        credited: list[str] = []
        blended: dict = {}
        for group in self.reward_groups():
            names, moved = group.reward(amount, t, window, rate=rate)
            credited += names
            blended.update(moved)
        self.world.emit("reward", creature=self.name, tuple=credited[-1] if credited else None, amount=amount,
                        credited=credited, blended=blended)
        return credited

    def drive(self, t: float, name: str, *, amount: float | None = None, level: float | None = None) -> float:
        """Perturb drive ``name`` of ``motivation`` at ``t``: add ``amount``, or set it to
        ``level``; logged as ``drive``. Returns the new level."""
        motivation = self.motivation  # type: ignore[attr-defined]  # kinds with DRIVES have one
        change = amount if level is None else level - motivation.level(name, max(t, motivation.time))
        motivation.perturb(max(t, motivation.time), name, change)
        new = motivation.level(name)
        self.world.emit("drive", creature=self.name, drive=name, level=new, amount=change)
        return new

    def hear(self, note: "NoteEvent", source: str) -> None:
        """A note played by ``source`` (another creature's name, or "input") started."""

    def played(self, note: "NoteEvent") -> None:
        """One of this creature's own notes was scheduled (e.g. to start its voice)."""

    def listen(self, t: float, block: np.ndarray, sample_rate: int) -> None:
        """A block of audio input (mono float32) ending at clock time ``t``."""

    def described(self) -> list[Any]:
        """What else this creature is made of, for ``creatures describe``'s tree (labels, or
        ``(label, children)``): a kind whose parts are not action-groups and percepts shows them."""
        return []

    @property
    def hears_audio(self) -> bool:
        """Whether :meth:`listen` takes anything in: a room gathers an ear's block of sound
        across it (creatures/room/air.py) only for the creatures that listen."""
        return type(self).listen is not CreatureKind.listen

    @abstractmethod
    def tick(self, t: float) -> None:
        """Perceive, select actions, move: one behaviour tick at clock time ``t``."""

    @classmethod
    def tick_many(cls, creatures: Sequence["CreatureKind"], t: float) -> None:
        """:meth:`tick` of each of ``creatures`` (all of this kind) in turn, at one time: a kind
        whose crowds can share the work of a tick across creatures (arrays over the crowd
        instead of a loop of small ones) does so here, with the same effects in the same
        order as ticking them one by one."""
        for creature in creatures:
            creature.tick(t)

    def sound(self, out: np.ndarray, sample_rate: int) -> None:
        """Fill ``out`` (mono, preallocated) with this creature's voice; default silent."""
        out[:] = 0.0

    def pan(self) -> float:
        """Where the stereo mix places this creature now (−1 left … 1 right): its ``pan``; an
        authored creature's skills may move it (``voice.pan``)."""
        return self.spec.pan

    def figure(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Joint positions ``(J, 3)`` and parents ``(J,)`` to draw, or None for no body."""
        return None

    def effector(self) -> np.ndarray | None:
        """Position ``(3,)`` of the body's (first) end-effector in its :meth:`figure` (its own
        frame, also in a room, so a CC range set once holds wherever it walks), or None for no
        body: what ``[[output.cc]]`` body features read."""
        return self.effector_of(self.figure())

    def effector_of(self, figure: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray | None:
        """The end-effector of ``figure`` (joints in :meth:`figure`'s order: the body stream
        passes the :meth:`shown` joints it sends, so its effector is where those put it)."""
        body = getattr(self, "body", None)
        if figure is None or body is None or not body.skeleton.end_effectors:
            return None
        return figure[0][body.skeleton.index(body.skeleton.end_effectors[0])]

    def marks(self) -> list[tuple[tuple[float, float, float], int]]:
        """Note objects to draw in space as ``(position, pitch)``."""
        return []

    # -- as drawn: every picture of the creature (frames, the live view, pose events, the body
    # stream) asks these, so all of them agree on where it stands -------------------------
    @property
    def stage(self) -> "Stage | None":
        """The room this creature stands in (its world's ``[room]``), or None."""
        return getattr(self.world, "room", None)

    def shown(self) -> tuple[np.ndarray, np.ndarray] | None:
        """:meth:`figure` as drawn: in a room (``[room]``) where its vehicle stands, facing its
        heading, walking if it has a gait (:meth:`creatures.room.stage.Stage.figure`), and a
        creature without a body as a marker there (:data:`creatures.room.stage.MARKER`: a post
        and an arm pointing its heading); without a room, its own figure or None (the view and
        the frames put it at its side-by-side place)."""
        figure = self.figure()
        if self.stage is None:
            return figure
        if figure is None:
            return self.stage.marker(self)
        return self.stage.figure(self, figure[0]), figure[1]

    def shown_marks(self) -> list[tuple[tuple[float, float, float], int]]:
        """:meth:`marks` as drawn: carried with the creature in a room, as :meth:`shown`."""
        marks = self.marks()
        if not marks or self.stage is None:
            return marks
        points = self.stage.carry(self, np.array([position for position, _ in marks], dtype=float).reshape(-1, 3))
        return [(tuple(float(x) for x in point), pitch) for point, (_, pitch) in zip(points, marks)]

    def finish(self, out: "Path") -> dict[str, "Path"]:
        """The run is over: write any kind-specific outputs into ``out`` (e.g. an edit
        decision list) and return them by name; default none."""
        return {}

    def state(self) -> dict[str, Any]:
        """JSON-able learned state, saved periodically and on exit."""
        return {}

    def restore(self, state: dict[str, Any]) -> None:
        """Take back what :meth:`state` returned (the same kind and config)."""
