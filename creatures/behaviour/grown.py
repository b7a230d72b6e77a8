"""A grown percept tree as saved state (thesis "percept trees": trees "grow and shrink" by
fission and fusion, :mod:`creatures.behaviour.learning`).

What learning grew under a percept the author declared is data, not code: each child fission
made is a :class:`GaussianPercept` of its parent's flow, told by its name and its model. So a
tree is saved as the declared percept's model and its grown children, each with its own model
and children, and is grown again under the same percept at load: the creature resumes with
the distinctions it had learnt, instead of a restart pruning every tree back to its root.
"""

from __future__ import annotations

from typing import Any, Collection

from creatures import bounds
from creatures.behaviour.models.gaussian import GaussianModel, GaussianPercept
from creatures.behaviour.percept import Percept

MOST_CHILDREN = 64
"""Most children a saved percept may have (fission adds two at a time; a damaged list is refused)."""

DEEPEST = 32
"""Deepest a saved tree may grow below its declared percept."""


def tree_state(root: GaussianPercept, declared: Collection[str]) -> dict[str, Any]:
    """``root``'s name and model and the children learning grew under it (those whose name is
    not one of ``declared``, the config's percepts), JSON-able: each node's ``name`` and
    ``children``, as ``creatures inspect`` reads a tree."""
    return {"name": root.name, "model": root.model.to_dict(), "children": _grown(root, declared)}


def _grown(percept: Percept, declared: Collection[str] = ()) -> list[dict[str, Any]]:
    return [{"name": c.name, "model": c.model.to_dict(), "children": _grown(c)}
            for c in percept.children if isinstance(c, GaussianPercept) and c.name not in declared]


def check_tree(data: Any, key: str, root: str, taken: Collection[str] = ()) -> dict[str, Any]:
    """``data`` as a saved tree of the percept ``root``, every model and name checked
    (:class:`ValueError` naming the key of what is damaged); nothing is built. A child's name
    must extend its parent's and be none of ``taken`` nor another's (a saved tree cannot
    shadow a declared percept)."""
    data = bounds.table(data, key)
    if data.get("name") != root:
        raise ValueError(f"{key}.name: the tree of {root!r} is saved as {data.get('name')!r}")
    _model(data.get("model"), f"{key}.model")
    _children(data, key, root, set(taken), 0)
    return data


def _children(data: dict[str, Any], key: str, parent: str, taken: set[str], depth: int) -> None:
    if depth > DEEPEST:
        raise ValueError(f"{key}: a tree deeper than {DEEPEST} percepts")
    for k, child in enumerate(bounds.items(data.get("children"), f"{key}.children", longest=MOST_CHILDREN)):
        where = f"{key}.children.{k}"
        child = bounds.table(child, where)
        name = bounds.text(child.get("name"), f"{where}.name")
        if not name.startswith(f"{parent}.") or name in taken:
            raise ValueError(f"{where}.name: {name!r} is not a new percept grown under {parent!r}")
        taken.add(name)
        _model(child.get("model"), f"{where}.model")
        _children(child, where, name, taken, depth + 1)


def _model(data: Any, key: str) -> GaussianModel:
    try:
        return GaussianModel.from_dict(bounds.table(data, key))
    except ValueError as exc:
        raise ValueError(f"{key}: {exc}") from None


def regrow(root: GaussianPercept, data: dict[str, Any], key: str, declared: Collection[str]) -> None:
    """Take back a tree :func:`check_tree` passed: ``root``'s samples (its prior is the
    config's), and in place of what grew under it now, the saved children."""
    try:
        root.model.restore(data["model"])
    except ValueError as exc:
        raise ValueError(f"{key}.model: {exc}") from None
    for child in [c for c in root.children if c.name not in declared]:
        root.remove_child(child)
    _regrow_children(root, data)


def _regrow_children(parent: GaussianPercept, data: dict[str, Any]) -> None:
    for saved in data["children"]:
        child = GaussianPercept(saved["name"], parent.state, GaussianModel.from_dict(saved["model"]), parent=parent,
                                lookback=parent.lookback, mask_reach=parent.mask_reach)
        _regrow_children(child, saved)
