"""Motor moves several creature kinds share (thesis "towards a complete motor system").

A kind's actions ask its :class:`~creatures.kinds.parts.Body` to go somewhere on the motor
graph; when A* finds no way there (an edited graph may leave a node unreachable) the body
simply carries on with what it was doing rather than the creature failing.
"""

from __future__ import annotations

from collections.abc import Sequence

from creatures.behaviour.action_tuple import Action, ActionTuple
from creatures.kinds.parts import Body
from creatures.motor.search import NoPath, Path


def head_for(body: Body, t: float, nodes: Sequence[int] | Path) -> bool:
    """Set off along the shortest path to the nearest of ``nodes`` (or along ``nodes`` if it
    is already a path); False when there is no way there."""
    motor = body.motor
    try:
        motor.set_course(t, nodes if isinstance(nodes, Path) else motor.course(t, list(nodes)))
    except NoPath:
        return False
    return True


class Rest(Action):
    """Return to the nearest low-energy pose and stay there (thesis "enforcing physical
    constraints")."""

    def __init__(self, body: Body) -> None:
        super().__init__("rest")
        self.body = body

    def start(self, t: float, tuple_: ActionTuple) -> None:
        try:
            head_for(self.body, t, self.body.finder.to_rest(self.body.motor.position(t)))
        except NoPath:
            pass
