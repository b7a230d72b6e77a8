"""Levels scripted as ``[seconds, level]`` points: linear between them, held outside.

A drive's scripted arc (``arc``) and a ``script`` percept (a visitor moving a rock) are read
every tick of every creature that has one, with a single time each: a bisection over the
points' own lists costs a fraction of ``np.interp``'s array round trip, and gives the same
number (the same slope, then the same product and sum).
"""

from __future__ import annotations

from bisect import bisect_right
from typing import Sequence


class Scripted:
    """Points ``[(time, level), …]`` with strictly increasing times, read at any time."""

    def __init__(self, points: Sequence[tuple[float, float]]) -> None:
        if not points:
            raise ValueError("a script needs at least one [time, level] point")
        self.times = [float(t) for t, _ in points]
        self.levels = [float(level) for _, level in points]

    def __call__(self, t: float) -> float:
        """The level at ``t``: linear between the points around it, the first or last outside."""
        i = bisect_right(self.times, t)
        if i == 0:
            return self.levels[0]
        if i == len(self.times):
            return self.levels[-1]
        t0, f0 = self.times[i - 1], self.levels[i - 1]
        slope = (self.levels[i] - f0) / (self.times[i] - t0)
        return slope * (t - t0) + f0
