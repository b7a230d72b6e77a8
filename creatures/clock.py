"""One clock per run (DESIGN.md, "Time").

Everything that changes over time reads elapsed seconds from a clock object, never loop
counts: the WavesWorld lesson is that machine-dependent time makes behaviour run faster on
faster machines. Offline runs and tests use :class:`SimulatedClock`, advanced as fast as the
work allows; live runs use :class:`WallClock`.
"""

from __future__ import annotations

import time
from typing import Protocol


CLOCK_GAP = 1.0
"""Longest step of the clock between two ticks (or two audio blocks) that is still lived time,
in seconds: 25 to 50 ticks of any shipped piece (0.02–0.04 s), far beyond a late tick under
load. A longer step is a clock gap: the machine was suspended, a thread stalled, or an offline
run fast-forwarded its clock (``creatures.behaviour.action_group``, ``audio.segment``)."""


def clock_gap(expected: float, now: float) -> float:
    """Seconds the clock has jumped past ``expected`` (where a stream of ticks or samples
    would be by now), or 0 when it is within :data:`CLOCK_GAP` of it: what a stream that
    counts its own time (an ear counting samples) must skip to stay on the clock."""
    ahead = now - expected
    return ahead if ahead > CLOCK_GAP else 0.0


class Clock(Protocol):
    """Anything that can tell the current time in seconds since the run started."""

    def now(self) -> float: ...


class SimulatedClock:
    """A clock that only moves when told to, so runs are deterministic and fast."""

    def __init__(self, start: float = 0.0) -> None:
        self._t = float(start)

    def now(self) -> float:
        return self._t

    def advance(self, dt: float) -> float:
        """Move time forward by ``dt`` seconds (never backwards) and return the new time."""
        if not dt >= 0.0:
            raise ValueError(f"a clock cannot go backwards (dt={dt!r})")
        self._t += dt
        return self._t

    def advance_to(self, t: float) -> float:
        """Move time forward to ``t``; a ``t`` in the past is an error."""
        return self.advance(t - self._t)


class WallClock:
    """Monotonic real time, zeroed when the clock is made."""

    def __init__(self) -> None:
        self._t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self._t0


def next_on_grid(due: float, period: float, t: float) -> float:
    """When something done every ``period`` s is next due after being done at ``t``: on the grid
    of its previous due time while it keeps up (``t + period`` from a tick a hair early would skip
    every other 0.08 s report at a 0.04 s tick), from ``t`` after it fell behind or at the start."""
    return due + period if due + period > t + 1e-9 else t + period
