"""Percepts and percept trees (thesis: "percepts", "percept trees").

A percept is a creature-wide container of a concept ("there is food", "a sound like *sit*").
Many triggers can look at the same percept, so when its model changes every tuple that
references it changes with it. ``evaluate(t)`` returns a saliency in [−∞, ∞): negative
saliencies (the lion) and saliencies above 1 (the clicker's startling click) are allowed on
purpose.

Percepts form trees rooted at a "whatever" percept that says yes to everything; trees grow
by fission (a child for a newly distinct cluster) and shrink by fusion, and each new child
lets the action-group create new action-tuple hypotheses.
"""

from __future__ import annotations

from typing import Any, Callable, Iterator


class Percept:
    """A node of a percept tree with an ``evaluate(t)`` saliency.

    Subclasses override :meth:`evaluate`; models that learn also override :meth:`update`
    (fed the data that led up to a valuable action) and may propose children.
    """

    def __init__(self, name: str, *, parent: "Percept | None" = None) -> None:
        self.name = name
        self.parent: Percept | None = None
        self.children: list[Percept] = []
        if parent is not None:
            parent.add_child(self)

    def evaluate(self, t: float) -> float:
        raise NotImplementedError(f"{type(self).__name__} must implement evaluate(t)")

    def update(self, t: float, value: float) -> None:
        """Learn from the situation at time ``t`` that earned credit ``value``.

        The default percept is fixed (pre-wired); models override this.
        """

    def add_child(self, child: "Percept") -> "Percept":
        if child.parent is not None:
            child.parent.remove_child(child)
        child.parent = self
        self.children.append(child)
        return child

    def remove_child(self, child: "Percept") -> None:
        self.children.remove(child)
        child.parent = None

    def walk(self) -> Iterator["Percept"]:
        """This percept and all its descendants, depth first."""
        yield self
        for child in self.children:
            yield from child.walk()

    def find(self, name: str) -> "Percept":
        for node in self.walk():
            if node.name == name:
                return node
        raise KeyError(f"no percept named {name!r} under {self.name!r}")

    def depth(self) -> int:
        return 0 if self.parent is None else 1 + self.parent.depth()

    def describe(self) -> str:
        """An indented text rendering of the tree (for logs and the inspector)."""
        return "\n".join("  " * n.depth() + f"{n.name} ({type(n).__name__})" for n in self.walk())

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "type": type(self).__name__,
            "children": [c.to_dict() for c in self.children],
        }

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


class WhateverPercept(Percept):
    """The root of every percept tree: says yes regardless of the world (a blank prior)."""

    def __init__(self, name: str = "whatever") -> None:
        super().__init__(name)

    def evaluate(self, t: float) -> float:
        return 1.0


class FunctionPercept(Percept):
    """A pre-wired percept from a plain function of time: the "quick sketch" of an idea."""

    def __init__(
        self, name: str, fn: Callable[[float], float], *, parent: Percept | None = None
    ) -> None:
        super().__init__(name, parent=parent)
        self.fn = fn

    def evaluate(self, t: float) -> float:
        return float(self.fn(t))
