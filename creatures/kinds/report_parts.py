"""Writing a creature's inner life to the events log (DESIGN.md "Seeing inside").

Shared by the kinds that report through the same events as *exchange*: ``selection`` /
``interruption`` / ``stop`` / ``credit`` from an :class:`ActionGroup`, periodic ``values``
and ``motivation`` snapshots, and the body's way through its motor graph
(:class:`MotorTrail`), each tagged with the creature's name so the report can plot creatures
side by side.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from creatures.behaviour.value import ChainValue, StanceValue

if TYPE_CHECKING:
    from creatures.behaviour.action_group import ActionGroup
    from creatures.behaviour.motivation import Motivation
    from creatures.kinds.parts import Body
    from creatures.motor.gesture import BodyMemory
    from creatures.motor.playback import Playback
    from creatures.runtime.world import World


def selection_logger(world: "World", creature: str) -> Callable[[dict[str, Any]], None]:
    """An ``on_event`` sink for an :class:`ActionGroup` that logs under ``creature``'s name."""

    def log(event: dict[str, Any]) -> None:
        fields = dict(event)
        kind, t = fields.pop("event"), fields.pop("t")
        fields.pop("group", None)
        world.log.emit(t, kind, creature=creature, **fields)

    return log


def report_values(world: "World", t: float, creature: str, group: "ActionGroup",
                  motivation: "Motivation | None" = None) -> None:
    """One ``values`` (and ``motivation``) snapshot of ``group``'s tuples at time ``t``, and of
    the tracer dye of its chained values (``dye``: tuple → goal → steps, thesis "value
    chaining"), which the values themselves do not show: what each tuple has learnt it leads to;
    and of its stance tags (``stance``: tuple → stance, thesis "emotional tags")."""
    world.log.emit(t, "values", creature=creature, values={tp.name: tp.value.to_float() for tp in group.tuples})
    dye = {tp.name: dict(tp.value.distances) for tp in group.tuples if isinstance(tp.value, ChainValue)}
    if dye:
        world.log.emit(t, "dye", creature=creature, distances=dye)
    stance = {tp.name: tp.value.stance for tp in group.tuples if isinstance(tp.value, StanceValue)}
    if stance:  # the emotional tags credit assignment carries (thesis "emotional tags")
        world.log.emit(t, "stance", creature=creature, stances=stance)
    if motivation is not None:
        world.log.emit(t, "motivation", creature=creature,
                       drives=dict(zip(motivation.names, motivation.levels_at(t).tolist())))


PATH_KEPT = 36_000
"""Nodes of a body's path kept for its state folder: an hour of a body crossing ten nodes a
second (432 kB of arrays per embodied creature; about 0.5 MB of JSON), the newest kept."""


class MotorTrail:
    """Every motor-graph node a body reaches, in order, for the events log (thesis
    "graph-based motor systems": the body's path through its graph).

    A snapshot of where the body is every half second skips the nodes it passed in between,
    and joining snapshots draws edges the graph does not have. So :meth:`follow` runs every
    tick, *before* ``Body.update`` (which forgets a finished course), and collects the
    course's own ``visited`` nodes; a course abandoned for a new one ends where the body
    turned, and the new one starts from there (an end of the same edge), so consecutive
    nodes are always joined by a graph edge. :meth:`report` logs the graph itself once
    (node → hand position, edges) as a ``motor graph`` event, then a ``motor`` snapshot with
    the nodes ``reached`` since the last one.
    """

    def __init__(self, world: "World", creature: str, body: "Body") -> None:
        self.world = world
        self.creature = creature
        self.body = body
        self.reached: list[int] = []
        self.times: list[float] = []  # when each of ``reached`` was reached (clock time)
        # the run's path for the state folder: a ring of the newest PATH_KEPT, two arrays made at
        # the first node reached (a list of tuples grew the heap by a block per node)
        self._taken = (np.empty(0, np.int32), np.empty(0))
        self._count = 0
        self.memory: "BodyMemory | None" = None  # complex shaping's memory of the nodes passed
        self._last: int | None = None
        self._course: "Playback | None" = None
        self._seen = 0  # nodes of the current course already reached
        self._graph_logged = False

    def follow(self, t: float) -> None:
        """Collect the nodes reached by clock time ``t`` (call every tick, before the body moves on)."""
        motor = self.body.motor
        course = motor.playback
        if course is None:
            self._reach(motor.position(t).node, t)
            return
        if course is not self._course:
            self._course, self._seen = course, 0
        visited = course.visited(t)
        for node in visited[self._seen:]:
            self._reach(node, t)
        self._seen = len(visited)

    def _reach(self, node: int, t: float) -> None:
        if node != self._last:
            self.reached.append(node)
            self.times.append(round(t, 4))
            nodes, times = self._taken
            if not len(nodes):
                nodes, times = self._taken = np.empty(PATH_KEPT, np.int32), np.empty(PATH_KEPT)
            nodes[self._count % PATH_KEPT], times[self._count % PATH_KEPT] = node, round(t, 4)
            self._count += 1
            self._last = node
            if self.memory is not None:
                self.memory.record(node, t)

    def path_state(self) -> dict[str, list]:
        """The nodes the body reached this run and when (the last :data:`PATH_KEPT`): saved
        beside the creature's learned state, so ``creatures export-motion STATE_DIR`` has the
        path of a live run that kept no events log."""
        nodes, times = self._taken
        kept = min(self._count, PATH_KEPT)
        order = (np.arange(kept) + self._count - kept) % PATH_KEPT if kept else np.zeros(0, np.int64)
        return {"nodes": nodes[order].tolist(), "at": times[order].tolist()}

    def report(self, t: float, *, shift: tuple[float, float, float] = (0.0, 0.0, 0.0), **fields: object) -> None:
        """The graph (first time only), then where the body is and what it reached since;
        ``shift`` moves the hand by where the whole body stands in the room (a walking
        creature), ``fields`` add kind-specific context to the ``motor`` event, and a body
        with layers adds each contributor's weight (``layers``) and, for every joint more than
        one drives, each one's weight there (``joints``), at the creature's ``report_every``."""
        log = self.world.log
        if not self._graph_logged:
            graph = self.body.graph
            edges = sorted({(min(a, b), max(a, b)) for a, b in graph.edges()})
            log.emit(t, "motor graph", creature=self.creature, effector=self.body.effector,
                     hands=np.round(self.body.reach(), 4), edges=edges)
            self._graph_logged = True
        hand = self.body.hand() + np.asarray(shift)
        if self.body.layers is not None:  # who drives the joints (issue 17: contributors in the log)
            blend = self.body.layers.blend
            names = self.body.skeleton.names
            shared = {names[j]: who for j, who in enumerate(blend.channel_contributors(t)) if len(who) > 1}
            fields = {**fields, "layers": blend.contributors(t), "joints": shared}
        log.emit(t, "motor", creature=self.creature, node=self.body.motor.position(t).node,
                 position={"x": hand[0], "y": hand[1], "z": hand[2]}, reached=self.reached, at=self.times, **fields)
        self.reached, self.times = [], []
