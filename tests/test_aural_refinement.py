"""Refinement of aural Ac percept trees (thesis, "aural Ac percept trees": "Action-tuples start
at the top of the tree … and slowly refine what it is that they should be playing"): with
``refine`` a tuple singing a class that has split gives way to the tuples singing its children,
and that family takes over its duties (the class's clustering, tuples for classes it gains
later); without it the tuple stays beside them (:class:`AuralLearning`). ``in_kind``: a tuple
whose Tr and Ac are one percept answers each class of it with that class."""

from __future__ import annotations

import numpy as np

from audio.utterance import UtterancePercept
from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import FunctionPercept
from creatures.behaviour.value import ScalarValue
from creatures.kinds.hearing_parts import AuralLearning, SingFrom


class Tree:
    """An aural tree split into two classes by hand, one group whose ``sing`` tuple sings its
    root, and the learning under test."""

    def __init__(self, *, refine: bool, in_kind: bool = False) -> None:
        self.root = UtterancePercept("any sound")
        self.kids = [UtterancePercept(f"any sound/{k}", parent=self.root) for k in (1, 2)]
        self.root._born = 2
        rng = np.random.default_rng(1)
        self.singers: dict[int, SingFrom] = {}
        self.events: list[dict] = []
        self.learning = AuralLearning(self.root, self.sing_from, refine=refine, in_kind=in_kind,
                                      on_event=self.events.append)
        self.excited = FunctionPercept("excited", lambda t: 1.0)
        self.group = ActionGroup("main", rng=rng, learning=self.learning, tuples=[
            ActionTuple("sing", self.excited, self.sing_from(self.root), DoUntil(2.0), 2.0),
            ActionTuple("rest", FunctionPercept("always", lambda t: 1.0), Action("rest"), DoUntil(1.0),
                        ScalarValue(0.3, plasticity=0.0)),
        ])

    def sing_from(self, percept: UtterancePercept) -> SingFrom:
        if id(percept) not in self.singers:
            self.singers[id(percept)] = SingFrom(percept, np.random.default_rng(2), lambda t, u, p: None)
        return self.singers[id(percept)]

    def names(self) -> list[str]:
        return [tp.name for tp in self.group.tuples]


def test_without_refine_the_tuple_stays_beside_its_children() -> None:
    tree = Tree(refine=False)
    tree.learning.review(tree.group, tree.group.find("sing"), 1.0)
    assert tree.names() == ["sing", "rest", "excited|sing any sound/1", "excited|sing any sound/2"]
    assert not [e for e in tree.events if e["event"] == "refinement"]


def test_refined_the_tuple_gives_way_to_its_childrens() -> None:
    tree = Tree(refine=True)
    tree.group.find("sing").value.value = 2.5
    tree.learning.review(tree.group, tree.group.find("sing"), 1.0)
    assert tree.names() == ["rest", "excited|sing any sound/1", "excited|sing any sound/2"]
    assert [tree.group.find(n).value.to_float() for n in tree.names()[1:]] == [2.5, 2.5]  # V inherited
    [event] = [e for e in tree.events if e["event"] == "refinement"]
    assert event["tuple"] == "sing" and event["children"] == ["any sound/1", "any sound/2"]


def test_the_family_reviews_the_class_and_gives_a_new_class_a_tuple() -> None:
    """After refinement nothing sings the root, so its members review it: a class it gains
    (as its re-clustering would make) gets a tuple with the same Tr, V copied from the member
    reviewed; a tuple whose class has a tuple singing it under its Tr is no member."""
    tree = Tree(refine=True)
    tree.learning.review(tree.group, tree.group.find("sing"), 1.0)
    clustered: list[str] = []
    for percept in tree.root.walk():
        percept.fission = lambda value, threshold, p=percept: clustered.append(p.name) or []
    member = tree.group.find("excited|sing any sound/1")
    member.value.value = 1.7
    UtterancePercept("any sound/3", parent=tree.root)
    tree.learning.review(tree.group, member, 20.0)
    assert clustered == ["any sound/1", "any sound"]  # its own class, and the family's
    assert tree.names()[-1] == "excited|sing any sound/3"
    assert tree.group.find("excited|sing any sound/3").value.to_float() == 1.7
    assert tree.group.find("excited|sing any sound/3").trigger is tree.excited

    unrefined = Tree(refine=False)
    unrefined.learning.review(unrefined.group, unrefined.group.find("sing"), 1.0)
    clustered.clear()
    for percept in unrefined.root.walk():
        percept.fission = lambda value, threshold, p=percept: clustered.append(p.name) or []
    UtterancePercept("any sound/3", parent=unrefined.root)
    unrefined.learning.review(unrefined.group, unrefined.group.find("excited|sing any sound/1"), 20.0)
    assert clustered == ["any sound/1"]  # "sing" still sings the root: the root is its to review
    assert "excited|sing any sound/3" not in unrefined.names()


def answering(tree: Tree) -> ActionTuple:
    """``tree``'s group with an ``answer`` tuple hearing and singing the root, reviewed once."""
    answer = tree.group.add(ActionTuple("answer", tree.root, tree.sing_from(tree.root), DoUntil(2.0), 1.5))
    tree.learning.review(tree.group, answer, 1.0)
    return answer


def test_an_answer_in_kind_sings_each_class_it_hears() -> None:
    """A tuple hearing and singing the root: with ``in_kind`` each class gets ``class | sing
    class`` (V inherited), not the class as a trigger of any song and any sound as a trigger
    of the class's song (as without it); refined, it gives way to them, and their family gives
    a class the root gains later its answer."""
    answers = ["any sound/1|sing any sound/1", "any sound/2|sing any sound/2"]
    crossed = Tree(refine=False)
    answering(crossed)
    assert crossed.names()[2:] == ["answer", "any sound/1|sing any sound", "any sound/2|sing any sound",
                                   "any sound|sing any sound/1", "any sound|sing any sound/2"]
    beside = Tree(refine=False, in_kind=True)
    answering(beside)
    assert beside.names()[2:] == ["answer", *answers]
    for name, kid in zip(answers, beside.kids):
        tp = beside.group.find(name)
        assert tp.trigger is kid and tp.action.percept is kid and tp.value.to_float() == 1.5

    refined = Tree(refine=True, in_kind=True)
    answering(refined)
    assert refined.names()[2:] == answers
    UtterancePercept("any sound/3", parent=refined.root)
    refined.learning.review(refined.group, refined.group.find(answers[0]), 20.0)
    assert refined.names()[-1] == "any sound/3|sing any sound/3"
    assert refined.group.find("any sound/3|sing any sound/3").trigger is refined.root.children[-1]
