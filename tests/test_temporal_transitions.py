"""Do-untils with forward transition models (thesis: "forward transition models", fig. 10):
recording what follows what, priming selection with it, and fission on value contrast."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.behaviour import Action, ActionTuple, DoUntil, WhateverPercept
from creatures.behaviour.action_group import ActionGroup
from creatures.temporal.transitions import LikelySuccessor, Succession, TransitionDoUntil, fission, follow


def tuples(succession: Succession, names: str = "ABC", *, strength: float = 1.0) -> list[ActionTuple]:
    return [
        follow(ActionTuple(n, WhateverPercept(), Action(n), DoUntil(0.5), 1.0), succession, strength=strength)
        for n in names
    ]


def recorded_starts(group: ActionGroup) -> list[str]:
    """The names of the tuples the group starts from now on, in order (from its events)."""
    started: list[str] = []

    def record(event: dict) -> None:
        if event["event"] == "selection" and not event.get("kept"):
            started.append(event["tuple"])

    group.on_event = record
    return started


def selections(group: ActionGroup, seconds: float, dt: float = 0.1) -> list[str]:
    started = recorded_starts(group)
    for k in range(int(seconds / dt)):
        group.tick(k * dt)
    return started


def successors(sequence: list[str], of: str) -> list[str]:
    return [b for a, b in zip(sequence, sequence[1:]) if a == of]


def test_the_du_records_every_transition_the_group_makes():
    succession = Succession(window=1000)
    group = ActionGroup("g", tuples(succession), rng=np.random.default_rng(0),
                        grounded_by="transitions under test, not values")
    seq = selections(group, 30.0)
    assert len(seq) > 20
    model = succession.model
    for i in "ABC":
        for j in "ABC":
            expected = sum(1 for a, b in zip(seq, seq[1:]) if (a, b) == (i, j))
            assert model.counts[model.index(i), model.index(j)] == expected
    assert succession.current == seq[-1]


def test_likely_successors_are_primed():
    succession = Succession(window=10, alpha=0.1)
    a, b, c = tuples(succession)
    for _ in range(10):
        succession.model.record("A", "B")
    succession.observe(a)  # A has played and is not active: what follows A is primed
    assert b.trigger.evaluate(0.0) > 1.0 > c.trigger.evaluate(0.0)
    assert b.trigger.evaluate(0.0) == pytest.approx(3 * (1 + 0.1) / (1 + 0.3))
    a.start(1.0, np.random.default_rng(0))  # while A plays again, A's predecessor (A) still primes...
    assert succession.source(1.2) == "A" and succession.previous == "A"
    b.start(1.5, np.random.default_rng(0))
    assert succession.source(1.7) == "A"  # ...and while B plays, what follows A stays primed
    assert succession.source(2.0) == "B"  # B's Du is done (0.5 s): now what follows B is primed


def first_successor(group: ActionGroup, of: str, seconds: float = 30.0, dt: float = 0.1) -> str | None:
    """What the group chose right after ``of`` first ended (None if it never did)."""
    started = recorded_starts(group)
    for k in range(int(seconds / dt)):
        group.tick(k * dt)
        after = successors(started, of)
        if after:
            return after[0]
    return None


def test_priming_makes_what_usually_follows_follow_more_often():
    shares = {}
    for strength in (0.0, 1.0):
        chosen = []
        for seed in range(60):
            succession = Succession(window=10)
            group = ActionGroup("g", tuples(succession, strength=strength), rng=np.random.default_rng(seed),
                                grounded_by="transitions under test, not values")
            for _ in range(10):  # a history in which B followed A
                succession.model.record("A", "B")
            chosen.append(first_successor(group, "A"))
        shares[strength] = chosen.count("B") / len(chosen)
    assert shares[0.0] < 0.5  # unprimed: B is one of three
    assert shares[1.0] > 0.65  # primed by p(A → B) ≈ 0.85: what usually happens next


def fissionable(values: dict[str, float]) -> tuple[Succession, list[ActionTuple]]:
    succession = Succession(window=10)
    tps = tuples(succession)
    for _ in range(4):
        for j, v in values.items():
            succession.model.record("A", j, v)
    return succession, tps


def test_fission_splits_off_the_valuable_transition():
    succession, (a, b, c) = fissionable({"B": 1.0, "C": 0.0})
    child = fission(a, succession)
    assert child is not None and child.name == "A→B"
    assert child.value.to_float() == pytest.approx(1.0)
    assert child.action is a.action and child.do_until is not a.do_until
    assert isinstance(child.do_until, TransitionDoUntil) and isinstance(child.trigger, LikelySuccessor)
    model = succession.model
    assert model.probability("A→B", "B") > model.probability("A", "B")
    assert fission(a, succession) is None  # A' exists already


def test_no_fission_without_value_contrast():
    succession, (a, _, _) = fissionable({"B": 0.5, "C": 0.5})
    assert fission(a, succession) is None
    with pytest.raises(ValueError, match="follow"):
        fission(ActionTuple("X", WhateverPercept(), Action("X"), DoUntil(1.0), 1.0), succession)


def test_a_fissioned_tuple_tends_to_lead_to_its_successor():
    chosen = []
    for seed in range(40):
        succession, tps = fissionable({"B": 1.0, "C": 0.0})
        group = ActionGroup("g", tps, rng=np.random.default_rng(seed), alpha=0.0)
        child = fission(tps[0], succession)
        group.add(child)
        chosen.append(first_successor(group, child.name))
    assert chosen.count(None) < 10
    assert chosen.count("B") / len(chosen) > 0.5  # chance would be one in four


def valued(succession: Succession, values: dict[str, float]) -> list[ActionTuple]:
    return [
        follow(ActionTuple(n, WhateverPercept(), Action(n), DoUntil(0.5), v), succession)
        for n, v in values.items()
    ]


def test_the_succession_fissions_by_itself_when_transitions_carry_different_values():
    succession = Succession(window=10)
    group = ActionGroup("g", valued(succession, {"A": 0.5, "B": 1.0, "C": 0.2}), rng=np.random.default_rng(0), alpha=0.0)
    played = selections(group, 60.0)
    grown = {tp.name: succession.fissioned[tp.name] for tp in group.tuples if tp.name in succession.fissioned}
    assert "A→B" in grown  # the group grew the sub-hypothesis "A, leading to B" as it played
    assert set(grown.values()) == {"B"}  # every sub-hypothesis leads to the valuable successor...
    assert len(group.tuples) == 3 + len(grown) == len(succession.model.names)  # ...once (no A→B→B)
    child = group.find("A→B")
    assert child.value.to_float() == pytest.approx(1.0)
    assert isinstance(child.do_until, TransitionDoUntil) and isinstance(child.trigger, LikelySuccessor)
    assert "A→B" in played  # and the group chooses it


@pytest.mark.parametrize(
    "values, innovation",
    [
        ({"A": 1.0, "B": 1.0, "C": 1.0}, 0.25),  # no spread of values at all
        ({"A": 1.0, "B": 0.95, "C": 0.9}, 0.25),  # η² ≈ 1, but the values hardly differ
        ({"A": 0.5, "B": 1.0, "C": 0.2}, None),  # automatic fission switched off
    ],
)
def test_no_automatic_fission_below_the_innovation_threshold(values, innovation):
    succession = Succession(window=10, innovation=innovation)
    group = ActionGroup("g", valued(succession, values), rng=np.random.default_rng(0), alpha=0.0)
    assert len(set(selections(group, 60.0))) == 3
    assert succession.fissioned == {} and [tp.name for tp in group.tuples] == list(values)


def test_a_shared_succession_keeps_a_stream_for_each_group():
    """Several groups (creatures) share one model: each records from, and is primed by, its
    own last start; a stream that only follows teaches the model nothing; labels let a
    perception tuple and a playing tuple be one phrase."""
    shared = Succession(innovation=None)

    def member(name: str, label: str, stream: str, record: bool = True) -> ActionTuple:
        tuple_ = ActionTuple(name, WhateverPercept(), Action(name), DoUntil(0.5), 1.0)
        return follow(tuple_, shared, label=label, stream=stream, record=record)

    heard = {n: member(f"hear {n}", n, "ear") for n in "ABC"}
    x = {n: member(n, n, "x", record=False) for n in "ABC"}
    y = {n: member(n, n, "y", record=False) for n in "ABC"}
    rng = np.random.default_rng(0)
    t = 0.0
    for n in "ABC" * 5:  # the ear hears A B C A B C ...: a clean succession, one row each
        heard[n].start(t, rng)
        heard[n].stop(t + 0.5)
        t += 1.0
    counts = shared.model.counts.copy()
    assert counts[shared.model.index("A"), shared.model.index("B")] == 5
    x["A"].start(t, rng)
    x["A"].stop(t + 0.5)
    y["B"].start(t, rng)
    y["B"].stop(t + 0.5)
    t += 1.0
    assert (shared.model.counts == counts).all()  # following without recording
    assert x["B"].trigger.evaluate(t) > 2.0 > x["C"].trigger.evaluate(t)  # after x's A: B
    assert y["C"].trigger.evaluate(t) > 2.0 > y["B"].trigger.evaluate(t)  # after y's B: C
    assert heard["A"].trigger.evaluate(t) > 2.0  # the ear's last was C: A is what follows it


def test_sub_hypotheses_are_bounded_however_long_the_valuable_successor_keeps_changing():
    """A group whose valuable successor keeps changing (a new one every hundred starts) grows
    sub-hypotheses one level deep only: at most N + N² tuples however long it plays (before,
    "A→B" split again into "A→B→C", ... : 25 tuples, 15 deep after 3000 starts)."""
    succession = Succession(window=10)
    names = "ABCD"
    pool = [follow(ActionTuple(n, WhateverPercept(), Action(n), DoUntil(0.5), 0.5), succession) for n in names]
    rng = np.random.default_rng(0)
    for k in range(3000):
        if k % 100 == 0:
            values = dict(zip(names, rng.uniform(0.0, 1.0, len(names))))
        tuple_ = pool[rng.integers(len(pool))]
        tuple_.value.value = float(values[tuple_.name[-1]])  # a version of B is worth what B is
        child = succession.observe(tuple_)
        if child is not None:
            pool.append(child)
    grown = [tp.name for tp in pool[len(names):]]
    assert len(grown) >= 4  # it did split, repeatedly...
    assert all(name.count("→") == 1 and name.split("→")[0] in names for name in grown)  # ...one level deep
    assert len(pool) <= len(names) + len(names) ** 2 and len(set(grown)) == len(grown)


def test_a_labelled_tuple_splits_under_its_label():
    """``follow_as``: the model knows a tuple by its label, and fission looked it up by its
    name ("no tuple named 'A'", a KeyError that ended the run at the first valued transition
    out of it). The sub-hypothesis is named after the tuple and recorded under the label."""
    succession = Succession(window=10)
    pool = [follow(ActionTuple(n, WhateverPercept(), Action(n), DoUntil(0.5), 0.5), succession, label=f"heard {n}")
            for n in "ABC"]
    rng = np.random.default_rng(0)
    grown = []
    for _ in range(400):
        tuple_ = pool[rng.integers(len(pool))]
        tuple_.value.value = 1.0 if tuple_.name.endswith("B") else 0.0
        child = succession.observe(tuple_, tuple_.do_until.label)
        if child is not None:
            pool.append(child)
            grown.append((child.name, child.do_until.label))
    assert ("A→heard B", "heard A→heard B") in grown
    assert all(label in succession.model.names and label in succession.fissioned for _, label in grown)
