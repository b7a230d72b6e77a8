"""A character-wide emotional state that stance-tagged values perturb (thesis: "emotional
tags": "StanceValue perturbs a character wide emotional state towards a particular stance
state when such action-tuples become active").

The state is one of the creature's drives (thesis "soft state": emotion and motivation are
modelled explicitly, with "the same primitives"): its decay returns the mood to its
equilibrium between perturbations, it is saved and logged with the other drives, and a
``drive`` percept lets other tuples act on it. Each time a tuple whose value is a
:class:`~creatures.behaviour.value.StanceValue` becomes active, the mood is moved toward
that tuple's stance by ``strength`` (``StanceValue.perturb``). Since credit assignment blends
the stance tag with the value, a startle (stance −1, "run away") that comes to precede food
(stance +1) turns the mood it brings from fear toward gladness.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

from creatures.behaviour.action_tuple import ActionTuple
from creatures.behaviour.motivation import Motivation
from creatures.behaviour.value import StanceValue

if TYPE_CHECKING:
    from creatures.behaviour.action_group import ActionGroup


class Mood:
    """Drive ``drive`` of ``motivation`` as the mood; :meth:`felt` is an action-group start
    hook (``group.on_start``). ``on_event`` receives a ``mood`` event per perturbation
    (tuple, its stance, the mood before and after)."""

    def __init__(self, motivation: Motivation, drive: str, *, strength: float = 0.25,
                 on_event: Callable[[dict[str, Any]], None] | None = None) -> None:
        if not 0.0 < strength <= 1.0:
            raise ValueError(f"mood strength must be in (0, 1] (got {strength!r})")
        motivation.index(drive)
        self.motivation = motivation
        self.drive = drive
        self.strength = float(strength)
        self.on_event = on_event

    def level(self, t: float) -> float:
        return self.motivation.level(self.drive, max(t, self.motivation.time))

    def felt(self, group: "ActionGroup", t: float, tuple_: ActionTuple) -> None:
        """``tuple_`` became active at ``t``: a stance value pulls the mood toward its stance."""
        value = tuple_.value
        if not isinstance(value, StanceValue):
            return
        before = self.level(t)
        self.motivation.perturb(t, self.drive, value.perturb(before, self.strength) - before)
        if self.on_event is not None:
            self.on_event({"event": "mood", "t": t, "group": group.name, "tuple": tuple_.name,
                           "stance": value.stance, "before": before, "after": self.level(t)})
