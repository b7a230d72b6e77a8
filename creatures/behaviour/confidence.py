"""Confidence in a model (thesis: "expectations about value": "if a model has been wrong
recently, it should be less surprising if it is wrong again; secondly, if a model has not
been tested for a long time, then it should be less surprising if it just happens to be
wrong"). Shared by :class:`~creatures.behaviour.value.GaussianValue` and the action-tuple
expectations of :mod:`creatures.behaviour.expectation`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass
class Confidence:
    """Trust in a model: ``reliability`` (an exponential average of hits, rate ``reliance``)
    discounted by exp(−(t − tested_at) / ``memory``) seconds untested."""

    reliance: float = 0.2
    memory: float = 600.0
    reliability: float = 0.0
    tested_at: float | None = None

    def at(self, t: float | None) -> float:
        """Confidence at ``t`` (without a time, or never tested: the reliability alone)."""
        if t is None or self.tested_at is None:
            return self.reliability
        return self.reliability * math.exp(-max(0.0, t - self.tested_at) / self.memory)

    def record(self, hit: bool, t: float | None, weight: float = 1.0) -> None:
        """One test of the model (``weight`` in [0, 1]: a partial observation counts partly)."""
        self.reliability += self.reliance * weight * ((1.0 if hit else 0.0) - self.reliability)
        if t is not None:
            self.tested_at = t
