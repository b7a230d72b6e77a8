"""The action-tuple: Trigger | Action | Do-until | Value (thesis: "the action-tuple",
"computing expected values").

Each tuple is a hypothesis: in context Tr, doing Ac until Du holds is worth V. Tr and Du share
one functional interface (``evaluate(t)``) and get their meaning from their role. The expected
value is ``Tr.evaluate(t)·V`` while inactive and ``(1 − Du.evaluate(t))·V`` while active
(with a graded Du, declining over the planned duration).
Every tuple follows one life cycle, after py_trees: ``start`` → ``update``… → ``stop``.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from creatures.behaviour.percept import Percept
from creatures.behaviour.value import ScalarValue, Value


class DurationModel(Protocol):
    """Anything a Du can sample a duration from and teach the actual duration to."""

    def sample(self, rng: np.random.Generator) -> float: ...

    def update(self, duration: float) -> None: ...


class Action:
    """Ac: what the creature does. Subclasses drive motors, voices or MIDI.

    ``proximity_to`` says how much credit earned by one action should also reach another
    (thesis: "all equivalent action-tuples take place in credit assignment"); identical
    actions have proximity 1, unrelated ones 0.
    """

    def __init__(self, name: str) -> None:
        self.name = name

    def start(self, t: float, tuple_: "ActionTuple") -> None:
        """Called once when the owning tuple becomes active."""

    def update(self, t: float) -> None:
        """Called on every tick while the owning tuple is active."""

    def stop(self, t: float, *, interrupted: bool) -> None:
        """Called once when the owning tuple stops (interrupted or done)."""

    def proximity_to(self, other: "Action") -> float:
        return 1.0 if other.name == self.name else 0.0

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


class DoUntil:
    """Du: when an active tuple should stop, as a saliency in [0, 1] (1 = done).

    ``duration`` is a fixed number of seconds or a shared duration model that is sampled when
    the tuple starts and taught the actual duration when it stops, so many tuples looking at
    one model share one pulse. ``until`` is an optional percept for "until the food is gone";
    the tuple is done when either says so.

    ``graded``: Du ramps from 0 at the start to 1 at the planned duration instead of stepping
    (thesis, "computing expected values": while active the expected value is related to "how
    *distant* the world is from the ending condition (including the expected duration)"), so
    an active tuple's expected value ``(1 − Du)·V`` declines as its time runs out and an
    interruption competes against what is left of it, not against its full value. The tuple
    still stops at the planned duration (Du = 1) or when ``until`` says so.

    ``fresh``: the until-percept counts only once it has fallen below 1 since the start, so
    "until the next onset" is not ended at once by the onset that triggered the tuple.

    Du is two descriptions of the end, :meth:`timing` (the planned duration) and :meth:`world`
    (the until-percept): the tuple stops when either says done; what the world should look
    like when it does is the expectation :mod:`creatures.behaviour.expectation` checks.

    An activation the clock jumped across (:meth:`span_gap`, called by the action-group on a
    clock gap) teaches its model nothing: its length is mostly time the creature did not live
    (a suspended machine, a fast-forwarded clock), not a duration of the action (thesis,
    "percept updating – model building": a model is built from what the creature perceived).
    """

    def __init__(
        self,
        duration: float | DurationModel | None = None,
        *,
        until: Percept | None = None,
        learn: bool = True,
        graded: bool = False,
        fresh: bool = False,
    ) -> None:
        if duration is None and until is None:
            raise ValueError("a Do-until needs a duration, an until-percept, or both")
        if isinstance(duration, (int, float)) and not duration > 0:
            raise ValueError(f"a fixed duration must be positive (got {duration!r})")
        self.duration = duration
        self.until = until
        self.learn = learn
        self.graded = graded
        self.fresh = fresh
        self._armed = not fresh
        self.started_at: float | None = None
        self.planned: float = float("inf")
        self.spans_gap = False

    @property
    def model(self) -> DurationModel | None:
        return None if isinstance(self.duration, (int, float, type(None))) else self.duration

    def begin(self, t: float, rng: np.random.Generator) -> None:
        self.started_at = t
        self.spans_gap = False
        self._armed = not self.fresh
        if self.duration is None:
            self.planned = float("inf")
        elif isinstance(self.duration, (int, float)):
            self.planned = float(self.duration)
        else:
            self.planned = float(self.duration.sample(rng))

    def timing(self, t: float) -> float | None:
        """The planned-duration part of Du at ``t`` (a step, or the graded ramp), or None
        when there is no plan (an until-percept alone, or not started)."""
        if self.started_at is None or self.planned == float("inf"):
            return None
        elapsed = t - self.started_at
        if elapsed >= self.planned:
            return 1.0
        return max(elapsed, 0.0) / self.planned if self.graded else 0.0

    def world(self, t: float) -> float | None:
        """The until-percept part of Du at ``t``, or None without one (``fresh``: 0 until
        the percept has fallen below 1 since the start)."""
        if self.until is None:
            return None
        w = float(self.until.evaluate(t))
        if not self._armed:
            self._armed = w < 1.0
            return 0.0
        return w

    @property
    def settled(self) -> bool:
        """Whether evaluating it twice at one time gives one answer: not while a ``fresh``
        until-percept waits for its first fall below 1 (the first evaluation may see it)."""
        return self._armed

    def evaluate(self, t: float) -> float:
        timing, world = self.timing(t), self.world(t)
        return max(0.0 if timing is None else timing, 0.0 if world is None else world)

    def span_gap(self) -> None:
        """The clock jumped while this activation ran: :meth:`end` will not teach its length."""
        if self.started_at is not None:
            self.spans_gap = True

    def end(self, t: float) -> float:
        """Close the activation; teach the model the actual duration (unless the activation
        spans a clock gap, or lasted longer than the model's ``max_duration``); return it.

        A tuple held open by another (an interval constraint) or planned from a pulse longer
        than an hour can live longer than its model takes a duration: the model refused it
        with a ValueError, raised in the middle of the group's tick, and the creature stopped."""
        if self.started_at is None:
            return 0.0
        actual = t - self.started_at
        self.started_at = None
        model = self.model
        if (self.learn and model is not None and 0 < actual <= getattr(model, "max_duration", math.inf)
                and not self.spans_gap):
            model.update(actual)
        self.spans_gap = False
        return actual


class ActionTuple:
    """Tr | Ac | Du | V — a valued hypothesis about doing something in some context."""

    def __init__(
        self,
        name: str,
        trigger: Percept,
        action: Action,
        do_until: DoUntil,
        value: Value | float,
    ) -> None:
        self.name = name
        self.trigger = trigger
        self.action = action
        self.do_until = do_until
        self.value: Value = value if isinstance(value, Value) else ScalarValue(value)
        self.active = False
        self.started_at: float | None = None
        self.stopped_at: float | None = None  # when the last activation ended (interval relations)
        self.trigger_at_start = 0.0
        self.context: dict[str, Any] = {}

    def expected_value(self, t: float) -> float:
        v = self.value.to_float()
        if self.active:
            return (1.0 - self.do_until.evaluate(t)) * v
        return self.trigger.evaluate(t) * v

    def start(self, t: float, rng: np.random.Generator, **context: Any) -> None:
        """Become active: remember Tr at activation (for credit), sample Du, start Ac."""
        self.active = True
        self.started_at = t
        self.trigger_at_start = float(self.trigger.evaluate(t))
        self.context = dict(context)
        self.do_until.begin(t, rng)
        self.action.start(t, self)

    def update(self, t: float) -> None:
        self.action.update(t)

    def stop(self, t: float, *, interrupted: bool = False) -> float:
        """Become inactive; returns how long the tuple was active."""
        self.active = False
        self.stopped_at = t
        self.action.stop(t, interrupted=interrupted)
        return self.do_until.end(t)

    def proximity_to(self, other: "ActionTuple") -> float:
        return self.action.proximity_to(other.action)

    def __repr__(self) -> str:
        return (
            f"ActionTuple({self.trigger.name} | {self.action.name} | "
            f"{self.name}; V={self.value.to_float():.3g})"
        )
