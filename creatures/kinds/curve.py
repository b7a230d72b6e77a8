"""*curve*: line-drawn creatures whose bodies play scanned strings and who perceive each
other's shapes (thesis "curve (technology)", "scanned synthesis models (technology)",
"artificial gestural control").

"There is an obvious hybrid to be made between our character animation technology and this
synthesis model – to connect characters' bodies to such a synthesis technique." Design:

* **Bodies in one room.** Every curve creature is a :class:`~creatures.kinds.parts.Body` on
  its motor graph (the shipped figure's, or a ``[creature.body]`` of its own), standing at
  ``x`` along a room (the figure is drawn as lines: the skeleton's bones). It walks along the room (``walk_speed``) as well as moving through the
  graph. With ``[creature.body] metric = "spline"`` (the shipped curve's three) that graph
  measures poses as the lines they draw (:mod:`~creatures.motor.line_metric`), so what the
  creature's moves are made of is the shapes others see.
* **Strings in space.** Each creature's :class:`~creatures.kinds.parts.Voice` is a scanned
  string stretched along x through the space its hands reach, carried with it. The *first*
  of the thesis's two connections: the nearby movement of limbs — its own and every other
  curve creature's, in the room's coordinates — pushes the string
  (:class:`~audio.coupling.BodyCoupling`: force ∝ joint velocity near each mass), so a body
  moving through a string changes its shape, hence its timbre, while a still body leaves it
  to ring down. A creature sounds a note on its string each time it begins an action: the
  pitch its hand's place names (:class:`~creatures.motor.note_space.NotePlacement`).
* **Spring bodies.** With ``springs`` the body others see and touch, that pushes the strings
  and that is drawn is a spring system's realisation of the pose (:mod:`creatures.body.springs`:
  joints pulled to the pose, bones and the floor as constraints): a fast move overshoots and
  rings on, so the strings go on being pushed after the motor system has arrived.
* **Perceiving shapes.** Percepts read the other bodies: the distance between the nearest
  joints of two bodies (*seen* within ``sense``, *close* within ``near``), and how much of
  the creature's string another body overlaps (logged).
* **Responding.** An :class:`ActionGroup` chooses *wander* (a random graph target and a
  small drift along the room), *approach* (walk towards the nearest creature seen and reach
  for it), *mirror* (follow the other's movement in the pose that is its left–right mirror
  image, or its very pose where the material has no mirror image — the seed of "creatures
  that learn through imitation") or *rest* (a low-energy pose, standing still: the strings
  ring down). Percepts are evaluated once per tick (:meth:`Curve.look`), not per tuple.
"""

from __future__ import annotations

import math
import weakref
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
from pydantic import Field, model_validator
from scipy.spatial import cKDTree

from creatures.behaviour.action_group import ActionGroup
from creatures.body.springs import SpringBody, SpringSpec
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.config import nearest
from creatures.kinds import register
from creatures.kinds.base import CreatureKind, CreatureSpec, built_once
from creatures.kinds.moves import Rest, head_for
from creatures.kinds.figures import FigureBodySpec, figure_graph
from creatures.kinds.parts import VOICE_READ_ONCE, Body, Voice, VoiceSpec, shared_graph
from creatures.motor.graph import MotorGraph
from creatures.kinds.report_parts import MotorTrail, report_values, selection_logger
from creatures.motor.note_space import NotePlacement
from creatures.motor.pose import PoseSet
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.runtime.world import World

LIMBS = tuple(f"{part}_{side}" for side in "lr" for part in ("elbow", "wrist", "hand"))
"""Joints whose movement pushes strings: the thesis's "nearby movement of a character's limbs"."""

REPORT_EVERY = 0.5
"""Seconds between the values/percepts/motor snapshots written to the events log."""


class CurveSpec(CreatureSpec):
    kind: Literal["curve"]
    place: float = Field(0.0, ge=-100, le=100, description="where along the room the creature starts (x, m)")
    room: float = Field(3.0, gt=0, le=100, description="half-width of the room (m): creatures stay within ±room")
    walk_speed: float = Field(0.4, gt=0, le=5, description="how fast the creature walks along the room (m/s)")
    drift: float = Field(0.4, ge=0, le=100, description="furthest a wander moves it along the room (m)")
    sense: float = Field(2.5, gt=0, le=200, description="distance between bodies within which another creature is seen (m)")
    near: float = Field(0.8, gt=0, le=200, description="distance between bodies at which another creature is close (m; "
                                                       "at most sense: a creature close is one seen)")
    note_length: float = Field(3.0, gt=0, le=30, description="seconds each note the creature sounds is held")
    temperature: float | None = Field(None, gt=0, le=1e3, description="Boltzmann temperature of action selection")
    voice: VoiceSpec = VoiceSpec(voices=3, body_gain=12.0)
    body: FigureBodySpec = FigureBodySpec()
    springs: SpringSpec | None = Field(None, description="the body realised as a spring system: joints pulled to "
                                                         "the pose by damped springs, bones and the floor as "
                                                         "constraints (creatures/body/springs.py); none = the pose itself")
    limbs: list[str] | None = Field(None, max_length=256,
                                    description="joints whose movement pushes the strings; default the elbows, "
                                                "wrists and hands the body has, else its striking joints")
    READ_ONCE: ClassVar[dict[str, str]] = {**CreatureSpec.READ_ONCE, **VOICE_READ_ONCE,
                                           **built_once("place", "temperature", "body", "springs", "limbs")}
    """Where it starts, its action-group's temperature, its body, springs and pushing limbs
    and its strings are built when it starts (:class:`Curve`); the rest is read as it runs."""

    @model_validator(mode="after")
    def _close_is_seen(self) -> "CurveSpec":
        """"other close" is a child of "other seen" in the percept tree (thesis "percept trees": a
        child is a more specific case of its parent), so a creature close must be one seen.
        Accepted, ``near`` beyond ``sense`` triggered mirror while nothing was seen (sense 0.01,
        near 200: 5 mirrors in 20 s, "seen" 0.0 throughout)."""
        if self.near > self.sense:
            raise ValueError(f"near: {self.near:g} m is beyond sense ({self.sense:g} m): a creature close to "
                             f"another is one it sees, so near must be at most sense")
        return self

    @model_validator(mode="after")
    def _limbs_on_the_figure(self) -> "CurveSpec":
        """A shipped figure's joints are known now; a body from files is checked once built."""
        if not self.body.custom:
            names = figure_graph(self.body.figure, metric=self.body.metric).skeleton.names
            problem = self.missing_limb(names, f"the {self.body.figure}")
            if problem is not None:
                raise ValueError(problem)
        return self

    def missing_limb(self, joints: tuple[str, ...], body: str) -> str | None:
        """The first of :attr:`limbs` that ``body`` has no joint of, said with its nearest name."""
        missing = [j for j in self.limbs or () if j not in joints]
        return f"limbs: {body} has no joint {missing[0]!r}{nearest(missing[0], joints, 'joints')}" if missing else None


MIRROR_TOLERANCE = 0.05
"""Mean joint distance (m) within which a pose counts as another's mirror image."""

MIRROR_CANDIDATES = 32
"""Nearest poses (as flat joint vectors) among which a mirror image is sought: exact for the
shipped bodies' few hundred nodes, and a KD-tree's few microseconds on a large body."""


class MirrorImages:
    """The poses of one body's graph, to find the node nearest a pose and its mirror image (x
    negated, left and right joints swapped: ``x_l`` ↔ ``x_r``)."""

    def __init__(self, graph: MotorGraph) -> None:
        names = list(graph.skeleton.names)
        self.names = tuple(names)
        self.swap = np.array([names.index(n[:-2] + {"_l": "_r", "_r": "_l"}[n[-2:]])
                              if n[-2:] in ("_l", "_r") and n[:-2] + {"_l": "_r", "_r": "_l"}[n[-2:]] in names else i
                              for i, n in enumerate(names)])
        self.positions = graph.poses.positions  # (N, J, 3)
        self.tree = cKDTree(self.positions.reshape(len(self.positions), -1))
        self._known: "weakref.WeakKeyDictionary[PoseSet, dict[int, int]]" = weakref.WeakKeyDictionary()

    def goal(self, poses: PoseSet, node: int) -> int:
        """:meth:`goals` of one node of another body's ``poses``, found once and kept: a mirroring
        creature asks every tick, while its partner passes through a few nodes (the two KD-tree
        queries were an eighth of curve's time)."""
        known = self._known.setdefault(poses, {})
        if node not in known:
            known[node] = int(self.goals(poses.positions[node][None])[0])
        return known[node]

    def goals(self, positions: np.ndarray) -> np.ndarray:
        """For poses ``(M, J, 3)`` of a body with these joints, the node whose pose is each one's
        mirror image, or, where the material has none within :data:`MIRROR_TOLERANCE`, the node
        nearest the pose itself: the creature then copies the other's shape instead, the way
        dancers "mirror" a partner they stand beside."""
        mirrored = positions[:, self.swap] * np.array([-1.0, 1.0, 1.0])
        image, gap = self._nearest(mirrored)
        copy, _ = self._nearest(positions)
        return np.where(gap <= MIRROR_TOLERANCE, image, copy)

    def _nearest(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Node of least mean joint distance to each pose, among its nearest flat candidates."""
        k = min(MIRROR_CANDIDATES, len(self.positions))
        _, candidates = self.tree.query(positions.reshape(len(positions), -1), k=k)
        candidates = np.sort(candidates.reshape(len(positions), k), axis=1)  # ties: the lowest node, as ever
        gaps = np.linalg.norm(self.positions[candidates] - positions[:, None], axis=-1).mean(axis=-1)
        best = np.argmin(gaps, axis=1)
        rows = np.arange(len(positions))
        return candidates[rows, best], gaps[rows, best]


_IMAGES: "weakref.WeakKeyDictionary[MotorGraph, MirrorImages]" = weakref.WeakKeyDictionary()


def mirror_images(graph: MotorGraph) -> MirrorImages:
    """One :class:`MirrorImages` per graph (the bodies of a room share their figure's)."""
    if graph not in _IMAGES:
        _IMAGES[graph] = MirrorImages(graph)
    return _IMAGES[graph]


def mirror_nodes(graph: MotorGraph | None = None) -> np.ndarray:
    """For every node of ``graph`` (default the shared one), the node whose pose is its mirror
    image, or the node itself where the material has no such pose (the shipped *reach* and
    *strike* are right-handed)."""
    images = mirror_images(graph if graph is not None else shared_graph())
    return images.goals(images.positions)


class _Wander(Action):
    """A random graph target and a small drift along the room."""

    def __init__(self, creature: "Curve") -> None:
        super().__init__("wander")
        self.creature = creature

    def start(self, t: float, tuple_: ActionTuple) -> None:
        c = self.creature
        head_for(c.body, t, [int(c.rng.integers(len(c.body.graph)))])
        c.target_x = c.x + c.rng.uniform(-c.spec.drift, c.spec.drift)
        c.sound_hand(t)


class _Approach(Action):
    """Walk towards the nearest creature seen and reach for it."""

    def __init__(self, creature: "Curve") -> None:
        super().__init__("approach")
        self.creature = creature

    def start(self, t: float, tuple_: ActionTuple) -> None:
        c = self.creature
        other = c.nearest()
        if other is None:
            return
        side = np.sign(other.x - c.x) or 1.0
        c.target_x = other.x - side * 0.8 * c.spec.near
        chest = other.positions()[other.centre]
        reach_for = chest + [other.x - c.target_x, 0.0, 0.0]  # where it will be, seen from where c goes
        head_for(c.body, t, c.body.finder.effector_goals(c.body.effector, reach_for).tolist())
        c.sound_hand(t)


class _Mirror(Action):
    """Take the mirror image of the nearest creature's pose, and keep following it."""

    def __init__(self, creature: "Curve") -> None:
        super().__init__("mirror")
        self.creature = creature
        self.goal = -1

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.goal = -1
        self.update(t)
        self.creature.sound_hand(t)

    def update(self, t: float) -> None:
        c = self.creature
        other = c.nearest()
        if other is None:
            return
        if other.body.skeleton.names != c.images.names:
            return  # another skeleton: no pose of this body is its image
        node = other.body.motor.position(t).node
        goal = c.images.goal(other.body.graph.poses, node)
        if goal != self.goal:
            self.goal = goal
            head_for(c.body, t, [goal])


class _Rest(Rest):
    """Stand still in a low-energy pose: the strings ring down."""

    def __init__(self, creature: "Curve") -> None:
        super().__init__(creature.body)
        self.creature = creature

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.creature.target_x = self.creature.x
        super().start(t, tuple_)


@register("curve")
class Curve(CreatureKind):
    Spec = CurveSpec
    @classmethod
    def body_problem(cls, spec: CreatureSpec, labels: frozenset[str], joints: tuple[str, ...]) -> str | None:
        return spec.missing_limb(joints, "the body")

    def __init__(self, spec: CurveSpec, world: "World", rng: np.random.Generator) -> None:
        super().__init__(spec, world, rng)
        self.body = Body(rng, spec=spec.body, figure=spec.body.figure)
        names = self.body.skeleton.names
        self.limbs = [names.index(j) for j in (spec.limbs or [j for j in LIMBS if j in names])] or self.body.touching
        roots = np.flatnonzero(self.body.skeleton.parents < 0)
        self.centre = names.index("chest") if "chest" in names else int(roots[0])
        """The joint another creature reaches for (the chest, else the root)."""
        self.images = mirror_images(self.body.graph)
        self.springs = (SpringBody(spec.springs, self.body.skeleton.parents, self.body.pose.positions)
                        if spec.springs is not None else None)
        self._realised = self.body.pose.positions
        self.trail = MotorTrail(world, self.name, self.body)
        self.x = self.target_x = float(np.clip(spec.place, -spec.room, spec.room))
        self.placement = NotePlacement.around(self.body.reach())
        self.voice: Voice | None = None
        self._t = 0.0
        self._nearest: Curve | None = None
        self.distance = np.inf
        root = WhateverPercept()
        seen = FunctionPercept("other seen", self.seen, parent=root)
        close = FunctionPercept("other close", self.close, parent=seen)
        arrived = FunctionPercept("arrived", lambda t: 1.0 if self.body.motor.arrived(t) else 0.0)
        there = FunctionPercept("walked there", lambda t: float(abs(self.x - self.target_x) < 0.05 and
                                                                self.body.motor.arrived(t)))
        # Values as authored (alpha = 0), as in exchange: nothing here is a consummatory reward,
        # so credit assignment would only shrink every value by the discount at each
        # selection (one simulated hour took 3.0/2.0/0.3 to ~1e-7; ActionGroup now refuses it).
        self.group = ActionGroup(
            self.name, rng=rng, alpha=0.0, temperature=spec.temperature,
            on_event=selection_logger(world, self.name),
            tuples=[
                ActionTuple("wander", root, _Wander(self), DoUntil(GaussianModel(4.0, 1.0), until=arrived), 1.0),
                ActionTuple("approach", seen, _Approach(self), DoUntil(6.0, until=there), 2.0),
                ActionTuple("mirror", close, _Mirror(self), DoUntil(GaussianModel(4.0, 1.0)), 3.0),
                ActionTuple("rest", root, _Rest(self), DoUntil(GaussianModel(3.0, 1.0)), 0.4),
            ],
        )
        self._next_report = 0.0

    # -- the room ------------------------------------------------------------------------------
    def positions(self) -> np.ndarray:
        """Where its joints are (its body's frame): the spring system's realisation of the
        pose, or the pose itself. What others see and touch, what pushes the strings, what is
        drawn."""
        return self._realised

    def others(self) -> list["Curve"]:
        return [c for c in self.world.creatures if isinstance(c, Curve) and c is not self]

    def gap(self, other: "Curve") -> float:
        """Distance between the nearest joints of two bodies, in the room (m)."""
        apart = self.positions()[:, None] - other.positions()[None]
        apart[..., 0] += self.x - other.x
        return math.sqrt(float(np.einsum("ijk,ijk->ij", apart, apart).min()))

    def look(self) -> None:
        """Find the nearest other body (once a tick; the percepts read what was seen)."""
        others = self.others()
        gaps = [self.gap(o) for o in others]
        k = int(np.argmin(gaps)) if gaps else -1
        self._nearest, self.distance = (others[k], gaps[k]) if gaps else (None, np.inf)

    def nearest(self) -> "Curve | None":
        return self._nearest

    def seen(self, t: float) -> float:
        """Saliency of the nearest other body: 1 at touching, falling to 0 at ``sense``."""
        return min(max(1.0 - self.distance / self.spec.sense, 0.0), 1.0)

    def close(self, t: float) -> float:
        return 1.0 if self.distance <= self.spec.near else 0.0

    def overlap(self) -> float:
        """Fraction of this creature's string within reach of another body's joints."""
        if self.voice is None or self.voice.coupling is None:
            return 0.0
        nodes = self.voice.coupling.nodes
        near = np.zeros(len(nodes), dtype=bool)
        for other in self.others():
            theirs = other.positions() + [other.x - self.x, 0.0, 0.0]
            d = np.sqrt(((nodes[:, None] - theirs[None]) ** 2).sum(axis=-1)).min(axis=1)
            near |= d <= self.voice.coupling.radius
        return float(near.mean())

    # -- moving and sounding -----------------------------------------------------------------
    def sound_hand(self, t: float) -> None:
        """Sound the note the hand's place names, held for ``note_length``."""
        pitch, velocity = self.placement.note_at(self.body.hand())
        self.world.play(self, NoteEvent(t, pitch, max(velocity, 40), self.spec.channel, self.spec.note_length))

    def feel(self) -> None:
        """The limbs of every curve body in the room push this creature's string (in its
        coordinates)."""
        if self.voice is None:
            return
        bodies = [self.positions()[self.limbs]] + [o.positions()[o.limbs] + [o.x - self.x, 0.0, 0.0]
                                                   for o in self.others()]
        self.voice.feel(_Bodies(np.concatenate(bodies), self._t), own=_Bodies(self.positions(), self._t))

    def tick(self, t: float) -> None:
        dt, self._t = t - self._t, t
        step = self.spec.walk_speed * dt
        self.x = min(max(self.x + min(max(self.target_x - self.x, -step), step), -self.spec.room), self.spec.room)
        self.trail.follow(t)
        self.body.update(t)
        self._realised = (self.body.pose.positions if self.springs is None
                          else self.springs.follow(t, self.body.pose.positions).copy())
        self.look()
        self.group.tick(t)
        self.feel()
        if t >= self._next_report:
            self._next_report = t + REPORT_EVERY
            self._report(t)

    def _report(self, t: float) -> None:
        report_values(self.world, t, self.name, self.group)
        self.world.emit("percepts", creature=self.name,
                        sizes={"bodies seen": int(sum(self.gap(o) < self.spec.sense for o in self.others()))},
                        levels={"seen": self.seen(t), "close": self.close(t), "string overlap": self.overlap()},
                        distance=None if self._nearest is None else self.distance)
        self.trail.report(t, shift=(self.x, 0.0, 0.0), x=self.x)

    # -- outputs -------------------------------------------------------------------------------
    def played(self, note: NoteEvent) -> None:
        if self.voice is not None:
            self.voice.play(note.pitch, note.velocity, note.end)

    def sound(self, out: np.ndarray, sample_rate: int) -> None:
        if self.voice is None:
            self.voice = Voice(self.spec.voice, sample_rate)
            reach = self.body.reach()
            low, high = reach.min(axis=0), reach.max(axis=0)
            height = float(np.median(reach[:, 1]))
            self.voice.couple(np.column_stack((np.linspace(low[0], high[0], self.spec.voice.masses),
                                               np.full(self.spec.voice.masses, height),
                                               np.full(self.spec.voice.masses, float(np.median(reach[:, 2]))))),
                              joints=None)
            if self.spec.voice.body_shape > 0:  # the second connection: its strings hold its body's shape
                self.voice.shape_as(self.body.line())
        self.voice.render(out, self.world.clock.now(), gain=self.spec.voice.gain)

    def figure(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.positions() + [self.x, 0.0, 0.0], np.asarray(self.body.skeleton.parents)

    # -- persistence ---------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {"values": self.group.value_state(), "x": self.x}

    def restore(self, state: dict[str, Any]) -> None:
        # Values are authored (alpha = 0): the config is their truth, and a state saved while
        # credit assignment still decayed them must not carry the decay into this run.
        if "x" in state:
            self.x = self.target_x = float(np.clip(state["x"], -self.spec.room, self.spec.room))


class _Bodies:
    """Several bodies' joints as one pose-like object for :class:`BodyCoupling`."""

    def __init__(self, positions: np.ndarray, time: float) -> None:
        self.positions = positions
        self.time = time
