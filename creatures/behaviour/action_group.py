"""The action-group: competitive action selection and credit assignment (thesis: "the
action-group", "a baseline action selection mechanism", "credit assignment", "hierarchical
action-groups").

Selection follows the thesis's pseudocode. When a slot is free, choose a tuple with
probability proportional to the expected values ``S`` and record every tuple's expected value
at that moment (the *base* values). While a tuple is active, interrupt it only if some other
tuple's expected value has grown to ``multiple`` × its base value *and* is at least the
active tuple's current expected value; then choose again from everyone (the active tuple
included, so an interruption may confirm what the creature is already doing). ``multiple``
above 1 is the hysteresis that stops the creature dithering between near-equal tuples; a
tuple whose trigger was absent at the last selection (base ≤ 0) only has to become positive
and beat the active tuple, which is how the dog still reacts to a sudden noise.

Expected values ≤ 0 are never chosen: a non-positive value says "not worth doing now". With
a ``temperature`` T the positive expected values pass through the Boltzmann function
``exp(S/T)`` (the thesis's exploration/exploitation extension); negative and zero values are
still excluded rather than given the small weight ``exp(S/T)`` would give them, so a lion
tuple whose negative saliency meets a negative value (S > 0) can win while a negative S can
never be drawn by a high temperature.

Credit assignment runs whenever a tuple becomes active (a finished tuple starting again is
a new activation and discounts itself; an interruption that re-chooses the running tuple is
not): every tuple ``i`` is blended toward the discounted value of the newcomer,
``V_i ← (1 − a_i)V_i + a_i·β·V_n`` with ``a_i = α · proximity(last_active, i) · Tr_i``
(clipped to [0, 1]) where ``Tr_i`` is tuple i's trigger saliency at the time the last active
tuple became active. Proximity is graded, per ordered pair of actions, and may be learnt
(:mod:`creatures.behaviour.proximity`); an activation whose credit raised its value (what
followed was worth more) or that a reward from outside reached counts as rewarded: the
proximity table learns from it and the ``on_credit`` hooks are told (complex shaping). β·V_n is a value of V_n's own kind (:func:`discounted`), so tracer dye or
stance tags travel back with it. Only leaf tuples take credit, and a group tuple's transitions
are credited between the leaves it ran (hierarchical groups: "assign only the credit to the
leaf nodes"); a group tuple's Du is its active child's Du.

A clock gap is a step between two consecutive ticks of a group longer than ``creatures.clock.CLOCK_GAP``
seconds: the machine was suspended, the creature's thread stalled, or an offline run
fast-forwarded its clock. Every tuple active across it is told (``DoUntil.span_gap``) and its
activation's length is not learnt as a duration (thesis, "percept updating – model building":
a Du model is a model of what the creature lived; a 4 s mirror that "lasted" a night would
otherwise teach a mean of hours, and the creature would then hold one mirror all day). The
gap is logged as a ``gap`` event. Values are untouched: credit assignment depends on which
tuple followed which, not on how long either lasted.

Hot path: triggers are evaluated once per distinct percept (percepts are creature-wide and
shared between tuples) and combined with the values as numpy arrays, so only the active
tuples do Python-level work per tick. A crowd's groups (one per creature) go further:
:class:`CrowdTick` works out their expected values and whether selection has work as arrays
across the crowd, and only a group with something to do runs its own Python.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterable, Iterator, Protocol

import numpy as np

from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import Percept
from creatures.behaviour.proximity import Proximity
from creatures.behaviour.value import Value, reattach, restored, value_from_dict
from creatures.clock import clock_gap

if TYPE_CHECKING:
    from creatures.behaviour.expectation import Expectations

EventSink = Callable[[dict[str, Any]], None]
CreditHook = Callable[["ActionGroup", float, "Activation"], None]
"""Told ``(group, t, activation)`` when a leaf activation was rewarded (complex shaping's
gesture model learns what the body did during it)."""
StartHook = Callable[["ActionGroup", float, ActionTuple], None]
"""Told ``(group, t, tuple)`` when a tuple becomes active (a stance value perturbs the
creature's mood: :mod:`creatures.behaviour.emotion`)."""

RECALL = 10.0
"""Seconds an ended activation is remembered for a late reward (the longest reward window)."""

Ready = bool | tuple[np.ndarray, np.ndarray, bool]
"""A group's tick as :class:`CrowdTick` worked it out: True (its one active tuple is done), False
(nothing to do), or its triggers, its expected values and whether selection has work
(:meth:`ActionGroup.idle`, :meth:`ActionGroup.grown`)."""



@dataclass
class Activation:
    """One time a tuple was active: when, and every tuple's Tr saliency when it began (what
    credit assignment needs to credit it later)."""

    tuple_: ActionTuple
    started: float
    triggers: np.ndarray
    ended: float | None = None


class Learner(Protocol):
    """Anything that learns from a credit assignment (see ``creatures.behaviour.learning``)."""

    def after_credit(
        self, group: "ActionGroup", t: float, last: ActionTuple, a: np.ndarray, target: Value, before: np.ndarray
    ) -> None: ...


def discounted(value: Value, beta: float) -> Value:
    """β·V as a value of the same kind, so hidden structure (tracer dye, stance tags) rides
    along with the scalar when ``blend_to`` carries it back."""
    data = value.to_dict()
    data["value"] = beta * data["value"]
    return value_from_dict(data)


def ungrounded_message(name: str, alpha: float, discount: float) -> str:
    """Why a group that assigns credit needs a fixed value to learn from (thesis "credit
    assignment": values flow back from consummatory actions; with none, each step only blends
    a value toward β × another value and all of them shrink geometrically toward 0)."""
    return (f"group {name!r} assigns credit (alpha = {alpha:g}, discount = {discount:g}) but none of its tuples "
            f"(nor those of the groups it holds) has a non-plastic value: every value would only be blended toward {discount:g} × another value, "
            "shrinking geometrically toward 0 (thesis 'credit assignment': values are grounded by consummatory "
            "rewards)")


def grounds(value: Value) -> bool:
    """A value credit assignment cannot move (plasticity 0): a reward that grounds the others."""
    return getattr(value, "plasticity", 1.0) == 0.0


def leaves(tuples: Iterable[ActionTuple]) -> Iterator[ActionTuple]:
    """The leaf tuples under ``tuples``: a group tuple's are its group's, at any depth. Credit
    targets a leaf's value (:meth:`ActionGroup.assign_credit`), so a reward there grounds the group."""
    for tp in tuples:
        if isinstance(tp.action, GroupAction):
            yield from leaves(tp.action.group.tuples)
        else:
            yield tp


def selection_probabilities(expected: np.ndarray, temperature: float | None = None) -> np.ndarray | None:
    """Probabilities ∝ ``expected`` (or ∝ ``exp(S/T)``) over the strictly positive entries.

    Returns ``None`` when nothing is positive: nothing is worth doing.
    """
    positive = expected > 0.0
    if not positive.any():
        return None
    weights = np.zeros_like(expected, dtype=float)
    s = expected[positive]
    weights[positive] = s if temperature is None else np.exp((s - s.max()) / temperature)
    return weights / weights.sum()


class ActionGroup:
    """A set of action-tuples competing for ``max_active`` activation slots.

    ``rng`` is the creature's numpy Generator (no global randomness); time comes in through
    :meth:`tick`. ``on_event`` receives plain dicts for the events log: ``selection`` (a
    tuple became active), ``interruption``, ``reselection`` (an interruption chose the
    running tuple again), ``stop`` and ``credit``. ``max_active`` > 1 lets several tuples be
    active at once (e.g. a non-exclusive group of perception actions). ``expectations``
    (:mod:`creatures.behaviour.expectation`) is told of every start and end before they
    happen, of every tick, and of every credit assignment (it may slow the confident).
    """

    def __init__(
        self,
        name: str,
        tuples: Iterable[ActionTuple] = (),
        *,
        rng: np.random.Generator,
        alpha: float = 0.1,
        discount: float = 0.8,
        multiple: float = 1.5,
        temperature: float | None = None,
        max_active: int = 1,
        on_event: EventSink | None = None,
        learning: Learner | None = None,
        grounded_by: str | None = None,
        expectations: "Expectations | None" = None,
        proximity: Proximity | None = None,
    ) -> None:
        if max_active < 1:
            raise ValueError(f"{name}: max_active must be at least 1 (got {max_active})")
        if temperature is not None and not temperature > 0:
            raise ValueError(f"{name}: temperature must be positive (got {temperature})")
        self.name = name
        self.rng = rng
        self.alpha = float(alpha)
        self.discount = float(discount)
        self.multiple = float(multiple)
        self.temperature = temperature
        self.max_active = int(max_active)
        self.on_event = on_event
        self.learning = learning
        self.grounded_by = grounded_by
        self.expectations = expectations  # surprise and confidence (creatures/behaviour/expectation.py)
        self._checked = False
        self.tuples: list[ActionTuple] = []
        self.active: list[ActionTuple] = []
        self.last_active: ActionTuple | None = None
        self.last_started_at: float | None = None  # when last_active became active
        self.last_tick: float | None = None
        self._base = np.zeros(0)
        self._interrupt_at = np.zeros(0)
        self._trigger_at_last_start = np.zeros(0)
        self.disabled: set[str] = set()  # tuples that cannot trigger (a zone of the room turned them off)
        self.proximities = proximity or Proximity()
        self._proximity: dict[ActionTuple, np.ndarray] = {}
        self._proximity_version = self.proximities.version
        self.on_credit: list[CreditHook] = []  # told of every rewarded leaf activation
        self.on_start: list[StartHook] = []  # told of every tuple that becomes active
        self._positions: dict[int, int] = {}
        self._ticking = False
        self._deferred: list[Callable[[], object]] = []
        self._percepts: list[Percept] = []
        self._percept_index = np.zeros(0, dtype=np.intp)
        self._shape: tuple[int, bytes] = (0, b"")
        self._leaf = np.zeros(0, dtype=bool)
        self.recent: list[Activation] = []  # activations that may still take a late reward
        for tuple_ in tuples:
            self.add(tuple_)
        if self.tuples:
            self.check_grounded()

    def check_grounded(self) -> None:
        """Refuse credit assignment with nothing to ground it (see the class docstring)."""
        self._checked = True
        if self.alpha > 0 and self.discount < 1 and self.grounded_by is None:
            if not any(grounds(tp.value) for tp in leaves(self.tuples)):
                raise ValueError(ungrounded_message(self.name, self.alpha, self.discount))

    # -- membership -------------------------------------------------------------------
    def add(self, tuple_: ActionTuple) -> ActionTuple:
        """Add a tuple (e.g. a new hypothesis); it takes no credit for the current transition.

        Called during a tick (by a learner), the change waits for the end of the tick so the
        arrays of this tick's selection stay aligned with the tuples.
        """
        if self._ticking:
            self._deferred.append(lambda: self.add(tuple_))
            return tuple_
        self.tuples.append(tuple_)
        self.record_base(np.append(self._base, 0.0))
        self._trigger_at_last_start = np.append(self._trigger_at_last_start, 0.0)
        for activation in self.recent:  # a newcomer takes no credit for what went before it
            activation.triggers = np.append(activation.triggers, 0.0)
        self._reindex()
        return tuple_

    def remove(self, tuple_: ActionTuple, t: float) -> None:
        """Drop a tuple (e.g. after percept fusion), stopping it first if active. One dropped
        already is left alone: within a tick, removals wait for its end, and two fusions in one
        tick (two tuples reviewed, each re-clustering the tree) may each ask for the same one."""
        if self._ticking:
            self._deferred.append(lambda: self.remove(tuple_, t))
            return
        if id(tuple_) not in self._positions:
            return
        if tuple_.active:  # dropped, not interrupted: no expectation of it was violated
            self._stop(tuple_, t, interrupted=True, judged=False)
        i = self._position(tuple_)
        del self.tuples[i]
        self.record_base(np.delete(self._base, i))
        self._trigger_at_last_start = np.delete(self._trigger_at_last_start, i)
        self.recent = [a for a in self.recent if a.tuple_ is not tuple_]
        for activation in self.recent:
            activation.triggers = np.delete(activation.triggers, i)
        if self.last_active is tuple_:
            self.last_active = None
        if self.expectations is not None:
            self.expectations.forget(tuple_)
        if all(tp.action.name != tuple_.action.name for tp in self.tuples):
            self.proximities.forget(tuple_.action.name)
        self._reindex()

    def find(self, name: str) -> ActionTuple:
        for tuple_ in self.tuples:
            if tuple_.name == name:
                return tuple_
        raise KeyError(f"no action-tuple named {name!r} in group {self.name!r}")

    def _position(self, tuple_: ActionTuple) -> int:
        return self._positions[id(tuple_)]

    def _reindex(self) -> None:
        self._positions = {id(tp): i for i, tp in enumerate(self.tuples)}
        index: dict[int, int] = {}
        self._percepts = []
        for tuple_ in self.tuples:
            if id(tuple_.trigger) not in index:
                index[id(tuple_.trigger)] = len(self._percepts)
                self._percepts.append(tuple_.trigger)
        self._percept_index = np.array([index[id(tp.trigger)] for tp in self.tuples], dtype=np.intp)
        self._shape = (len(self.tuples), self._percept_index.tobytes())  # groups alike for CrowdTick
        self._leaf = np.array([not isinstance(tp.action, GroupAction) for tp in self.tuples], dtype=bool)
        self._proximity.clear()

    # -- evaluation ---------------------------------------------------------------------
    def triggers(self, t: float) -> np.ndarray:
        """Every tuple's trigger saliency at ``t`` (each distinct percept evaluated once)."""
        saliency = np.fromiter((p.evaluate(t) for p in self._percepts), float, len(self._percepts))
        trig = saliency[self._percept_index]
        if self.disabled:  # a director's zone has switched some off (creatures/room/zones.py)
            trig *= np.fromiter((tp.name not in self.disabled for tp in self.tuples), float, len(self.tuples))
        return trig

    def values(self) -> np.ndarray:
        return np.fromiter((tp.value.to_float() for tp in self.tuples), float, len(self.tuples))

    @property
    def trigger_at_last_start(self) -> np.ndarray:
        """Every tuple's Tr saliency when the last active tuple became active (read-only)."""
        view = self._trigger_at_last_start.view()
        view.flags.writeable = False
        return view

    def leaf_values(self) -> np.ndarray:
        """Values of the leaf tuples only (group tuples excluded), e.g. for thresholds."""
        return self.values()[self._leaf]

    def expected_values(self, t: float) -> np.ndarray:
        """``Tr·V`` for inactive tuples and ``(1 − Du)·V`` for active ones, as one array."""
        return self._expected(t, self.triggers(t), self.values())

    def _expected(self, t: float, trig: np.ndarray, vals: np.ndarray) -> np.ndarray:
        expected = trig * vals
        for tuple_ in self.active:
            i = self._position(tuple_)
            expected[i] = (1.0 - tuple_.do_until.evaluate(t)) * vals[i]
        return expected

    # -- the selection loop -------------------------------------------------------------
    def tick(self, t: float, ready: "Ready | None" = None, *, choose: bool = True) -> None:
        """One step of the baseline mechanism: stop what is done, fill free slots or
        interrupt, then update whatever is active.

        ``choose`` False: a step between two of the soft state's (a creature's ``soft_rate``),
        whose triggers read soft state that has not stepped: what is running acts and stops
        when done (a freed slot is filled at once), but no trigger is asked and nothing
        interrupts until the next soft step (thesis "soft state").

        ``ready``: this step as :class:`CrowdTick` worked it out with a crowd's arrays, the
        evaluations it made not made again: True (the active tuple is done), False (nothing
        to do and nothing running acts each tick: the step only notes the time), or this
        tick's triggers, expected values and whether selection has work to do."""
        if ready is False:  # shares_tick held: no grounding to check, no gap, no expectations
            self.last_tick = t
            return
        if not self._checked:
            self.check_grounded()
        if self.last_tick is not None and clock_gap(self.last_tick, t) and self.active:
            for tuple_ in self.active:
                tuple_.do_until.span_gap()
            self._emit("gap", t, seconds=t - self.last_tick, spanned=[tp.name for tp in self.active])
        self.last_tick = t
        if self.expectations is not None:
            self.expectations.tick(t)
        self._ticking = True
        try:
            if ready is None:
                for tuple_ in list(self.active):
                    if tuple_.do_until.evaluate(t) >= 1.0:
                        self._stop(tuple_, t, interrupted=False)
                        choose = True
            elif ready is True:
                self._stop(self.active[0], t, interrupted=False)
            if not choose:
                for tuple_ in list(self.active):
                    tuple_.update(t)
            elif ready is None or ready is True:
                trig = self.triggers(t)
                self._decide(t, trig, self._expected(t, trig, self.values()))
            else:
                self._decide(t, *ready)
        finally:
            self._ticking = False
        while self._deferred:
            self._deferred.pop(0)()

    def _decide(self, t: float, trig: np.ndarray, expected: np.ndarray, wants: bool | None = None) -> None:
        """Fill a free slot or interrupt when selection has work (``wants``, else asked here of
        :meth:`idle` or :meth:`grown`), then update whatever is active."""
        free = len(self.active) < self.max_active
        if wants is None and free:
            wants = np.count_nonzero(self.idle(expected, self._active_mask())) > 0
        elif wants is None:
            weakest = min(expected[[self._position(tp) for tp in self.active]].tolist())  # in active order, as asked
            wants = np.count_nonzero(self.grown(expected, self._active_mask(), self._interrupt_at, weakest)) > 0
        if wants:
            if free:
                self._fill(t, trig, expected)
            else:
                self._reselect(t, trig, expected)
        for tuple_ in list(self.active):
            tuple_.update(t)

    @staticmethod
    def idle(expected: np.ndarray, active: np.ndarray) -> np.ndarray:
        """The tuples not running (``active`` false) that are worth starting (the last axis: a
        group's tuples): with a slot free, selection has work when there is one."""
        return (expected > 0.0) & ~active

    @staticmethod
    def grown(expected: np.ndarray, active: np.ndarray, interrupt_at: np.ndarray,
              weakest: np.ndarray | float) -> np.ndarray:
        """The tuples not running that have grown to their interruption threshold and to the
        ``weakest`` running tuple's expected value: with every slot taken, selection has work
        when there is one (:meth:`_reselect` chooses again)."""
        return ActionGroup.idle(expected, active) & (expected >= interrupt_at) & (expected >= weakest)

    def shares_tick(self, t: float) -> bool:
        """Whether :class:`CrowdTick` may work out this group's tick at ``t`` with others': at
        most one tuple active (several are stopped one after another, each stop before the
        next is asked), no clock gap to report, no expectations to tell, no zone switching
        tuples off, grounding checked."""
        return (self._checked and self.expectations is None and not self.disabled and len(self.active) <= 1
                and not (self.active and self.last_tick is not None and clock_gap(self.last_tick, t)))

    def _active_mask(self) -> np.ndarray:
        mask = np.zeros(len(self.tuples), dtype=bool)  # zeros: np.ones is a Python wrapper, several times slower
        for tuple_ in self.active:
            mask[self._position(tuple_)] = True
        return mask

    def _inactive_mask(self) -> np.ndarray:
        return ~self._active_mask()

    def record_base(self, expected: np.ndarray) -> None:
        """Remember every tuple's expected value at a selection, and from it the interruption
        thresholds: ``multiple`` × a positive base value, the base itself otherwise."""
        self._base = np.array(expected, dtype=float)
        self._interrupt_at = np.where(self._base > 0.0, self.multiple * self._base, self._base)

    def _choose(self, expected: np.ndarray, allowed: np.ndarray) -> int | None:
        p = selection_probabilities(np.where(allowed, expected, 0.0), self.temperature)
        if p is None:
            return None
        i = int(np.searchsorted(np.cumsum(p), self.rng.random() * p.sum(), side="right"))
        return min(i, len(p) - 1)

    def _fill(self, t: float, trig: np.ndarray, expected: np.ndarray) -> None:
        while len(self.active) < self.max_active:
            i = self._choose(expected, self._inactive_mask())
            if i is None:
                return
            self.record_base(expected)
            self._start(self.tuples[i], t, trig)

    def _reselect(self, t: float, trig: np.ndarray, expected: np.ndarray) -> None:
        weakest = min(self.active, key=lambda tp: expected[self._position(tp)])
        allowed = self._inactive_mask()
        allowed[self._position(weakest)] = True
        i = self._choose(expected, allowed)
        if i is None or self.tuples[i] is weakest:
            self.record_base(expected)
            self._emit("reselection", t, tuple=weakest.name)  # the interruption confirmed it
            return
        self.record_base(self._as_candidate(expected, trig, weakest))
        self._emit("interruption", t, tuple=weakest.name, by=self.tuples[i].name)
        self._stop(weakest, t, interrupted=True)
        self._start(self.tuples[i], t, trig)

    def _as_candidate(self, expected: np.ndarray, trig: np.ndarray, stopped: ActionTuple) -> np.ndarray:
        """``expected`` with the tuple being stopped counted as a candidate again (Tr·V), when
        that is more than what was left of it: its base value for the next interruption.

        A graded Du (thesis "computing expected values") leaves a running tuple worth
        little near its end; a base recorded from that would let it interrupt its successor
        in the next tick, having "grown" only back to its own value, and the creature would
        dither. With a stepped Du the running tuple's (1 − Du)·V = V is already the larger."""
        i = self._position(stopped)
        candidate = float(trig[i]) * stopped.value.to_float()
        if candidate <= expected[i]:
            return expected
        out = expected.copy()
        out[i] = candidate
        return out

    def _start(self, tuple_: ActionTuple, t: float, trig: np.ndarray) -> None:
        # The leaf that ran last, read before the start: a group tuple starting again chooses
        # its new child as it starts, and the transition to credit is from the child it ran.
        previous = None if self.last_active is None else leaf_of(self.last_active)
        if self.expectations is not None:
            self.expectations.starting(self, previous, tuple_, t)
        tuple_.start(t, self.rng, group=self)
        self.active.append(tuple_)
        self._emit("selection", t, tuple=tuple_.name, value=tuple_.value.to_float())
        for hook in self.on_start:
            hook(self, t, tuple_)
        if previous is not None:  # a tuple restarting after it finished counts too
            self.assign_credit(t, previous, tuple_)
        self.last_active = tuple_
        self.last_started_at = t
        self._trigger_at_last_start = trig.copy()
        self.recent = [a for a in self.recent if a.ended is None or a.ended >= t - RECALL]
        self.recent.append(Activation(tuple_, t, self._trigger_at_last_start))

    def _stop(self, tuple_: ActionTuple, t: float, *, interrupted: bool, judged: bool = True) -> None:
        if self.expectations is not None and judged:
            self.expectations.ended(self, tuple_, t, interrupted=interrupted)
        duration = tuple_.stop(t, interrupted=interrupted)
        self.active.remove(tuple_)
        for activation in reversed(self.recent):
            if activation.tuple_ is tuple_ and activation.ended is None:
                activation.ended = t
                break
        self._emit("stop", t, tuple=tuple_.name, duration=duration, interrupted=interrupted)

    def force(self, name: str, t: float) -> ActionTuple:
        """Start tuple ``name`` at ``t`` whatever its expected value: an operator's choice
        (the remote console's ``trigger``), not the group's. The weakest active tuple makes
        room when every slot is taken (logged as an ``interruption``); the start is logged
        as a ``selection`` and assigns credit as any start does. Between ticks only."""
        tuple_ = self.find(name)
        if tuple_ in self.active:
            return tuple_
        trig = self.triggers(t)
        expected = self._expected(t, trig, self.values())
        if len(self.active) >= self.max_active:
            weakest = min(self.active, key=lambda tp: expected[self._position(tp)])
            self._emit("interruption", t, tuple=weakest.name, by=name)
            self._stop(weakest, t, interrupted=True)
            expected = self._as_candidate(expected, trig, weakest)
        self.record_base(expected)
        self._start(tuple_, t, trig)
        return tuple_

    def stop_all(self, t: float) -> None:
        """Stop every active tuple (the group itself is being deactivated). One whose Du says
        done ends as done, not interrupted: its end is what ended the group tuple (thesis
        "hierarchical action-groups": the Du of the action selected within percolates
        upward), and a phrase ended on its plan still hands over its last notes."""
        for tuple_ in list(self.active):
            self._stop(tuple_, t, interrupted=tuple_.do_until.evaluate(t) < 1.0)

    # -- credit assignment ------------------------------------------------------------
    def proximity(self, leaf: ActionTuple) -> np.ndarray:
        """How much of ``leaf``'s credit reaches each tuple (0 for group tuples): the group's
        :class:`~creatures.behaviour.proximity.Proximity` table, cached per leaf until it changes."""
        if self._proximity_version != self.proximities.version:
            self._proximity.clear()
            self._proximity_version = self.proximities.version
        row = self._proximity.get(leaf)
        if row is None:
            row = np.array([self.proximities.between(leaf.action, tp.action) if is_leaf else 0.0
                            for tp, is_leaf in zip(self.tuples, self._leaf)])
            self._proximity[leaf] = row
        return row

    def assign_credit(self, t: float, last: ActionTuple, new: ActionTuple) -> np.ndarray:
        """Blend every leaf toward ``β·V_n``; returns the blend parameters ``a_i`` used."""
        last_leaf, new_leaf = leaf_of(last), leaf_of(new)
        target = discounted(new_leaf.value, self.discount)
        a = np.clip(self.alpha * self.proximity(last_leaf) * self._trigger_at_last_start, 0.0, 1.0)
        if self.expectations is not None:
            a = self.expectations.credit_rates(self, t, last_leaf, target, a)
        before = self.values() if self.learning is not None else None
        raised = target.to_float() > last_leaf.value.to_float()  # what followed was worth more: a reward
        for i in np.flatnonzero(a):
            self.tuples[i].value.blend_to(target, float(a[i]))
        self._emit(
            "credit", t, last=last_leaf.name, new=new_leaf.name, target=target.to_float(),
            blended={self.tuples[i].name: float(a[i]) for i in np.flatnonzero(a)},
        )
        if self.learning is not None:
            self.learning.after_credit(self, t, last_leaf, a, target, before)
        if raised:
            self._credited(t, [x for x in self.recent if x.tuple_ is last_leaf][-1:])
        return a

    def _credited(self, t: float, activations: list[Activation]) -> None:
        """These leaf activations were rewarded (what followed was worth more than the tuple,
        or a reward from outside reached them): teach the proximity table what preceded
        them, then tell the hooks."""
        for activation in activations:
            self.proximities.credited(activation.tuple_, self.tuples, self.recent, activation.started)
            for hook in self.on_credit:
                hook(self, t, activation)

    def reward(self, amount: float, t: float, window: float, *,
               rate: float | None = None) -> tuple[list[str], dict[str, float]]:
        """A reward from outside at ``t`` (the clicker): every tuple active at some time in
        the last ``window`` seconds — active now, or ended since ``t − window`` — is credited
        as if ``amount`` of value had followed it (thesis: clicker training, "credit
        assignment"), so a visitor's late click still lands on what they saw.

        Credit reaches what that activation's credit assignment reaches: each leaf ``i`` moves
        by ``a_i·amount`` (``V_i ← V_i + a_i·amount``, through ``blend_to`` so plasticity
        scales it), ``a_i = rate·proximity(credited, i)·Tr_i`` with ``Tr_i`` read when the
        credited tuple began, and the largest ``a_i`` of all credited activations. ``rate``
        is the group's α unless given: an authored group that keeps its values (α = 0, no
        reward inside it to ground them) is still trained by a reward from outside. A group
        tuple passes the reward to its own group. Returns the credited tuples' names and ``{tuple name: a_i}``
        of every value moved."""
        window = min(max(window, 0.0), RECALL)
        rate = self.alpha if rate is None else rate
        credited = [a for a in self.recent if a.started <= t and (a.ended is None or a.ended >= t - window)]
        names, moved = [c.tuple_.name for c in credited], {}
        a = np.zeros(len(self.tuples))
        leaves: list[Activation] = []
        for activation in credited:
            tuple_ = activation.tuple_
            if isinstance(tuple_.action, GroupAction):
                inner, inner_moved = tuple_.action.group.reward(amount, t, window, rate=rate)
                names += inner
                moved.update(inner_moved)
            elif id(tuple_) in self._positions:
                np.maximum(a, np.clip(rate * self.proximity(tuple_) * activation.triggers, 0.0, 1.0), out=a)
                leaves.append(activation)
        for i in np.flatnonzero(a):
            value = self.tuples[i].value
            target = value.to_dict()
            target["value"] += amount
            value.blend_to(value_from_dict(target), float(a[i]))
            moved[self.tuples[i].name] = float(a[i])
        if amount > 0.0:
            self._credited(t, leaves)
        return names, moved

    # -- persistence ----------------------------------------------------------------------
    def activation_state(self) -> dict[str, Any]:
        """What selection needs to continue exactly after a reload: who is active, the base
        values of the last selection, the triggers when the last active tuple started.
        Arrays are returned as numpy arrays (the creature stores them in its NPZ)."""
        return {
            "active": [tp.name for tp in self.active],
            "last_active": None if self.last_active is None else self.last_active.name,
            "last_started_at": self.last_started_at,
            "last_tick": self.last_tick,
            "alpha": self.alpha,
            "base": self._base.copy(),
            "trigger_at_last_start": self._trigger_at_last_start.copy(),
        }

    def restore_activation(self, state: dict[str, Any], order: list[str]) -> None:
        """Take back :meth:`activation_state`, with the tuples put in the saved ``order``."""
        position = {name: k for k, name in enumerate(order)}
        unsaved = sorted({tp.name for tp in self.tuples} - position.keys())
        if unsaved or len(position) != len(self.tuples):
            raise ValueError(f"group {self.name!r}: tuples {unsaved or order} do not match the saved tuples")
        self.tuples.sort(key=lambda tp: position[tp.name])
        self._reindex()
        base, trig = np.asarray(state["base"], float), np.asarray(state["trigger_at_last_start"], float)
        if base.shape != (len(self.tuples),) or trig.shape != (len(self.tuples),):
            raise ValueError(f"group {self.name!r}: saved arrays do not match its {len(self.tuples)} tuples")
        self.record_base(base)
        self._trigger_at_last_start = trig
        self.alpha = float(state["alpha"])
        self.active = [self.find(name) for name in state["active"]]
        self.last_active = None if state["last_active"] is None else self.find(state["last_active"])
        self.last_started_at = state["last_started_at"]
        self.last_tick = state["last_tick"]

    # -- what lasts across runs --------------------------------------------------------------
    def value_state(self) -> dict[str, dict[str, Any]]:
        """Every tuple's learned value, by tuple name (JSON-able)."""
        return {tp.name: tp.value.to_dict() for tp in self.tuples}

    def restore_values(self, saved: dict[str, dict[str, Any]]) -> None:
        """Take back values saved by :meth:`value_state` (a reward stays the config's, see
        :func:`restored`); tuples not saved keep theirs, and a saved value no tuple is named for
        is the caller's to keep (creatures/behaviour/unplaced.py)."""
        for tp in self.tuples:
            if tp.name in saved:
                tp.value = restored(tp.value, reattach(value_from_dict(saved[tp.name]), tp.value))

    def _emit(self, event: str, t: float, **fields: Any) -> None:
        if self.on_event is not None:
            self.on_event({"event": event, "t": t, "group": self.name, **fields})

    def __repr__(self) -> str:
        return f"ActionGroup({self.name!r}, {len(self.tuples)} tuples, active={[tp.name for tp in self.active]})"


class CrowdTick:
    """One tick of many action-groups (a crowd's creatures, each its own group), the
    arithmetic of selection done as arrays across them.

    Each group's Du of its active tuple, its triggers (percept by percept down the crowd),
    values and Du again (unless a second evaluation must give the first's answer:
    :attr:`DoUntil.settled`) are evaluated once, in the order its own tick would evaluate
    them; the expected values and whether selection has work (:meth:`ActionGroup.idle`,
    :meth:`ActionGroup.grown`) are arrays over every group of one shape (same tuples, same
    triggers). A group then
    finishes its tick in the crowd's order with :meth:`finish` (an ordinary tick given what
    was worked out), so every start, stop, note and event happens as the groups one by one
    would have made them. A group that may not share (:meth:`ActionGroup.shares_tick`)
    ticks on its own in its turn. What a percept of one creature reads must not be what
    another creature's tick changes (their triggers are read before the others finish).
    """

    def __init__(self, groups: list[ActionGroup], t: float) -> None:
        self.t = t
        self.ready: list[Ready | None] = [None] * len(groups)
        shapes: dict[tuple[int, bytes], list[tuple[int, float | None]]] = {}
        for k, group in enumerate(groups):
            if not group.shares_tick(t):
                continue
            done = None  # the active tuple's Du, when asking again now would give it
            if group.active:
                du = group.active[0].do_until
                settled = du.settled
                done = du.evaluate(t)
                if done >= 1.0:
                    self.ready[k] = True
                    continue
                if not settled:
                    done = None
            shapes.setdefault(group._shape, []).append((k, done))
        for members in shapes.values():
            self._work_out([groups[k] for k, _ in members], members)

    def _work_out(self, groups: list[ActionGroup], members: list[tuple[int, float | None]]) -> None:
        """Triggers, values, expected values and selection's work of groups of one shape."""
        t, n, first = self.t, len(groups), groups[0]
        saliency = np.empty((n, len(first._percepts)))
        for p in range(len(first._percepts)):
            saliency[:, p] = [group._percepts[p].evaluate(t) for group in groups]
        trig = saliency[:, first._percept_index]
        values = np.array([tp.value.to_float() for group in groups for tp in group.tuples]).reshape(n, -1)
        expected = trig * values
        rows, at, done = [], [], []
        for r, (group, (_, du)) in enumerate(zip(groups, members)):
            if group.active:
                rows.append(r)
                at.append(group._position(group.active[0]))
                done.append(group.active[0].do_until.evaluate(t) if du is None else du)
        expected[rows, at] = (1.0 - np.array(done, dtype=float)) * values[rows, at]
        active = np.zeros(expected.shape, dtype=bool)
        active[rows, at] = True
        weakest = np.zeros((n, 1))
        weakest[rows, 0] = expected[rows, at]
        free = np.array([len(group.active) < group.max_active for group in groups])
        interrupt_at = np.concatenate([group._interrupt_at for group in groups]).reshape(n, -1)
        wants = np.where(free, ActionGroup.idle(expected, active).any(axis=1),
                         ActionGroup.grown(expected, active, interrupt_at, weakest).any(axis=1)).tolist()
        for r, ((k, _), group) in enumerate(zip(members, groups)):
            acts = group.active and type(group.active[0].action).update is not Action.update
            # False: nothing to do, and nothing running acts each tick
            self.ready[k] = (trig[r], expected[r], wants[r]) if wants[r] or acts else False

    def finish(self, group: ActionGroup, k: int) -> None:
        """Group ``k`` (in the order given) ticks, from what was worked out for it."""
        group.tick(self.t, self.ready[k])


# -- hierarchical action-groups ------------------------------------------------------------
class GroupAction(Action):
    """Ac of a tuple that *is* an action-group: while active it runs selection among its
    children (thesis: "we can dress an action-group ... up as an action-tuple itself")."""

    def __init__(self, group: ActionGroup) -> None:
        super().__init__(group.name)
        self.group = group

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.group.tick(t)

    def update(self, t: float) -> None:
        if self.group.last_tick != t:  # already ticked by start() at this instant
            self.group.tick(t)

    def stop(self, t: float, *, interrupted: bool) -> None:
        self.group.stop_all(t)


class ActiveChildDone(Percept):
    """Du of a group tuple: the active child's Du percolates upward; with no active child
    (nothing worth doing inside) the group is done."""

    def __init__(self, group: ActionGroup) -> None:
        super().__init__(f"{group.name}:done")
        self.group = group

    def evaluate(self, t: float) -> float:
        if not self.group.active:
            return 1.0
        return min(tp.do_until.evaluate(t) for tp in self.group.active)


def group_tuple(
    group: ActionGroup, trigger: Percept, value: Value | float, *, duration: float | None = None
) -> ActionTuple:
    """Wrap ``group`` as ``trigger | group | until its active child is done | value``."""
    return ActionTuple(group.name, trigger, GroupAction(group), DoUntil(duration, until=ActiveChildDone(group)), value)


def leaf_of(tuple_: ActionTuple) -> ActionTuple:
    """The leaf tuple actually doing the work under ``tuple_`` (itself if it is a leaf)."""
    while isinstance(tuple_.action, GroupAction) and tuple_.action.group.last_active is not None:
        tuple_ = tuple_.action.group.last_active
    return tuple_
