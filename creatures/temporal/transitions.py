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
B") that is refined on its own. The succession tries that fission itself each time it
records a valued transition (see :class:`Succession`, ``innovation``), so a group grows
its sub-hypotheses as it plays; :func:`fission` can also be called by hand.

Everything goes through the public life cycle (``DoUntil.begin``) and percepts, so an
:class:`~creatures.behaviour.action_group.ActionGroup` needs no hook: wrap the tuples with
:func:`follow` before adding them; a fissioned tuple joins the group that started the
tuple whose transition grounded it (``group.add``, deferred to the end of the tick). (A
group that re-took its interruption base values just after each start would let the
priming switch to the new tuple's successors at once; see :class:`Succession` for why it
waits.)
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

    **Shared by a colony.** The thesis keeps these models "privately (local only to a
    particular action-tuple) or ... shared between a group of action-tuples"; a succession
    may also be shared by the groups of several creatures (``World.successions``, named by a
    group's ``succession`` key), so the colony learns one "what usually happens next". Each
    group is a *stream* of its own: a transition is recorded from the group's own last start
    and its candidates are primed by it (everything above, per stream), so three creatures
    playing at once teach the model three clean successions, not the interleaving of their
    parts, and a listener's perception group teaches it the visitor's. Tuples record under
    a *label* (their name by default): a perception tuple hearing phrase ``a`` and the
    tuples playing ``a`` all say ``a``, so what is heard shapes what is played. Fission is
    for a group's own succession (its sub-hypothesis joins that group): a shared one is made
    with ``innovation=None``. A stream may also only *follow* without recording
    (``record=False``): its tuples are primed by what usually follows their own last start
    but teach the model nothing. A colony that learns its order from the visitors it hears
    is built so: in ten minutes of a visitor keeping one order, three creatures teaching
    the model their own choices as well (a window of ten transitions a row, mostly theirs)
    let it drift from the visitor's order back to chance (phrase entropy 0.9 → 1.5 bits);
    primed but not teaching, they walk the order the visitor keeps.

    **Fission.** After recording a valued transition out of a tuple, the succession tries
    :func:`fission` on it with ``innovation`` as the value gap: the best successor's
    transitions must carry at least ``innovation`` more value than the tuple's transitions
    on average (besides the correlation-ratio and count tests of :func:`fission`). The gap
    is what makes the divergence matter: η² alone is scale-free, and two successors whose
    values differ by a few hundredths would explain all of a tiny spread. ``None`` leaves
    fission to the author. ``fissioned`` maps each sub-hypothesis made here to the
    successor it leads to; a sub-hypothesis is not split again and is no successor to split
    towards (see :func:`fission`), so a group of N followed tuples grows at most N² of them
    however long it plays.
    """

    def __init__(
        self,
        model: TransitionModel | None = None,
        *,
        window: int = 10,
        alpha: float = 0.1,
        innovation: float | None = 0.25,
    ) -> None:
        if innovation is not None and not innovation >= 0.0:
            raise ValueError(f"innovation is a value gap, ≥ 0 or None (got {innovation!r})")
        self.model = model if model is not None else TransitionModel(window=window, alpha=alpha)
        self.innovation = innovation
        self.tuples: dict[str, ActionTuple] = {}
        self.fissioned: dict[str, str] = {}
        # Per stream (a group; None for a succession of one group): [previous, current, the
        # tuple that started last].
        self._streams: dict[str | None, list] = {}

    @property
    def current(self) -> str | None:
        """The label that started last (in the default stream)."""
        return self._streams.get(None, [None, None, None])[1]

    @property
    def previous(self) -> str | None:
        """The label ``current`` followed (in the default stream)."""
        return self._streams.get(None, [None, None, None])[0]

    def join(self, tuple_: ActionTuple, label: str | None = None) -> None:
        label = tuple_.name if label is None else label
        self.tuples[label] = tuple_
        self.model.add(label)

    def observe(self, tuple_: ActionTuple, label: str | None = None, stream: str | None = None, *,
                record: bool = True) -> ActionTuple | None:
        """``tuple_`` became active in ``stream`` (as ``label``, its name by default),
        carrying its value: record the stream's current → label (unless not ``record``), and
        return the sub-hypothesis that transition grounded, if any (see the class notes)."""
        name = tuple_.name if label is None else label
        state = self._streams.setdefault(stream, [None, None, None])
        source = state[1]
        state[:] = [source, name, tuple_]
        if source is None or not record:
            return None
        self.model.record(source, name, tuple_.value.to_float())
        tuple_ = self.tuples.get(source)
        if self.innovation is None or tuple_ is None or not isinstance(tuple_.trigger, LikelySuccessor):
            return None
        return fission(tuple_, self, min_gap=self.innovation)

    def source(self, t: float, stream: str | None = None) -> str | None:
        """The label a candidate of ``stream`` starting at ``t`` would follow (see the class notes)."""
        previous, current, started = self._streams.get(stream, [None, None, None])
        if started is None or not started.active or started.do_until.evaluate(t) >= 1.0:
            return current
        return previous

    def likelihood(self, name: str, t: float, stream: str | None = None) -> float:
        """N·p(source → name): 1 for a chance successor (or with no history), >1 for a likely one."""
        source = self.source(t, stream)
        if source is None:
            return 1.0
        return len(self.model.names) * self.model.probability(source, name)


class TransitionDoUntil(WrappedDoUntil):
    """Du of ``tuple_`` that records each of its activations in the shared succession, as
    ``label`` (its name by default), in ``stream`` (see :class:`Succession`); with ``record``
    false it only keeps the stream's place (what its candidates are primed by)."""

    def __init__(self, inner: DoUntil, tuple_: ActionTuple, succession: Succession, label: str | None = None,
                 stream: str | None = None, record: bool = True) -> None:
        super().__init__(inner)
        self.tuple = tuple_
        self.succession = succession
        self.label = tuple_.name if label is None else label
        self.stream = stream
        self.record = record
        succession.join(tuple_, self.label)

    def expected(self, t: float) -> float:
        """How expected a start of the tuple at ``t`` is, before :meth:`begin` records it:
        N·p(source → it), 1 for a chance successor (or with no history), below 1 for one less
        likely than chance (thesis "expectations about the consequences of actions": with
        forward transition models, "surprise can be the result of a character being able to
        perform an unexpected action")."""
        return self.succession.likelihood(self.label, t, self.stream)

    def begin(self, t: float, rng: np.random.Generator) -> None:
        child = self.succession.observe(self.tuple, self.label, self.stream, record=self.record)
        group = self.tuple.context.get("group")  # the group that is starting this tuple
        if child is not None and group is not None:
            group.add(child)
        super().begin(t, rng)


class LikelySuccessor(Percept):
    """Tr: the tuple's own trigger × (how likely it follows the source tuple)^strength.

    ``strength`` 0 ignores the model; 1 weighs candidates by the transition probability
    itself (relative to chance), which is how "what usually happens next" primes selection.
    """

    def __init__(self, trigger: Percept, name: str, succession: Succession, *, strength: float = 1.0,
                 stream: str | None = None) -> None:
        if not strength >= 0.0:
            raise ValueError(f"strength must be non-negative (got {strength!r})")
        super().__init__(f"{trigger.name} · likely after last")
        self.trigger = trigger
        self.tuple_name = name
        self.succession = succession
        self.strength = float(strength)
        self.stream = stream

    def evaluate(self, t: float) -> float:
        likely = self.succession.likelihood(self.tuple_name, t, self.stream)
        return self.trigger.evaluate(t) * likely**self.strength


def follow(tuple_: ActionTuple, succession: Succession, *, strength: float = 1.0,
           label: str | None = None, stream: str | None = None, record: bool = True) -> ActionTuple:
    """Give ``tuple_`` a transition-modelling Du and a trigger primed by likely transitions,
    recorded (unless not ``record``) and primed as ``label`` (its name by default) in
    ``stream`` (its group's, when several groups share the succession; see
    :class:`Succession`).

    Apply before adding the tuple to its group (a group indexes triggers when tuples join).
    """
    tuple_.do_until = TransitionDoUntil(tuple_.do_until, tuple_, succession, label, stream, record)
    tuple_.trigger = LikelySuccessor(tuple_.trigger, tuple_.do_until.label, succession, strength=strength,
                                     stream=stream)
    return tuple_


def fission(
    tuple_: ActionTuple,
    succession: Succession,
    *,
    min_contrast: float = 0.5,
    min_count: int = 3,
    min_gap: float = 0.0,
) -> ActionTuple | None:
    """Split off "``tuple_``, leading to its most valuable successor" when it pays.

    It pays when the successor explains at least ``min_contrast`` of the spread of values
    credited on transitions out of the tuple (the model's correlation ratio η²), the best
    successor has been seen ``min_count`` times, and its transitions carry at least
    ``min_gap`` more value than the tuple's transitions on average. The new tuple A' shares
    A's action, trigger and duration model (a fresh Du around the same model), starts with the mean value of the
    A → B transitions, and inherits as many A' → B transitions (at that mean value) — so it
    tends to lead to B, while A stays the general hypothesis. Returns None when no split is
    warranted, A' exists, or A is itself a sub-hypothesis. A' is
    wrapped in :func:`follow` already; add it to the group with ``group.add``. (Its Du is a
    plain one: interval constraints on A are not copied.)

    **One level.** Only the tuples the group was given split, and only towards one of them:
    a sub-hypothesis is neither split again nor a successor to split towards. The thesis
    ("forward transition models", figure 10, step 5) splits A to "explore and refine
    versions of action-tuple A that lead to B separately from those which tend to lead to
    C": the children are versions of A, told apart by the successor. A→B followed best by C
    is a version of A that leads to C, which the sibling A→C already is, and a version of A
    leading to "B→C" is one leading to a version of B; splitting either way named a new
    tuple from a name that grew each time ("A→B→C→B→…"), so a group whose valuable
    successor kept changing grew tuples without bound (4 followed tuples, a new valuable
    one every 100 starts: 51 tuples, 19 deep after 20,000 starts, still growing). Split
    once per pair, a group of N tuples holds at most N + N² however long it plays.
    """
    if not isinstance(tuple_.do_until, TransitionDoUntil) or not isinstance(tuple_.trigger, LikelySuccessor):
        raise ValueError(f"{tuple_.name!r} does not model transitions: wrap it with follow() first")
    # The model knows a tuple by its label (``follow_as``; its name by default): by its name a
    # labelled tuple was "no tuple named" there, a KeyError that ended the run.
    model, name = succession.model, tuple_.do_until.label
    if name in succession.fissioned or model.value_contrast(name) < min_contrast:
        return None
    stats = {j: model.value_stats(name, j) for j in model.names}
    seen = {j: mean for j, (count, mean, _) in stats.items()
            if count >= min_count and not math.isnan(mean) and j not in succession.fissioned}
    if not seen:
        return None
    valued = [(count, mean) for count, mean, _ in stats.values() if count > 0]
    overall = sum(count * mean for count, mean in valued) / sum(count for count, _ in valued)
    best = max(seen, key=seen.__getitem__)
    child_label = f"{name}→{best}"
    if seen[best] - overall < min_gap or child_label in model.names:
        return None
    inner = tuple_.do_until.inner
    child = ActionTuple(
        f"{tuple_.name}→{best}",
        tuple_.trigger.trigger,
        tuple_.action,
        DoUntil(inner.duration, until=inner.until, learn=inner.learn),
        ScalarValue(seen[best]),
    )
    follow(child, succession, strength=tuple_.trigger.strength, label=child_label)
    succession.fissioned[child_label] = best
    for _ in range(stats[best][0]):
        model.record(child_label, best, seen[best])
    return child
