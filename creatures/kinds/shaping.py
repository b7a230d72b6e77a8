"""Complex shaping: learning a new movement under a guide (thesis "complex shaping",
"learning to chase your tail – part 1 / part 2", "gesture graph generation").

The dog follows a training stick with its nose, is rewarded for it, and in the end chases
its tail with no stick. The parts here:

* :class:`FollowStick` is the guide action ("moving stick | follow stick with your nose"):
  a stick point moves round a circle and the body keeps heading, by A* on its motor graph,
  for the pose that puts its effector nearest the stick;
* a :class:`~creatures.motor.gesture.BodyMemory` records the motor-graph nodes the body
  passes (fed by the creature's :class:`~creatures.kinds.report_parts.MotorTrail`);
* :class:`GestureShaping` is the Ac percept ("whenever | execute Ac's motor program"): a
  :class:`~creatures.motor.gesture.GestureModel` that learns the body memory of every
  rewarded activation whose credit reaches it. Its tuple is given proximity 1 to the guide
  (:class:`~creatures.behaviour.proximity.Proximity`, fixed), so it learns from the guide's
  rewarded runs and its value grows with the guide's. Chosen on its own, it performs the
  model's core as a motor program;
* after ``dispatch_after`` lessons the core is dispatched into the body's own motor graph as
  new material (:mod:`creatures.motor.dispatch`) and ``on_dispatch`` receives the
  :class:`~creatures.motor.dispatch.Gesture`: the creature leaves behind, in the shaping
  tuple's place, a tuple that runs the new motor program without the guide.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

import math

import numpy as np
from scipy.spatial import cKDTree

from creatures import bounds
from creatures.behaviour.action_group import ActionGroup, Activation
from creatures.behaviour.action_tuple import Action, ActionTuple
from creatures.motor.dispatch import Gesture, dispatch
from creatures.motor.gesture import BodyMemory, GestureModel, Observation
from creatures.motor.programs import MotorProgram, ProgramStack
from creatures.motor.search import NoPath

if TYPE_CHECKING:
    from creatures.kinds.parts import Body


MATCH_FLOOR = 1e-3
"""Probability :meth:`GestureShaping.match` gives a transition the model never saw (score 0)."""


class Circle:
    """Where the stick is: ``center + radius·(cos θ·u + sin θ·v)``, θ = 2π·phase."""

    def __init__(self, center: np.ndarray, u: np.ndarray, v: np.ndarray, radius: float) -> None:
        self.center = np.asarray(center, dtype=float)
        self.u = np.asarray(u, dtype=float) / np.linalg.norm(u)
        v = np.asarray(v, dtype=float) - np.dot(v, self.u) * self.u
        self.v = v / np.linalg.norm(v)
        self.radius = float(radius)

    @classmethod
    def in_reach(cls, reach: np.ndarray, size: float) -> Circle:
        """A circle in the plane of the two widest directions of ``reach`` (every effector
        position the body has), about its middle, ``size`` × the narrower spread in radius:
        a stick the body can follow whatever its material."""
        center = reach.mean(axis=0)
        _, spread, axes = np.linalg.svd(reach - center, full_matrices=False)
        return cls(center, axes[0], axes[1], size * float(spread[1]) / np.sqrt(len(reach)))

    def at(self, phase: float) -> np.ndarray:
        theta = 2.0 * np.pi * phase
        return self.center + self.radius * (np.cos(theta) * self.u + np.sin(theta) * self.v)

    def path(self, samples: int = 64) -> np.ndarray:
        """One lap as ``(samples, 3)`` points."""
        return np.stack([self.at(k / samples) for k in range(samples)])


class FollowStick(Action):
    """The guide: follow a stick round ``circle`` once per ``period`` seconds for ``laps`` laps
    (done then). Each tick, when the pose nearest the stick changes, the body sets off for it."""

    def __init__(self, name: str, body: "Body", circle: Circle, *, period: float, laps: float) -> None:
        super().__init__(name)
        self.body = body
        self.circle = circle
        self.period = float(period)
        self.laps = float(laps)
        self.started: float | None = None
        self.target: int | None = None
        self._tree: tuple[int, cKDTree] | None = None  # (graph size, effector positions)

    def _nearest(self, point: np.ndarray) -> int:
        graph = self.body.graph
        if self._tree is None or self._tree[0] != len(graph):
            self._tree = (len(graph), cKDTree(graph.poses.positions[:, self.body.effector_index]))
        return int(self._tree[1].query(point)[1])

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.started, self.target = t, None
        self.update(t)

    def update(self, t: float) -> None:
        node = self._nearest(self.circle.at((t - self.started) / self.period))
        if node != self.target:
            self.target = node
            motor = self.body.motor
            try:
                motor.set_course(t, motor.course(t, [node]))
            except NoPath:
                pass

    def done(self, t: float) -> float:
        return 1.0 if self.started is not None and t - self.started >= self.laps * self.period else 0.0


class RunsProgram(Action):
    """An action that runs :meth:`program` under a :class:`ProgramStack` on the body's motor
    system while its tuple is active (done when it ends; an interruption asks it to exit)."""

    def __init__(self, name: str, body: "Body") -> None:
        super().__init__(name)
        self.body = body
        self.stack: ProgramStack | None = None
        self.began: float | None = None
        self.performed: tuple[float, float] | None = None  # (start, stop) of the last run

    def program(self) -> MotorProgram | None:  # pragma: no cover - every subclass says
        raise NotImplementedError

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.began = t
        program = self.program()
        self.stack = None if program is None else ProgramStack(self.body.motor, program)
        if self.stack is not None:
            self.stack.start(t)

    def update(self, t: float) -> None:
        if self.stack is not None:
            self.stack.tick(t)

    def stop(self, t: float, *, interrupted: bool) -> None:
        if self.stack is not None:
            self.stack.stop(t, interrupted=interrupted)
        if self.began is not None:
            self.performed = (self.began, t)

    def done(self, t: float) -> float:
        return 1.0 if self.stack is None or self.stack.done else 0.0


class GestureShaping(RunsProgram):
    """The Ac percept of complex shaping: a gesture model of rewarded body memories, performed
    as a motor program, dispatched as new material after ``dispatch_after`` lessons."""

    def __init__(self, name: str, body: "Body", memory: BodyMemory, *, dispatch_after: int, gesture: str,
                 guide: str | None = None, on_dispatch: Callable[[Gesture], None] | None = None) -> None:
        super().__init__(name, body)
        self.guide = guide  # the guide action's name (its credit reaches this one at proximity 1)
        self.memory = memory
        self.dispatch_after = int(dispatch_after)
        self.gesture = gesture
        self.on_dispatch = on_dispatch
        self.model = GestureModel()
        self.lessons = 0
        self.dispatched: Gesture | None = None
        self.successor: PerformGesture | None = None  # the tuple's Ac left behind after dispatch
        self._learnt: set[tuple[str, float]] = set()  # activations already taught (a reward and a credit)

    # -- as a percept model: learning from the body's memory ----------------------------------
    def attach(self, group: ActionGroup) -> None:
        """Learn from ``group``'s rewarded activations (its credit hooks), and take the guide's
        credit: proximity 1, fixed (thesis: "we give this action-tuple a proximity of 1 to the
        'follow stick' action-tuple")."""
        group.on_credit.append(self.credited)
        if self.guide is not None:
            group.proximities.fix(self.guide, self.name, 1.0)

    def credited(self, group: ActionGroup, t: float, activation: Activation) -> None:
        """A rewarded activation whose credit reaches this action's tuple: learn what the body
        did during it (the guide's runs; later, its own)."""
        mine = [i for i, tp in enumerate(group.tuples) if tp.action is self]
        key = (activation.tuple_.name, activation.started)
        if not mine or key in self._learnt or group.proximity(activation.tuple_)[mine[0]] <= 0.0:
            return
        ended = t if activation.ended is None else activation.ended
        nodes = [o for o in self.memory.since(activation.started) if o.time <= ended]
        if len(nodes) < 3:
            return
        self._learnt = {k for k in self._learnt if k[1] >= activation.started - 60.0} | {key}
        self.model.learn(nodes)
        self.lessons += 1
        if self.dispatched is None and self.lessons >= self.dispatch_after:
            self.dispatch()

    def dispatch(self) -> Gesture | None:
        """Pull out the core and add it to the body's own graph as new material."""
        core = self.model.core()
        if len(core) < 2:
            return None
        nodes = [self.model.states[s].node for s in core]
        dwell = [self.model.states[s].dwell for s in core]
        self.dispatched = dispatch(self.body.own_graph(), self.gesture, nodes, dwell)
        if self.on_dispatch is not None:
            self.on_dispatch(self.dispatched)
        return self.dispatched

    def match(self, observations: list[Observation]) -> float:
        """How well a stretch of body memory is explained by the model, in [0, 1]: the mean
        log-probability per transition (:meth:`GestureModel.log_likelihood`) from 0 at the
        floor of an unseen transition to 1 at certainty. A dispatched gesture's new nodes
        count as the core nodes they copy (thesis: the models "can produce categorization
        probabilities of incoming data (here data from a BodyMemory)")."""
        copies = {} if self.dispatched is None else dict(zip(self.dispatched.nodes, self.dispatched.core))
        nodes = [copies.get(o.node, o.node) for o in observations]
        if len(nodes) < 2 or not self.model.states:
            return 0.0
        floor = math.log(MATCH_FLOOR)
        return min(max((self.model.log_likelihood(nodes, floor=MATCH_FLOOR) - floor) / -floor, 0.0), 1.0)

    def last_performance(self) -> tuple[float, float] | None:
        """(start, stop) of the last run of the model or of the gesture left behind."""
        runs = [r for r in (self.performed, None if self.successor is None else self.successor.performed) if r]
        return max(runs, default=None)

    def performance_match(self, t: float, window: float) -> float:
        """:meth:`match` of the last performance, for ``window`` seconds after it ended (what a
        trainer who saw it would reward); 0 otherwise."""
        run = self.last_performance()
        if run is None or not 0.0 <= t - run[1] <= window:
            return 0.0
        return self.match([o for o in self.memory.since(run[0]) if o.time <= run[1]])

    # -- as an action: performing the model --------------------------------------------------
    def program(self) -> MotorProgram | None:
        """The model's core as a motor program (none while the model is empty)."""
        return self.model.to_program(self.name) if self.model.states else None

    # -- what lasts ------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The model and how many lessons it has had (the body memory is not kept: a lesson is
        learnt when it is rewarded, within seconds)."""
        return {"model": self.model.to_dict(), "lessons": self.lessons}

    def restore(self, data: dict[str, Any], where: str) -> None:
        """Take back :meth:`to_dict` (ValueError naming ``where`` on damaged data)."""
        self.model = GestureModel.from_dict(data["model"], nodes=len(self.body.graph), where=f"{where}.model")
        self.lessons = bounds.count(data["lessons"], f"{where}.lessons")


class PerformGesture(RunsProgram):
    """Ac of the tuple left behind: run a dispatched gesture's motor program (done at its end)."""

    def __init__(self, name: str, body: "Body", gesture: Gesture) -> None:
        super().__init__(name, body)
        self.gesture = gesture

    def program(self) -> MotorProgram:
        return self.gesture.program
