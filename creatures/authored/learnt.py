"""What ``[creature.learning] groups`` grew, as an authored creature's state (thesis "percept
trees", "extending the percept tree"; README "What a restart keeps").

Value-driven learning (:class:`~creatures.behaviour.learning.PerceptLearning`) teaches the
Gaussian percepts the config declared, splits them into children and tries new tuples on
them, ``CHILD|ACTION``. All of it was lost at each restart, and the values saved for the new
tuples were said to match no tuple. Saved here, by name, as the rest of a creature's state:

- ``learning.trees.PERCEPT``: a declared percept's model and the children grown under it
  (:mod:`creatures.behaviour.grown`);
- ``learning.groups.GROUP``: the group's count of percepts grown (new names stay new) and
  ``tuples``, each learnt tuple's trigger and action by its name.

A tree of a percept, a group, or a learnt tuple whose trigger or action the config no longer
has is kept, said once and taken back when the name returns (:mod:`creatures.behaviour.unplaced`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from creatures import bounds
from creatures.behaviour.grown import check_tree, regrow, tree_state
from creatures.behaviour.learning import hypothesise
from creatures.behaviour.models.gaussian import GaussianPercept
from creatures.behaviour.unplaced import Unplaced

if TYPE_CHECKING:
    from creatures.authored.creature import Authored
    from creatures.behaviour.action_group import ActionGroup


def learning_state(creature: "Authored", kept: Unplaced) -> dict[str, Any]:
    """The trees and learnt tuples of ``creature``'s learning groups, with what ``kept`` keeps
    of names it no longer has (nothing when it learns no percept trees and kept none)."""
    groups = {name: creature.groups[name] for name in creature.spec.learning.groups}
    trees = {tp.trigger.name: tree_state(tp.trigger, creature.percepts) for group in groups.values()
             for tp in group.tuples if _declared_model(creature, tp.trigger.name)}
    saved = {name: {"grown": group.learning.grown,
                    "tuples": kept.carry(f"learning.groups.{name}.tuples", _learnt_tuples(creature, group))}
             for name, group in groups.items()}
    state = {"trees": kept.carry("learning.trees", trees), "groups": kept.carry("learning.groups", saved)}
    return state if any(state.values()) else {}


def _declared_model(creature: "Authored", name: str) -> bool:
    return isinstance(creature.percepts.get(name), GaussianPercept)


def _learnt_tuples(creature: "Authored", group: "ActionGroup") -> dict[str, list[str]]:
    """The tuples learning added to ``group``: ``CHILD|ACTION``, none the config wrote."""
    authored = set(creature.spec.groups[group.name].tuples)
    return {tp.name: [tp.trigger.name, tp.action.name] for tp in group.tuples
            if tp.name not in authored and tp.name == f"{tp.trigger.name}|{tp.action.name}"}


def restore_learning(creature: "Authored", kept: Unplaced, saved: Any) -> None:
    """Take back :func:`learning_state`: the trees first, then each group's learnt tuples on
    them (before the values, saved by tuple name, are given back)."""
    saved = bounds.table(saved, "learning")
    models = {name for name in creature.percepts if _declared_model(creature, name)}
    for name, tree in kept.place("learning.trees", saved.get("trees", {}), models, what="percept tree",
                                 of="percept", no="Gaussian percept",
                                 check=lambda data, key: check_tree(data, key, key.removeprefix("learning.trees."))).items():
        key = f"learning.trees.{name}"
        root = creature.percepts[name]
        regrow(root, check_tree(tree, key, name, taken=creature.percepts), key, creature.percepts)
    percepts = {p.name: p for name in models for p in creature.percepts[name].walk()} | creature.percepts
    groups = kept.place("learning.groups", saved.get("groups", {}), creature.spec.learning.groups,
                        what="learning", of="action-group", no="learning group", check=_check_group)
    for name, data in groups.items():
        group = creature.groups[name]
        group.learning.grown = max(group.learning.grown, data["grown"])
        _restore_tuples(creature, kept, group, data.get("tuples", {}),
                        _check_group(data, f"learning.groups.{name}"), percepts)


def _check_group(data: Any, key: str) -> dict[str, tuple[str, str]]:
    """A saved group's entry checked: its learnt tuples' (trigger, action) by name."""
    data = bounds.table(data, key)
    bounds.count(data.get("grown"), f"{key}.grown")
    return {name: _check_tuple(entry, f"{key}.tuples.{name}")
            for name, entry in bounds.table(data.get("tuples", {}), f"{key}.tuples").items()}


def _check_tuple(entry: Any, key: str) -> tuple[str, str]:
    trigger, action = bounds.items(entry, key, shortest=2, longest=2)
    return bounds.text(trigger, f"{key}.0"), bounds.text(action, f"{key}.1")


def _restore_tuples(creature: "Authored", kept: Unplaced, group: "ActionGroup", saved: dict[str, Any],
                    entries: dict[str, tuple[str, str]], percepts: dict[str, Any]) -> None:
    """Each learnt tuple whose trigger and action this creature has (``entries``, checked from
    ``saved``), built as fission built it (the authored tuple of that action lends its Du); the
    others are kept."""
    authored = {tp.action.name: tp for tp in group.tuples if tp.name in creature.spec.groups[group.name].tuples}
    buildable = {name for name, (trigger, action) in entries.items() if trigger in percepts and action in authored}
    have = {tp.name for tp in group.tuples}
    for name in kept.place(f"learning.groups.{group.name}.tuples", saved, buildable, what="learnt tuple",
                           of="trigger|action", within=f" in action-group {group.name!r}", no="percept|tuple pair"):
        trigger, action = entries[name]
        if name not in have:
            group.add(hypothesise(name, percepts[trigger], authored[action]))
