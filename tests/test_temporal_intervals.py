"""Allen's interval algebra (thesis: "temporal logics", figure 12): the pure classifier and
constraints on Tr/Du that make action-groups produce activations obeying a relation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from creatures.behaviour import Action, ActionTuple, DoUntil, WhateverPercept
from creatures.behaviour.action_group import ActionGroup
from creatures.clock import SimulatedClock
from creatures.temporal.intervals import GatedTrigger, Relation, constrain, during, meets, relation

R = Relation
HAND_MADE = {
    ((0, 1), (2, 3)): R.BEFORE,
    ((2, 3), (0, 1)): R.AFTER,
    ((0, 1), (1, 2)): R.MEETS,
    ((1, 2), (0, 1)): R.MET_BY,
    ((0, 2), (1, 3)): R.OVERLAPS,
    ((1, 3), (0, 2)): R.OVERLAPPED_BY,
    ((0, 1), (0, 2)): R.STARTS,
    ((0, 2), (0, 1)): R.STARTED_BY,
    ((1, 2), (0, 3)): R.DURING,
    ((0, 3), (1, 2)): R.CONTAINS,
    ((1, 2), (0, 2)): R.FINISHES,
    ((0, 2), (1, 2)): R.FINISHED_BY,
    ((0, 2), (0, 2)): R.EQUALS,
}


@pytest.mark.parametrize(("pair", "expected"), HAND_MADE.items(), ids=[r.value for r in HAND_MADE.values()])
def test_classifier_gives_each_of_the_thirteen_relations(pair, expected):
    assert relation(*pair) is expected


def test_tolerance_merges_near_equal_times():
    assert relation((0, 1.0), (1.001, 2), tolerance=0.01) is R.MEETS
    assert relation((0, 1.0), (1.001, 2)) is R.BEFORE
    with pytest.raises(ValueError, match="interval y"):
        relation((0, 1), (2, 2))


interval = st.tuples(st.integers(0, 20), st.integers(1, 10)).map(lambda p: (float(p[0]), float(p[0] + p[1])))


@given(interval, interval)
def test_inverse_symmetry(x, y):
    assert relation(y, x) is relation(x, y).inverse
    assert relation(x, y).inverse.inverse is relation(x, y)


# -- constraints in running action-groups ---------------------------------------------------
def tuple_(name: str, duration: float) -> ActionTuple:
    return ActionTuple(name, WhateverPercept(), Action(name), DoUntil(duration), 1.0)


Activations = dict[str, list[tuple[float, float | None]]]


def run(groups: list[ActionGroup], seconds: float, dt: float = 0.05) -> Activations:
    """Tick the groups in order on one simulated clock; return each tuple's activations
    (those still open at the end have end ``None``)."""
    clock, open_, done = SimulatedClock(), {}, {}

    def record(event: dict) -> None:
        if event["event"] == "selection" and not event.get("kept"):
            open_[event["tuple"]] = event["t"]
        elif event["event"] == "stop":
            done.setdefault(event["tuple"], []).append((open_.pop(event["tuple"]), event["t"]))

    for group in groups:
        group.on_event = record
    for k in range(int(seconds / dt)):
        t = clock.advance_to(k * dt)
        for group in groups:
            group.tick(t)
    for name, start in open_.items():
        done.setdefault(name, []).append((start, None))
    return done


def holds(rel: Relation, gated: list, reference: list, *, gated_is_x: bool) -> int:
    """Assert every finished activation of the gated tuple stands in ``rel`` to some
    activation of the reference (ignoring the ones the end of the run cut off); return how
    many were checked."""
    finished = [r for r in reference if r[1] is not None]
    still_open = [r[0] for r in reference if r[1] is None]
    checked = 0
    for activation in gated:
        if activation[1] is None or any(start <= activation[0] for start in still_open):
            continue
        found = [relation(activation, r) if gated_is_x else relation(r, activation) for r in finished]
        assert rel in found, (activation, sorted(set(found), key=lambda r: r.value))
        checked += 1
    return checked


def test_b_meets_a_and_c_during_a_in_every_seeded_run():
    seen = {"B": 0, "C": 0}
    for seed in range(50):
        rng = np.random.default_rng(seed)
        a, b, d = tuple_("A", rng.uniform(0.5, 1.5)), tuple_("B", rng.uniform(0.2, 0.8)), tuple_("D", 0.4)
        c, e = tuple_("C", rng.uniform(0.1, 0.4)), tuple_("E", 0.3)
        meets(a, b)  # "B starts when A ends"
        during(c, a)  # "C during A"
        melody = ActionGroup("melody", [a, b, d], rng=rng, alpha=0.0)
        accompaniment = ActionGroup("accompaniment", [c, e], rng=rng, alpha=0.0)
        log = run([melody, accompaniment], seconds=20.0)
        seen["B"] += holds(R.MEETS, log.get("B", []), log["A"], gated_is_x=False)
        seen["C"] += holds(R.DURING, log.get("C", []), log["A"], gated_is_x=True)
    assert seen["B"] >= 100 and seen["C"] >= 100  # the relations were exercised, not vacuous


@pytest.mark.parametrize("rel", list(Relation), ids=[r.value for r in Relation])
def test_every_constraint_yields_its_relation(rel):
    """x in one group, y in another; the tuple whose trigger the constraint gates is in the
    group ticked second, so it sees the other's start or end in the same tick."""
    count = 0
    for seed in range(6):
        rng = np.random.default_rng(seed)
        x, y = tuple_("x", rng.uniform(0.3, 1.2)), tuple_("y", rng.uniform(0.3, 1.2))
        constrain(x, rel, y)
        gated, reference = (x, y) if isinstance(x.trigger, GatedTrigger) else (y, x)
        # No interruptions by ordinary re-growth (a huge multiple): an interrupted reference
        # would end early, which no constraint on its partner can prevent.
        first = ActionGroup("first", [reference, tuple_("rest1", 0.5)], rng=rng, alpha=0.0, multiple=1e9)
        second = ActionGroup("second", [gated, tuple_("rest2", 0.4)], rng=rng, alpha=0.0, multiple=1e9)
        log = run([first, second], seconds=15.0)
        count += holds(rel, log.get(gated.name, []), log[reference.name], gated_is_x=gated is x)
    assert count >= 10


AUTHORED = """
title = "relations"
duration = 60.0

[[creature]]
name = "r"
kind = "authored"

[creature.tuples.x]
action = "rest"
until = {{ seconds = {x} }}

[creature.tuples.y]
action = "rest"
until = {{ seconds = {y} }}

[creature.tuples.rest1]
action = "rest"
until = {{ seconds = 0.5 }}

[creature.tuples.rest2]
action = "rest"
until = {{ seconds = 0.4 }}

[creature.groups.first]
tuples = ["{reference}", "rest1"]
alpha = 0.0
multiple = 1000.0

[creature.groups.second]
tuples = ["{gated}", "rest2"]
alpha = 0.0
multiple = 1000.0
constraints = [{{ relation = "{relation}", a = "x", b = "y"{gap} }}]
"""


@pytest.mark.parametrize("rel", list(Relation), ids=[r.value for r in Relation])
def test_every_relation_is_authored_as_a_group_constraint(tmp_path, rel):
    """``constraints = [{ relation = "...", a = "x", b = "y" }]`` makes x's activations stand in
    that relation to y's in an authored creature, for each of the thirteen relations (the
    gated tuple in the group that ticks second, as the reference says)."""
    from creatures.kinds import KINDS
    from creatures.runtime.schema import load_installation
    from tests.test_authored import _world_with

    x, y = tuple_("x", 1.0), tuple_("y", 1.0)
    constrain(x, rel, y)
    gated = "x" if isinstance(x.trigger, GatedTrigger) else "y"
    count = 0
    for seed in range(3):
        rng = np.random.default_rng(seed)
        path = tmp_path / f"{seed}.toml"
        gap = ", gap = 0.3" if rel in (R.BEFORE, R.AFTER) else ""
        path.write_text(AUTHORED.format(x=round(rng.uniform(0.3, 1.2), 2), y=round(rng.uniform(0.3, 1.2), 2),
                                        gated=gated, reference="y" if gated == "x" else "x", relation=rel.value,
                                        gap=gap))
        clock, world = _world_with({})
        spec = load_installation(path).specs[0]  # registers the authored kind
        creature = KINDS["authored"](spec, world, rng)
        open_: dict[str, float] = {}
        log: Activations = {}

        def emit(t, kind, **fields):
            if kind == "selection":
                open_[fields["tuple"]] = t
            elif kind == "stop":
                log.setdefault(fields["tuple"], []).append((open_.pop(fields["tuple"]), t))

        world.log.emit = emit
        for k in range(1, 300):
            creature.tick(clock.advance_to(k * 0.05))
        for name, start in open_.items():
            log.setdefault(name, []).append((start, None))
        count += holds(rel, log.get(gated, []), log["y" if gated == "x" else "x"], gated_is_x=gated == "x")
    assert count >= 5


def test_a_gap_is_only_for_before_and_after(tmp_path):
    from creatures.config import ConfigError
    from creatures.runtime.schema import load_installation

    path = tmp_path / "bad.toml"
    path.write_text(AUTHORED.format(x=1.0, y=1.0, gated="y", reference="x", relation="meets", gap=", gap = 0.3"))
    with pytest.raises(ConfigError, match="'gap' is for 'before' and 'after'"):
        load_installation(path)
