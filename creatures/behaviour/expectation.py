"""Expectations of action-tuples: surprise and confidence (thesis: "expectations about
value", "expectations about the consequences of actions", "surprise/confidence").

An action-tuple carries two expectations. Its Du describes the state of the world when the
action should finish, so the end is an expectation; the thesis reads it as an unnormalised
likelihood p ∝ 1 − Du.evaluate(end) of the end being *out of the ordinary* ("at the very
least characters can get surprised when they are interrupted"). Here:

- an **interruption** is judged on the whole Du: p = 1 − Du.evaluate(end). With a graded Du
  an interruption near the planned end is barely a violation, one just after the start is
  nearly a full one;
- a **natural end** is judged on the part of Du that did not end it (a Du of a duration and
  an until-percept expects both to agree): ended by the until-percept before the plan,
  p = 1 − timing(end) (the note came early); ended by the plan while the until-percept is
  not yet salient, the world gets ``grace`` × the planned duration to catch up (the note is
  a little late, as played notes are), after which p = 1 − until.evaluate(deadline).

With ``transitions``, forward transition models are expectations too: a tuple expects to be
followed by its likely successors, so when a tuple whose Du models transitions starts
(``expected``: N·p(last → it), :mod:`creatures.temporal.transitions`) less likely than
chance after the one before it, that one is judged p = 1 − N·p (a successor it has never
had, nearly 1) — as the thesis has it, "surprise can be the result of a character being able
to perform an unexpected action".

A p of at least ``tolerance`` is a violation. The second expectation is V's: at a credit
assignment, a tuple whose value models the values that follow it (a
:class:`~creatures.behaviour.value.GaussianValue`) finds β·V_n unexpected when its likelihood
falls below the value's threshold ("surprise at an unexpected value"), p = 1 − likelihood.

*How* surprising is the tuple's :class:`Confidence` times p. Confidence falls "if a model
has been wrong recently" (an exponential average of hits) and "if a model has not been
tested for a long time" (exp(−untested / memory)); a new tuple starts with none. Confidence
is then used as the thesis proposes: credit assignment moves a confident tuple's value
slower (a_i × (1 − rigidity·confidence_i)), and a *confident* expectation violated
(confidence ≥ ``confident`` before the violation) promotes percept-tree growth — the group's
learner reviews the tuple's trigger for fission whatever its value ("something in the world
has changed, and we need to refine our assumptions"). Surprise and confidence are readable
as percepts (``surprise``, ``confidence`` in the authored library), so other tuples can act
on them.

One :class:`Expectations` is creature-wide (like percepts) and is attached to each group
that keeps expectations (``group.expectations``); the group calls :meth:`starting` before a
tuple starts, :meth:`ended` before a tuple stops, :meth:`tick` at each tick and
:meth:`credit_rates` at each credit assignment.
Each tuple's confidence (its reliability, how long it has gone untested) and its counts of
tests and violations are saved by name (:meth:`Expectations.state`) and taken back at a
restart (:meth:`Expectations.restore`): a creature that had learnt which of its expectations
hold is as sure of them after a restart, less only as it tests them no more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from creatures import bounds
from creatures.behaviour.action_tuple import ActionTuple
from creatures.behaviour.confidence import Confidence

if TYPE_CHECKING:
    from creatures.behaviour.action_group import ActionGroup
    from creatures.behaviour.value import Value


@dataclass
class TupleExpectation:
    """What one tuple's expectations have met: its confidence and its last surprise."""

    tuple_: ActionTuple  # held, so its id is not reused for another tuple while this lives
    confidence: Confidence
    surprise: float = 0.0
    surprised_at: float = -math.inf
    violations: int = 0
    tests: int = 0


@dataclass
class _Pending:
    """A tuple that ended on its plan before its until-percept: the world may still catch up."""

    tuple_: ActionTuple
    group: "ActionGroup"
    deadline: float


class Expectations:
    """The expectation machinery of one creature (see the module docstring).

    ``decay`` is how many seconds a surprise stays salient as a percept (it fades as
    exp(−age / decay)). ``on_event`` receives ``surprise`` events (tuple, why, p, surprise,
    confidence) and ``expectation review`` events (a confident violation reviewed the
    tuple's trigger; ``children``: how many it gained).
    """

    def __init__(
        self,
        *,
        tolerance: float = 0.25,
        grace: float = 0.25,
        reliance: float = 0.2,
        memory: float = 600.0,
        rigidity: float = 0.5,
        confident: float = 0.5,
        fission: bool = True,
        decay: float = 1.0,
        transitions: bool = False,
        on_event: Callable[[dict[str, Any]], None] | None = None,
    ) -> None:
        if not 0.0 < tolerance <= 1.0:
            raise ValueError(f"tolerance must be in (0, 1] (got {tolerance!r})")
        if not 0.0 <= rigidity <= 1.0:
            raise ValueError(f"rigidity must be in [0, 1] (got {rigidity!r})")
        self.tolerance = float(tolerance)
        self.grace = float(grace)
        self.reliance = float(reliance)
        self.memory = float(memory)
        self.rigidity = float(rigidity)
        self.confident = float(confident)
        self.fission = fission
        self.decay = float(decay)
        self.transitions = transitions
        self.on_event = on_event
        self._of: dict[int, TupleExpectation] = {}
        self._names: dict[str, TupleExpectation] = {}
        self._pending: list[_Pending] = []
        self.latest = (0.0, -math.inf)  # (surprise, when): the creature's most recent surprise

    def of(self, tuple_: ActionTuple) -> TupleExpectation:
        state = self._of.get(id(tuple_))
        if state is None:
            state = TupleExpectation(tuple_, Confidence(self.reliance, self.memory))
            self._of[id(tuple_)] = state
            self._names[tuple_.name] = state
        return state

    def forget(self, tuple_: ActionTuple) -> None:
        """``tuple_`` has left its group (percept fusion, a refined or replaced tuple): drop
        its expectations and any end still waiting to be judged. Each new hypothesis gets a
        new name, so a creature that keeps growing and fusing its percept tree would
        otherwise hold every tuple it ever had (and through it that tuple's percept and
        models) for as long as the show runs."""
        state = self._of.pop(id(tuple_), None)
        if state is not None and self._names.get(tuple_.name) is state:
            del self._names[tuple_.name]
        self._pending = [p for p in self._pending if p.tuple_ is not tuple_]

    # -- state that lasts across restarts ----------------------------------------------------
    def state(self, tuple_: ActionTuple, t: float) -> dict[str, Any] | None:
        """``tuple_``'s confidence and counts at ``t`` (JSON-able); None while it has none."""
        e = self._of.get(id(tuple_))
        return None if e is None else {**e.confidence.state(t), "tests": e.tests, "violations": e.violations}

    def restore(self, tuple_: ActionTuple, data: Any, t: float, key: str) -> None:
        """Take back what :meth:`state` saved of ``tuple_`` at ``t``; :class:`ValueError` naming
        ``key`` for a damaged entry, before anything changes."""
        tests, violations = check_saved(data, key)
        state = self.of(tuple_)
        state.confidence.restore(data, t, key)
        state.tests, state.violations = tests, violations

    # -- readings (the percepts) ------------------------------------------------------------
    def surprise(self, t: float, name: str | None = None) -> float:
        """The surprise of tuple ``name`` (or the creature's latest), fading with ``decay``."""
        if name is None:
            s, at = self.latest
        else:
            state = self._names.get(name)
            if state is None:
                return 0.0
            s, at = state.surprise, state.surprised_at
        return s * math.exp(-max(0.0, t - at) / self.decay) if s else 0.0

    def confidence(self, t: float, name: str) -> float:
        state = self._names.get(name)
        return 0.0 if state is None else state.confidence.at(t)

    # -- the group's hooks ------------------------------------------------------------------
    def starting(self, group: "ActionGroup", previous: ActionTuple | None, tuple_: ActionTuple, t: float) -> None:
        """``tuple_`` is about to start at ``t`` after ``previous``: with ``transitions``,
        judge ``previous``'s expectation of its successor (before the start teaches the model)."""
        expected = getattr(tuple_.do_until, "expected", None) if self.transitions and previous is not None else None
        if expected is not None:
            self._judge(group, previous, t, max(0.0, 1.0 - expected(t)), "unexpected successor")

    def ended(self, group: "ActionGroup", tuple_: ActionTuple, t: float, *, interrupted: bool) -> None:
        """``tuple_`` is about to stop at ``t``: judge its end against its Du."""
        du = tuple_.do_until
        if interrupted:
            self._judge(group, tuple_, t, 1.0 - du.evaluate(t), "interrupted")
            return
        timing, world = du.timing(t), du.world(t)
        if timing is None or world is None:  # one description only, and it ended the tuple
            self._judge(group, tuple_, t, 0.0, "end")
        elif world >= 1.0:
            self._judge(group, tuple_, t, 1.0 - timing, "early")
        else:
            self._pending.append(_Pending(tuple_, group, t + self.grace * du.planned))

    def tick(self, t: float) -> None:
        """Settle the ends waiting for the world to catch up (called by each group's tick)."""
        if not self._pending:
            return
        waiting = []
        for pending in self._pending:
            world = float(pending.tuple_.do_until.until.evaluate(t))
            if world >= 1.0:
                self._judge(pending.group, pending.tuple_, t, 0.0, "late")
            elif t >= pending.deadline:
                self._judge(pending.group, pending.tuple_, t, 1.0 - world, "missed")
            else:
                waiting.append(pending)
        self._pending = waiting

    def credit_rates(self, group: "ActionGroup", t: float, last: ActionTuple, target: "Value",
                     a: np.ndarray) -> np.ndarray:
        """Before credit assignment blends toward ``target``: judge ``last``'s value
        expectation, then slow the confident (a_i × (1 − rigidity·confidence_i))."""
        likelihood = getattr(last.value, "likelihood", None)
        if likelihood is not None:
            p = likelihood(target.to_float())
            self._judge(group, last, t, 1.0 - p if p < last.value.threshold else 0.0, "value")
        if self.rigidity:
            a = a.copy()
            for i in np.flatnonzero(a):
                a[i] *= 1.0 - self.rigidity * self.of(group.tuples[i]).confidence.at(t)
        return a

    # -- judging ----------------------------------------------------------------------------
    def _judge(self, group: "ActionGroup", tuple_: ActionTuple, t: float, p: float, why: str) -> None:
        state = self.of(tuple_)
        confidence = state.confidence.at(t)
        violated = p >= self.tolerance
        state.tests += 1
        state.confidence.record(not violated, t)
        if not violated:
            return
        state.violations += 1
        state.surprise, state.surprised_at = confidence * p, t
        if state.surprise >= self.latest[0] * math.exp(-max(0.0, t - self.latest[1]) / self.decay):
            self.latest = (state.surprise, t)
        self._emit("surprise", t, group=group.name, tuple=tuple_.name, why=why, p=p, surprise=state.surprise,
                   confidence=confidence)
        review = getattr(group.learning, "review", None)
        if self.fission and confidence >= self.confident and review is not None:
            before = len(tuple_.trigger.children)
            review(group, tuple_, t)
            self._emit("expectation review", t, group=group.name, tuple=tuple_.name, percept=tuple_.trigger.name,
                       children=len(tuple_.trigger.children) - before)

    def _emit(self, event: str, t: float, **fields: Any) -> None:
        if self.on_event is not None:
            self.on_event({"event": event, "t": t, **fields})


def check_saved(data: Any, key: str) -> tuple[int, int]:
    """A saved tuple's expectation checked (:class:`ValueError` naming ``key``): its counts of
    tests and violations."""
    data = bounds.table(data, key)
    Confidence().restore(data, 0.0, key)
    tests = bounds.count(data.get("tests"), f"{key}.tests")
    return tests, bounds.count(data.get("violations"), f"{key}.violations", high=tests)
