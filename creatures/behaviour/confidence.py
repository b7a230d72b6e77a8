"""Confidence in a model (thesis: "expectations about value": "if a model has been wrong
recently, it should be less surprising if it is wrong again; secondly, if a model has not
been tested for a long time, then it should be less surprising if it just happens to be
wrong"). Shared by :class:`~creatures.behaviour.value.GaussianValue` and the action-tuple
expectations of :mod:`creatures.behaviour.expectation`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from creatures import bounds


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

    def state(self, t: float) -> dict[str, Any]:
        """JSON-able: the reliability and the seconds untested at ``t`` (not the clock time of
        the last test: a restarted run's clock starts again, so that time would be meaningless)."""
        return {"reliability": self.reliability,
                "untested": None if self.tested_at is None else max(0.0, t - self.tested_at)}

    def restore(self, data: Any, t: float, key: str) -> None:
        """Take back :meth:`state` at ``t``: as reliable, and untested as long, as it was
        saved (the time the creature was not running does not count). :class:`ValueError`
        naming ``key`` for a damaged entry, before anything changes."""
        data = bounds.table(data, key)
        reliability = bounds.number(data.get("reliability"), f"{key}.reliability", low=0.0, high=1.0)
        untested = data.get("untested")
        if untested is not None:
            untested = bounds.number(untested, f"{key}.untested", low=0.0, high=bounds.LATEST_TIME)
        self.reliability = reliability
        self.tested_at = None if untested is None else t - untested
