"""Learning that grows (thesis: "percept updating – model building", "extending the percept
tree"): value-driven model updates, fission of a bimodal percept into children with new
action-tuple hypotheses, no fission for one cluster, fusion when children converge, and an
Ac percept shaped by reward (simple shaping)."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.learning import (
    ParametrisedAction,
    PerceptLearning,
    bimodal_clusters,
    two_means_split,
)
from creatures.behaviour.models.gaussian import GaussianModel, GaussianPercept
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.behaviour.state_object import StateObject
from creatures.behaviour.value import ScalarValue

DT = 0.5


class Singer:
    """A creature that sings when it hears a pitch it likes; each song is fed.

    Every cycle: a pitch is heard, ``pitch | sing`` starts (its Tr looks at the pitch flow),
    food appears, ``food | eat`` interrupts, and credit assignment hands the learner the
    situation that led to the song.
    """

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self.t = 0.0
        self.food_until = -np.inf
        self.events: list[dict] = []
        self.pitch = StateObject("pitch")
        self.percept = GaussianPercept("pitch", self.pitch, GaussianModel(0.0, 3.0, size=32))
        self.learning = PerceptLearning(on_event=self.events.append)
        food = FunctionPercept("food", lambda t: 5.0 if t < self.food_until else 0.0)
        never = FunctionPercept("night", lambda t: 0.0)
        tuples = [
            ActionTuple("pitch|sing", self.percept, Action("sing"), DoUntil(2.0), 50.0),
            # Eating is the grounded source of value: not plastic.
            ActionTuple("food|eat", food, Action("eat"), DoUntil(DT), ScalarValue(100.0, plasticity=0.0)),
        ]
        # A repertoire of low-valued tuples that never fire tonight: they set the group's
        # mean value, against which the thresholds are measured.
        tuples += [ActionTuple(f"night|{n}", never, Action(n), DoUntil(1.0), 5.0) for n in ("sleep", "dream", "snore", "turn")]
        self.group = ActionGroup(
            "singer", tuples, rng=rng, alpha=0.2, discount=0.8, temperature=0.5, learning=self.learning,
            on_event=self.events.append,
        )

    def cycle(self, heard: float) -> None:
        self.pitch.push(self.t, heard)
        self.group.tick(self.t)  # sing starts
        self.t += DT
        self.food_until = self.t + DT
        self.group.tick(self.t)  # food: eat interrupts; credit to sing, model updated
        self.t += DT
        self.group.tick(self.t)  # eat done
        self.t += DT

    def kinds(self, kind: str) -> list[dict]:
        return [e for e in self.events if e["event"] == kind]


def test_two_means_split_is_exact():
    low, high = two_means_split(np.array([5.0, -1.0, 0.0, 4.0, 1.0, 6.0]))
    assert sorted(low) == [-1.0, 0.0, 1.0] and sorted(high) == [4.0, 5.0, 6.0]
    assert bimodal_clusters(np.r_[np.zeros(10), np.full(10, 10.0)] + np.linspace(0, 1, 20)) is not None
    unimodal = np.random.default_rng(5).normal(0.0, 1.0, 500)
    assert bimodal_clusters(unimodal) is None  # its halves alone would pass Ashman's D
    assert bimodal_clusters(np.linspace(-1, 1, 32)) is None  # flat is not two categories
    assert bimodal_clusters(np.r_[np.zeros(19), 100.0]) is None  # one outlier is not a category


def test_valuable_situations_teach_the_percept(rng):
    singer = Singer(rng)
    for _ in range(40):
        singer.cycle(rng.normal(2.0, 0.3))
    # The model has moved from its prior (mean 0, sd 3) to the rewarded situations.
    assert singer.percept.model.mean == pytest.approx(0.9 * 2.0, abs=0.3)
    assert singer.percept.model.std < 1.5


def test_fission_for_two_clusters_makes_children_and_hypotheses(rng):
    singer = Singer(rng)
    for k in range(60):
        singer.cycle(rng.normal(-4.0 if k % 2 else 4.0, 0.5))
    fissions = singer.kinds("fission")
    assert len(fissions) == 1
    children = singer.percept.children
    assert len(children) == 2
    means = sorted(c.model.mean for c in children)
    assert means[0] == pytest.approx(-4.0, abs=0.5) and means[1] == pytest.approx(4.0, abs=0.5)
    names = {tp.name for tp in singer.group.tuples}
    assert {f"{c.name}|sing" for c in children} <= names
    parent = singer.group.find("pitch|sing")
    for c in children:
        hypothesis = singer.group.find(f"{c.name}|sing")
        assert hypothesis.action is parent.action and hypothesis.trigger is c
        assert hypothesis.value is not parent.value
    # Each child hears only its own cluster.
    low = min(children, key=lambda c: c.model.mean)
    assert low.model.likelihood(-4.0) > 0.5 and low.model.likelihood(4.0) < 1e-3


def test_no_fission_for_one_cluster(rng):
    singer = Singer(rng)
    for _ in range(60):
        singer.cycle(rng.normal(1.0, 1.0))
    assert singer.kinds("fission") == [] and singer.percept.children == []
    assert len(singer.group.tuples) == 6


def test_no_model_updates_below_the_value_threshold(rng):
    """Singing is worth less than the group's mean (the statistics threshold): however
    often it is followed by food, the pitch model is left alone."""
    singer = Singer(rng)
    singer.group.find("pitch|sing").value.value = 3.0
    singer.group.find("food|eat").value.value = 4.0  # so credit keeps sing near 0.8·4 = 3.2
    before = singer.percept.model.buffer.copy()
    for _ in range(20):
        singer.cycle(rng.normal(4.0, 0.3))
    assert len(singer.kinds("credit")) >= 20
    assert singer.group.find("pitch|sing").value.to_float() < np.mean(singer.group.leaf_values())
    assert np.array_equal(singer.percept.model.buffer, before)


def test_children_fuse_when_they_converge(rng):
    singer = Singer(rng)
    for k in range(60):
        singer.cycle(rng.normal(-4.0 if k % 2 else 4.0, 0.5))
    assert len(singer.percept.children) == 2
    for _ in range(80):  # the two kinds of pitch are gone: one broad cluster in between
        singer.cycle(rng.normal(0.0, 2.0))
    fusions = singer.kinds("fusion")
    assert len(fusions) == 1
    assert singer.percept.children == []
    assert all(tp.trigger is not None and not tp.trigger.name.startswith("pitch.") for tp in singer.group.tuples)


def test_parametrised_action_is_shaped_by_reward(rng):
    """Simple shaping: the trainer feeds the dog only for paw shakes higher than 1; the Ac
    model drifts toward the rewarded region."""
    food_until = [-np.inf]
    model = GaussianModel(0.0, 1.0, size=16)
    shake = ParametrisedAction("shake paw", model, rng)
    food = FunctionPercept("food", lambda t: 5.0 if t < food_until[0] else 0.0)
    never = FunctionPercept("night", lambda t: 0.0)
    tuples = [
        ActionTuple("whatever|shake paw", WhateverPercept(), shake, DoUntil(DT), 50.0),
        ActionTuple("food|eat", food, Action("eat"), DoUntil(DT), ScalarValue(100.0, plasticity=0.0)),
    ] + [ActionTuple(f"night|{n}", never, Action(n), DoUntil(1.0), 5.0) for n in ("sleep", "dream", "snore")]
    group = ActionGroup("dog", tuples, rng=rng, alpha=0.2, temperature=0.5, learning=PerceptLearning())
    t = 0.0
    for _ in range(300):
        group.tick(t)
        if group.active and group.active[0].action is shake and shake.parameter > 1.0:
            food_until[0] = t + 2 * DT
        t += DT
    assert model.mean > 1.0
    assert model.std < 1.0
