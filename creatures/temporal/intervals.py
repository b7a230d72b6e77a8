"""Allen's interval algebra over action-tuple activations (thesis: "temporal logics",
figure 12: "the action-tuple structure can capture the primitive temporal relations of the
interval algebra (all thirteen of them) ... by engineering constraints on the trigger
conditions (Tr) and ending conditions (Du)").

Two halves:

* :func:`constrain` makes one tuple's activations obey a relation to another's, using only
  percepts that watch the other tuple's activity: a Trigger gate on *when it may start*, and
  a Do-until that says *when it must end* or *holds the other open*. Seven relations are made
  directly (:func:`before`, :func:`meets`, :func:`overlaps`, :func:`starts`, :func:`during`,
  :func:`finishes`, :func:`equals`); the other six are their :attr:`Relation.inverse` with
  the tuples swapped. A piece names them in a group's ``constraints`` (installations/wren.toml:
  its call meets its peck).
* :func:`relation` classifies two ``(start, end)`` intervals. It is kept as the constraint
  machinery's own check, and only that: a constraint is built from percepts and tick order
  (a gate on the same tick only works if the gated tuple's group ticks later), so whether
  it holds is a fact about a run, read from its activations (``selection`` and ``stop``
  events) with this classifier (tests/test_temporal_intervals.py, for every relation).
  No creature perceives or plays by a relation it recognises (no piece here has needed
  one), so nothing else calls it.

Activations are intervals ``[started_at, stopped_at]`` of clock time; "equal" times are the
same tick. Constraints are wired into tuples' ``trigger`` and ``do_until``, so apply them
before the tuples join an :class:`~creatures.behaviour.action_group.ActionGroup` (a group
indexes its tuples' triggers when they are added).
"""

from __future__ import annotations

import enum
from typing import Callable

from creatures.behaviour.action_tuple import ActionTuple, DoUntil
from creatures.behaviour.percept import Percept
from creatures.temporal.du import WrappedDoUntil


class Relation(enum.Enum):
    """The thirteen basic relations of ``x`` to ``y``."""

    BEFORE = "before"
    AFTER = "after"
    MEETS = "meets"
    MET_BY = "met_by"
    OVERLAPS = "overlaps"
    OVERLAPPED_BY = "overlapped_by"
    STARTS = "starts"
    STARTED_BY = "started_by"
    DURING = "during"
    CONTAINS = "contains"
    FINISHES = "finishes"
    FINISHED_BY = "finished_by"
    EQUALS = "equals"

    @property
    def inverse(self) -> "Relation":
        """The relation of ``y`` to ``x``."""
        return _INVERSE[self]


_INVERSE = {
    Relation.BEFORE: Relation.AFTER,
    Relation.MEETS: Relation.MET_BY,
    Relation.OVERLAPS: Relation.OVERLAPPED_BY,
    Relation.STARTS: Relation.STARTED_BY,
    Relation.DURING: Relation.CONTAINS,
    Relation.FINISHES: Relation.FINISHED_BY,
    Relation.EQUALS: Relation.EQUALS,
}
_INVERSE.update({inv: rel for rel, inv in list(_INVERSE.items())})

# (start of x vs start of y, end of x vs end of y) → relation, once x and y share time.
_BY_ENDPOINTS = {
    (0, 0): Relation.EQUALS,
    (0, -1): Relation.STARTS,
    (0, 1): Relation.STARTED_BY,
    (1, 0): Relation.FINISHES,
    (-1, 0): Relation.FINISHED_BY,
    (1, -1): Relation.DURING,
    (-1, 1): Relation.CONTAINS,
    (-1, -1): Relation.OVERLAPS,
    (1, 1): Relation.OVERLAPPED_BY,
}


def relation(x: tuple[float, float], y: tuple[float, float], *, tolerance: float = 0.0) -> Relation:
    """The Allen relation of interval ``x`` to interval ``y``.

    Times closer than ``tolerance`` count as equal (0: exactly equal, right for activations
    stamped by one clock). Intervals must have ``start < end``.

    >>> relation((0, 1), (1, 2))
    <Relation.MEETS: 'meets'>
    >>> relation((1, 2), (0, 3))
    <Relation.DURING: 'during'>
    """
    if not tolerance >= 0.0:
        raise ValueError(f"tolerance must be non-negative (got {tolerance!r})")
    for name, (start, end) in (("x", x), ("y", y)):
        if not start + tolerance < end:
            raise ValueError(f"interval {name} must have start < end (got {(start, end)!r})")

    def cmp(a: float, b: float) -> int:
        return 0 if abs(a - b) <= tolerance else (-1 if a < b else 1)

    (xs, xe), (ys, ye) = x, y
    end_vs_start, start_vs_end = cmp(xe, ys), cmp(xs, ye)
    if end_vs_start < 0:
        return Relation.BEFORE
    if end_vs_start == 0:
        return Relation.MEETS
    if start_vs_end > 0:
        return Relation.AFTER
    if start_vs_end == 0:
        return Relation.MET_BY
    return _BY_ENDPOINTS[cmp(xs, ys), cmp(xe, ye)]


# -- percepts that watch another tuple's activity ----------------------------------------
class ActivityPercept(Percept):
    """A percept about the activations of one tuple (1 when true, 0 otherwise)."""

    def __init__(self, tuple_: ActionTuple, *, name: str | None = None) -> None:
        super().__init__(name or f"{type(self).__name__.lower()}({tuple_.name})")
        self.tuple = tuple_

    def _ending(self, t: float) -> bool:
        tp = self.tuple
        return (tp.active and tp.do_until.evaluate(t) >= 1.0) or tp.stopped_at == t


class Ending(ActivityPercept):
    """The tuple ends at ``t``: it is active with its Du done, or it stopped at ``t``."""

    def evaluate(self, t: float) -> float:
        return float(self._ending(t))


class Running(ActivityPercept):
    """The tuple has been active since before ``t`` and is not ending at ``t``."""

    def evaluate(self, t: float) -> float:
        tp = self.tuple
        return float(tp.active and tp.started_at is not None and tp.started_at < t and not self._ending(t))


class Starting(ActivityPercept):
    """The tuple became active at ``t`` (visible to tuples whose group ticks after its own)."""

    def evaluate(self, t: float) -> float:
        return float(self.tuple.active and self.tuple.started_at == t)


class Active(ActivityPercept):
    """The tuple's activation includes ``t``: active now, or stopped at ``t``."""

    def evaluate(self, t: float) -> float:
        return float(self.tuple.active or self.tuple.stopped_at == t)


class Finished(ActivityPercept):
    """The tuple's last activation ended more than ``gap`` seconds before ``t``."""

    def __init__(self, tuple_: ActionTuple, *, gap: float = 0.0) -> None:
        if not gap >= 0.0:
            raise ValueError(f"gap must be non-negative (got {gap!r})")
        super().__init__(tuple_)
        self.gap = float(gap)

    def evaluate(self, t: float) -> float:
        tp = self.tuple
        return float(not tp.active and tp.stopped_at is not None and t - tp.stopped_at > self.gap)


class GatedTrigger(Percept):
    """Tr: the original trigger's saliency while ``gate`` is salient, 0 otherwise."""

    def __init__(self, trigger: Percept, gate: Percept) -> None:
        super().__init__(f"{trigger.name} if {gate.name}")
        self.trigger = trigger
        self.gate = gate

    def evaluate(self, t: float) -> float:
        return self.trigger.evaluate(t) if self.gate.evaluate(t) > 0.0 else 0.0


class ConstrainedDoUntil(WrappedDoUntil):
    """Du: the inner Du, also done when ``until`` is salient, never done while ``hold`` is.

    ``hold`` is how a tuple is kept open for another ("A may not end while C, during A, is
    still active"); ``until`` is how a tuple is made to end with another.
    """

    def __init__(self, inner: DoUntil, *, until: Percept | None = None, hold: Percept | None = None) -> None:
        super().__init__(inner)
        self.extra_until = until
        self.hold = hold

    def evaluate(self, t: float) -> float:
        if self.hold is not None and self.hold.evaluate(t) > 0.0:
            return 0.0
        done = self.inner.evaluate(t)
        if self.extra_until is not None:
            done = max(done, float(self.extra_until.evaluate(t)))
        return done


# -- constraints: make activations obey a relation ---------------------------------------
def _gate(tuple_: ActionTuple, gate: Percept) -> None:
    tuple_.trigger = GatedTrigger(tuple_.trigger, gate)


def _hold(tuple_: ActionTuple, by: ActionTuple) -> None:
    tuple_.do_until = ConstrainedDoUntil(tuple_.do_until, hold=Active(by))


def _end_with(tuple_: ActionTuple, other: ActionTuple) -> None:
    # Only the other's end ends it: its own duration model is not consulted.
    tuple_.do_until = DoUntil(None, until=Ending(other))


def before(x: ActionTuple, y: ActionTuple, *, gap: float = 0.0) -> None:
    """x before y: y starts more than ``gap`` seconds after x's last activation ended."""
    _gate(y, Finished(x, gap=gap))


def meets(x: ActionTuple, y: ActionTuple) -> None:
    """x meets y: y starts in the tick x ends ("B starts when A ends")."""
    _gate(y, Ending(x))


def overlaps(x: ActionTuple, y: ActionTuple) -> None:
    """x overlaps y: y starts while x runs and cannot end until x has ended."""
    _gate(y, Running(x))
    _hold(y, x)


def starts(x: ActionTuple, y: ActionTuple) -> None:
    """x starts y: y starts in the tick x starts (x's group must tick first) and outlasts x."""
    _gate(y, Starting(x))
    _hold(y, x)


def during(x: ActionTuple, y: ActionTuple) -> None:
    """x during y: x starts while y runs, and y is held open until x has ended ("C during A")."""
    _gate(x, Running(y))
    _hold(y, x)


def finishes(x: ActionTuple, y: ActionTuple) -> None:
    """x finishes y: x starts while y runs and ends in the tick y ends."""
    _gate(x, Running(y))
    _end_with(x, y)


def equals(x: ActionTuple, y: ActionTuple) -> None:
    """x equals y: y starts in the tick x starts (x's group ticks first) and ends with x."""
    _gate(y, Starting(x))
    _end_with(y, x)


MADE: dict[Relation, Callable[[ActionTuple, ActionTuple], None]] = {
    Relation.MEETS: meets,
    Relation.OVERLAPS: overlaps,
    Relation.STARTS: starts,
    Relation.DURING: during,
    Relation.FINISHES: finishes,
    Relation.EQUALS: equals,
}
"""The relations made by gating Tr and Du directly (with :func:`before`, which takes a gap);
each of the other six is its inverse with the tuples swapped (x after y is y before x)."""


def constrain(x: ActionTuple, rel: Relation, y: ActionTuple, *, gap: float = 0.0) -> None:
    """Make x's activations stand in ``rel`` to y's (``constrain(c, Relation.DURING, a)``);
    ``gap`` is the seconds between the earlier's end and the later's start of BEFORE and AFTER."""
    if gap and rel not in (Relation.BEFORE, Relation.AFTER):
        raise ValueError(f"a gap is for before and after, not {rel.value}")
    if rel is not Relation.BEFORE and rel not in MADE:
        x, rel, y = y, rel.inverse, x
    if rel is Relation.BEFORE:
        before(x, y, gap=gap)
    else:
        MADE[rel](x, y)
