"""Do-untils with forward transition models (thesis: "temporal models – forward transition
models", figure 10; "Du percepts equipped with forward transition models ... can simulate
and learn priming effects").

A Du is where a tuple learns *what usually happens next*: each activation records the
transition from the previously active tuple (with the value the newcomer carried) in a
:class:`~creatures.behaviour.models.transition.TransitionModel` shared by the tuples of one
group. The model then perturbs selection — a candidate's trigger is scaled by how likely
it is to follow what was just active, lowering the bar for likely successors and raising it
for unlikely ones — and, when the transitions out of a tuple carry different values
(A → B valuable, A → C not), it grounds a *fission*: a sub-hypothesis A' ("A, leading to
B") that is refined on its own.

Everything goes through the public life cycle (``DoUntil.begin``) and percepts, so an
:class:`~creatures.behaviour.action_group.ActionGroup` needs no hook: wrap the tuples with
:func:`follow` before adding them, and add a fissioned tuple with ``group.add``. (A group
that re-took its interruption base values just after each start would let the priming
switch to the new tuple's successors at once; see :class:`Succession` for why it waits.)
"""

from __future__ import annotations

import math

import numpy as np

from creatures.behaviour.action_tuple import ActionTuple, DoUntil
from creatures.behaviour.models.transition import TransitionModel
from creatures.behaviour.percept import Percept
from creatures.behaviour.value import ScalarValue
from creatures.temporal.du import WrappedDoUntil


class Succession:
    """One group's forward transition model and where its tuples are in the succession.

    ``current`` is the tuple that started last and ``previous`` the one it followed. The
    *source* a candidate is primed by — "what would I be following if I started now" — is
    ``current`` once it has ended or is ending, and ``previous`` while it is still going.
    Why not ``current`` at once: a group keeps each tuple's expected value at the moment of
    selection as the base for interruptions, and those were taken under the previous
    source's priming; switching the priming the instant a tuple starts reads to the group as
    a sudden growth of every unlikely candidate, which then interrupts at once.

    One succession serves one group; with several active slots, ``current`` is simply the
    latest start.
    """

    def __init__(self, model: TransitionModel | None = None, *, window: int = 10, alpha: float = 0.1) -> None:
        self.model = model if model is not None else TransitionModel(window=window, alpha=alpha)
        self.tuples: dict[str, ActionTuple] = {}
        self.current: str | None = None
        self.previous: str | None = None

    def join(self, tuple_: ActionTuple) -> None:
        self.tuples[tuple_.name] = tuple_
        self.model.add(tuple_.name)

    def observe(self, name: str, value: float) -> None:
        """``name`` became active carrying ``value``: record current → name."""
        if self.current is not None:
            self.model.record(self.current, name, value)
        self.previous, self.current = self.current, name

    def source(self, t: float) -> str | None:
        """The tuple a candidate starting at ``t`` would follow (see the class notes)."""
        current = self.tuples.get(self.current) if self.current is not None else None
        if current is None or not current.active or current.do_until.evaluate(t) >= 1.0:
            return self.current
        return self.previous

    def likelihood(self, name: str, t: float) -> float:
        """N·p(source → name): 1 for a chance successor (or with no history), >1 for a likely one."""
        source = self.source(t)
        if source is None:
            return 1.0
        return len(self.model.names) * self.model.probability(source, name)


class TransitionDoUntil(WrappedDoUntil):
    """Du of ``tuple_`` that records each of its activations in the shared succession."""

    def __init__(self, inner: DoUntil, tuple_: ActionTuple, succession: Succession) -> None:
        super().__init__(inner)
        self.tuple = tuple_
        self.succession = succession
        succession.join(tuple_)

    def begin(self, t: float, rng: np.random.Generator) -> None:
        self.succession.observe(self.tuple.name, self.tuple.value.to_float())
        super().begin(t, rng)


class LikelySuccessor(Percept):
    """Tr: the tuple's own trigger × (how likely it follows the source tuple)^strength.

    ``strength`` 0 ignores the model; 1 weighs candidates by the transition probability
    itself (relative to chance), which is how "what usually happens next" primes selection.
    """

    def __init__(self, trigger: Percept, name: str, succession: Succession, *, strength: float = 1.0) -> None:
        if not strength >= 0.0:
            raise ValueError(f"strength must be non-negative (got {strength!r})")
        super().__init__(f"{trigger.name} · likely after last")
        self.trigger = trigger
        self.tuple_name = name
        self.succession = succession
        self.strength = float(strength)

    def evaluate(self, t: float) -> float:
        return self.trigger.evaluate(t) * self.succession.likelihood(self.tuple_name, t) ** self.strength


def follow(tuple_: ActionTuple, succession: Succession, *, strength: float = 1.0) -> ActionTuple:
    """Give ``tuple_`` a transition-modelling Du and a trigger primed by likely transitions.

    Apply before adding the tuple to its group (a group indexes triggers when tuples join).
    """
    tuple_.do_until = TransitionDoUntil(tuple_.do_until, tuple_, succession)
    tuple_.trigger = LikelySuccessor(tuple_.trigger, tuple_.name, succession, strength=strength)
    return tuple_


def fission(
    tuple_: ActionTuple,
    succession: Succession,
    *,
    min_contrast: float = 0.5,
    min_count: int = 3,
) -> ActionTuple | None:
    """Split off "``tuple_``, leading to its most valuable successor" when it pays.

    It pays when the successor explains at least ``min_contrast`` of the spread of values
    credited on transitions out of the tuple (the model's correlation ratio η²) and the best
    successor has been seen ``min_count`` times. The new tuple A' shares A's action, trigger
    and duration model (a fresh Du around the same model), starts with the mean value of the
    A → B transitions, and inherits as many A' → B transitions (at that mean value) — so it
    tends to lead to B, while A stays the general hypothesis. Returns None when no split is
    warranted or A' exists. A' is wrapped in :func:`follow` already; add it to the group with
    ``group.add``. (Its Du is a plain one: interval constraints on A are not copied.)
    """
    if not isinstance(tuple_.do_until, TransitionDoUntil) or not isinstance(tuple_.trigger, LikelySuccessor):
        raise ValueError(f"{tuple_.name!r} does not model transitions: wrap it with follow() first")
    model, name = succession.model, tuple_.name
    if model.value_contrast(name) < min_contrast:
        return None
    stats = {j: model.value_stats(name, j) for j in model.names}
    seen = {j: mean for j, (count, mean, _) in stats.items() if count >= min_count and not math.isnan(mean)}
    if not seen:
        return None
    best = max(seen, key=seen.__getitem__)
    child_name = f"{name}→{best}"
    if child_name in model.names:
        return None
    inner = tuple_.do_until.inner
    child = ActionTuple(
        child_name,
        tuple_.trigger.trigger,
        tuple_.action,
        DoUntil(inner.duration, until=inner.until, learn=inner.learn),
        ScalarValue(seen[best]),
    )
    follow(child, succession, strength=tuple_.trigger.strength)
    for _ in range(stats[best][0]):
        model.record(child_name, best, seen[best])
    return child
