"""A Do-until that wraps another (thesis: "the action-tuple": Tr and Du are percepts whose
meaning comes from their role, so a Du can be decorated with more context).

Interval constraints (:mod:`creatures.temporal.intervals`) and forward transition models
(:mod:`creatures.temporal.transitions`) add behaviour *around* a tuple's existing Du — its
duration model keeps being sampled and taught — so they wrap it rather than replace it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from creatures.behaviour.action_tuple import DoUntil


class WrappedDoUntil(DoUntil):
    """Delegates the Du life cycle (``begin`` → ``evaluate``… → ``end``) to ``inner``.

    All Du state (duration, until-percept, start time, planned duration) stays in the inner
    Du, so wrappers stack: ``Held(Transitions(DoUntil(model)))``. Reading an attribute the
    wrapper does not define reads the inner Du's.
    """

    def __init__(self, inner: DoUntil) -> None:
        self.inner = inner

    def __getattr__(self, name: str) -> Any:
        if name == "inner":  # not yet set: avoid recursion during construction/copy
            raise AttributeError(name)
        return getattr(self.inner, name)

    def begin(self, t: float, rng: np.random.Generator) -> None:
        self.inner.begin(t, rng)

    def evaluate(self, t: float) -> float:
        return self.inner.evaluate(t)

    def end(self, t: float) -> float:
        return self.inner.end(t)

    def timing(self, t: float) -> float | None:
        return self.inner.timing(t)

    def world(self, t: float) -> float | None:
        return self.inner.world(t)
