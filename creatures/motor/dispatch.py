"""A learnt gesture's core dispatched into the motor graph as new material (thesis "learning
to chase your tail – part 2": "we can pull out the core of Ac and 'dispatch' it down to the
motor system – treating it as new animation material to be added to the graph in the same
way that we treat new animation material from the animators").

The core of a :class:`~creatures.motor.gesture.GestureModel` is a chain of motor-graph
nodes with the time the body dwelt at each. Its poses become one new source animation
(named after the gesture, every node labelled with that name) patched into the graph with
:meth:`MotorGraph.add_poses` — each new node joins its nearest poses and its successor in
the gesture — and a :class:`~creatures.motor.programs.MotorProgram` walks the body through
the new nodes in order: the "execute MotorProgram new_gesture_1" left behind in place of
the guide. Dispatching the same core into the same graph gives the same node indices, so a
saved creature re-dispatches its gestures on reload and its programs still name them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from creatures import bounds
from creatures.motor.graph import MotorGraph
from creatures.motor.pose import PoseSet
from creatures.motor.programs import MotorProgram, Statement, parse_programs

SHORTEST_DWELL = 0.05
"""Seconds between two new key-frames at least: a model state seen only in passing still
gets a time of its own (PoseSet velocities are differences over time)."""


@dataclass(frozen=True)
class Gesture:
    """A dispatched gesture: its name, the graph nodes it was learnt over, their dwell times,
    the new nodes standing for them and the motor program that performs it."""

    name: str
    core: tuple[int, ...]
    dwell: tuple[float, ...]
    nodes: tuple[int, ...]
    program: MotorProgram

    def to_dict(self) -> dict[str, object]:
        """Plain data: enough to dispatch it again into the same base graph, plus the program
        text, which the reload checks against the re-dispatched nodes."""
        return {"name": self.name, "core": list(self.core), "dwell": list(self.dwell),
                "program": program_text(self.program)}


def program_text(program: MotorProgram) -> str:
    """The program in the thesis's language (``name: getTo 12; wait; …``), as
    :func:`~creatures.motor.programs.parse_programs` reads it back."""
    return f"{program.name}: " + "; ".join(str(s).replace("{", "").replace("}", "") for s in program.statements)


def gesture_material(graph: MotorGraph, name: str, core: Sequence[int], dwell: Sequence[float]) -> PoseSet:
    """The core's poses as one new source animation ``name``, times from the dwell times."""
    core = np.asarray(core, dtype=np.int64)
    if len(core) < 2:
        raise ValueError(f"gesture {name!r}: a core of {len(core)} node(s) is no movement to dispatch")
    if core.min() < 0 or core.max() >= len(graph):
        raise ValueError(f"gesture {name!r}: the core names nodes outside 0..{len(graph) - 1}")
    p = graph.poses
    steps = np.maximum(np.asarray(dwell, dtype=float), SHORTEST_DWELL)
    times = np.concatenate(([0.0], np.cumsum(steps[:-1])))
    return PoseSet.animation(p.skeleton, p.rotations[core], p.roots[core], times, name,
                             [frozenset({name})] * len(core))


def dispatch(graph: MotorGraph, name: str, core: Sequence[int], dwell: Sequence[float]) -> Gesture:
    """Add the core to ``graph`` as new material and write the program that performs it:
    ``getTo`` each new node in turn, waiting for the body, then ``end``."""
    if name in graph.poses.sources:
        raise ValueError(f"gesture {name!r}: the graph already has material by that name")
    nodes = graph.add_poses(gesture_material(graph, name, core, dwell)).tolist()
    statements = [s for n in nodes for s in (Statement("getTo", (n,)), Statement("wait"))]
    program = MotorProgram(name, [*statements, Statement("end")])
    return Gesture(name, tuple(int(n) for n in core), tuple(float(d) for d in dwell), tuple(nodes), program)


def redispatch(graph: MotorGraph, data: dict, where: str = "gesture") -> Gesture:
    """A gesture saved by :meth:`Gesture.to_dict`, dispatched again; the saved program must be
    the one the new nodes give (ValueError naming ``where`` otherwise: a state saved over
    another body)."""
    name = data["name"]
    if not isinstance(name, str) or not name:
        raise ValueError(f"{where}.name: must be a non-empty string")
    core = [bounds.count(n, f"{where}.core", high=len(graph) - 1)
            for n in bounds.items(data["core"], f"{where}.core", longest=4096, shortest=2)]
    dwell = [bounds.number(d, f"{where}.dwell", low=0.0, high=3600.0)
             for d in bounds.items(data["dwell"], f"{where}.dwell", longest=4096, shortest=len(core))]
    if len(dwell) != len(core):
        raise ValueError(f"{where}.dwell: one time per core node ({len(core)}), found {len(dwell)}")
    gesture = dispatch(graph, name, core, dwell)
    saved = parse_programs(str(data["program"]), source=f"{where}.program").get(name)
    if saved is None or saved.statements != gesture.program.statements:
        raise ValueError(f"{where}.program: does not perform the gesture's new nodes in this body's graph")
    return gesture
