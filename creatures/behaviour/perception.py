"""Perception as action (thesis: "perception as action").

A non-exclusive action-group (every member may be active at once: ``max_active`` = its size)
holds *perception actions*: tuples whose Tr looks at percepts as before and whose activation
is the act of perceiving something. A sub-tree of :class:`PerceivingPercept` nodes then
models those tuples' activity, so other tuples can trigger on "I am perceiving X" rather
than on X itself, with the richer life of an action-tuple: a Du (how long a perception
lasts), credit assignment, expectations.

What a percept lacks and a tuple has is a value: the value of perceiving the thing. It
grounds the percept's saliency — a perceiving percept is as salient as what is being
perceived is worth (a zebra's perception of a lion can be large and negative). That value is
grounded both by other perception actions (credit assignment inside the perception group)
and by the values of the actions that result from perceiving it: when a tuple triggered by a
perceiving percept earns credit, :class:`~creatures.behaviour.learning.PerceptLearning`
updates that percept, which blends the perception tuples it watches toward the credit.
"""

from __future__ import annotations

import math
from typing import Callable

from creatures.behaviour.action_tuple import ActionTuple
from creatures.behaviour.percept import Percept
from creatures.behaviour.value import ScalarValue


class PerceivingPercept(Percept):
    """The activity of perception actions as a saliency.

    ``tuples()`` lists the perception tuples watched (one, or a whole group's; a callable
    because a creature builds its percepts before its tuples). A tuple's activity is 1
    while active and a trace exp(−(t − stopped) / ``trace``) after (0 with no trace); with
    ``valued`` it is multiplied by the tuple's value. The percept reads the strongest
    activity among its tuples (by magnitude, keeping the sign of a negative value).
    ``ground`` is the rate at which :meth:`update` blends the perceived tuples' values toward
    the credit of what resulted from perceiving them (0: never).
    """

    def __init__(
        self,
        name: str,
        tuples: Callable[[], list[ActionTuple]],
        *,
        trace: float = 0.0,
        valued: bool = True,
        ground: float = 0.1,
        parent: Percept | None = None,
    ) -> None:
        super().__init__(name, parent=parent)
        if trace < 0 or not 0.0 <= ground <= 1.0:
            raise ValueError(f"{name}: trace must be ≥ 0 and ground in [0, 1]")
        self.tuples = tuples
        self.trace = float(trace)
        self.valued = valued
        self.ground = float(ground)

    def activity(self, tuple_: ActionTuple, t: float) -> float:
        if tuple_.active:
            return 1.0
        if self.trace == 0.0 or tuple_.stopped_at is None:
            return 0.0
        return math.exp(-max(0.0, t - tuple_.stopped_at) / self.trace)

    def evaluate(self, t: float) -> float:
        best = 0.0
        for tuple_ in self.tuples():
            a = self.activity(tuple_, t)
            if a and self.valued:
                a *= tuple_.value.to_float()
            if abs(a) > abs(best):
                best = a
        return best

    def update(self, t: float, value: float) -> None:
        """What resulted from perceiving earned ``value``: the perceptions active at ``t``
        (the situation that led to it) move toward it by ``ground`` × their activity."""
        for tuple_ in self.tuples():
            a = self.ground * self.activity(tuple_, t)
            if a > 0.0:
                tuple_.value.blend_to(ScalarValue(value), a)
