"""The image creature: "another, trivial, behavior system – which explores the graph in
response to the commands read in from the audio EDL" (thesis, "ozymandias (video)").

Two action-tuples in one :class:`~creatures.behaviour.action_group.ActionGroup`:

* ``seek`` (Tr: an EDL entry is sounding; Du: until none is; V 1): "move along paths
  created to get to video material corresponding to the *time* that the sonic creature has
  taken audio material from". Each output frame the target is the footage frame of the
  sounding entry's source time (it advances as the part plays); the creature moves along the
  cheapest graph path towards it, at most ``max_step`` nodes a frame, so a far target is
  reached in one frame of blurred travel and a near one is simply followed.
* ``drift`` (Tr: always; V 0.1): between commands the footage plays on along its natural
  chain, taking a jump where the chain ends.

Neither value is learnt (α = 0): the behaviour is the EDL's. Where the graph has no path
(footage with no repeats and a target behind), the creature *cuts* to it and counts the cut.

Each :class:`Shot` lists the nodes passed to reach it; :mod:`creatures.image.video` counts
the traversals and blurs each frame over those nodes and a tail that grows with how often
they were traversed — "to modulate how these paths are played out according to the number of times
that the nodes have been traversed – specifically the amount of motion blur".
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import FunctionPercept
from creatures.behaviour.value import ScalarValue
from creatures.image.footage import Footage
from creatures.image.image_graph import ImageGraph


@dataclass(frozen=True)
class Command:
    """One EDL entry as the image creature reads it: from ``start`` to ``end`` (output
    seconds) show the recording from ``source`` seconds on."""

    start: float
    end: float
    source: float
    source_end: float

    @classmethod
    def from_entry(cls, entry: dict[str, Any], sample_rate: int) -> "Command":
        start = entry["output_frame"] / sample_rate
        length = (entry["source_end_frame"] - entry["source_start_frame"]) / sample_rate
        return cls(start, start + length, entry["source_start_frame"] / sample_rate,
                   entry["source_end_frame"] / sample_rate)


@dataclass
class Shot:
    """One output frame: the nodes passed to reach it (the last is shown), the command it
    answered (None while drifting), and whether it was a cut."""

    time: float
    nodes: list[int]
    command: Command | None
    cut: bool = False


@dataclass
class _Walk:
    graph: ImageGraph
    footage: Footage
    max_step: int
    node: int = 0
    plan: list[int] = field(default_factory=list)
    goal: int | None = None
    cuts: int = 0
    passed: list[int] = field(default_factory=list)
    cut: bool = False

    def towards(self, goal: int) -> None:
        if goal != self.goal or not self.plan:
            if self.plan and goal in self.plan:  # the target moved on along the plan
                self.plan = self.plan[: self.plan.index(goal) + 1]
            else:
                found = self.graph.path(self.node, goal)
                if found is None:
                    self.cuts += 1
                    self.cut = True
                    found = [goal]
                self.plan = found
            self.goal = goal
        take, self.plan = self.plan[: self.max_step], self.plan[self.max_step:]
        self.passed.extend(take)
        if take:
            self.node = take[-1]

    def drift(self) -> None:
        self.goal, self.plan = None, []
        following = self.graph.matrix.indices[self.graph.matrix.indptr[self.node]:self.graph.matrix.indptr[self.node + 1]]
        if self.node + 1 < self.graph.count:
            self.node += 1
        elif len(following):
            self.node = int(following[0])
        self.passed.append(self.node)


class _Seek(Action):
    def __init__(self, walker: "ImageCreature") -> None:
        super().__init__("seek")
        self.walker = walker

    def update(self, t: float) -> None:
        command = self.walker.command(t)
        if command is not None:
            source = command.source + (t - command.start)
            self.walker.walk.towards(self.walker.walk.footage.frame_at(min(source, command.source_end)))


class _Drift(Action):
    def __init__(self, walker: "ImageCreature") -> None:
        super().__init__("drift")
        self.walker = walker

    def update(self, t: float) -> None:
        self.walker.walk.drift()


class ImageCreature:
    """Walks ``graph`` at ``fps`` output frames a second, commanded by ``commands``."""

    def __init__(self, footage: Footage, graph: ImageGraph, commands: list[Command], *, fps: float,
                 max_step: int = 64, seed: int = 0) -> None:
        self.fps = float(fps)
        self.walk = _Walk(graph, footage, max_step)
        self.commands = sorted(commands, key=lambda c: c.start)
        self._starts = [c.start for c in self.commands]
        commanded = FunctionPercept("commanded", lambda t: 1.0 if self.command(t) is not None else 0.0)
        quiet = FunctionPercept("quiet", lambda t: 1.0 - commanded.evaluate(t))
        self.group = ActionGroup("images", rng=np.random.default_rng(seed), alpha=0.0, tuples=[
            ActionTuple("seek", commanded, _Seek(self), DoUntil(until=quiet), ScalarValue(1.0, plasticity=0.0)),
            ActionTuple("drift", FunctionPercept("always", lambda t: 1.0), _Drift(self), DoUntil(1.0 / self.fps),
                        ScalarValue(0.1, plasticity=0.0)),
        ])

    def command(self, t: float) -> Command | None:
        """The newest EDL entry sounding at ``t`` (the latest the sonic creature started)."""
        i = bisect.bisect_right(self._starts, t)
        for command in reversed(self.commands[max(0, i - 8):i]):  # overlapping reads are few
            if command.start <= t < command.end:
                return command
        return None

    def run(self, duration: float) -> list[Shot]:
        """Every output frame of ``duration`` seconds."""
        shots = []
        for k in range(int(np.ceil(duration * self.fps))):
            t = k / self.fps
            self.walk.passed, self.walk.cut = [], False
            self.group.tick(t)  # stops, selects and updates the active tuple
            shots.append(Shot(t, self.walk.passed or [self.walk.node], self.command(t), self.walk.cut))
        return shots
