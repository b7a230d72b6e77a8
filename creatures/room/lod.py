"""Level of detail for crowds (REACT's organizer updates only what is dirty; IViHumans'
distant characters act at lower rates; the issue: "distant or unheard creatures perceive,
decide and move at lower rates"): a creature far from every visitor steers less often, one no
listener hears (``unheard``: silent, or its note under the hearing threshold at the nearest
listener) less often still, and no more than a budget of creatures steer on one sub-step.

A creature at level L steers (perceives its neighbours, decides its force) once every 2**L
sub-steps and holds that force between; every creature still moves every sub-step, because
the integrator's few array operations over the whole crowd cost less than sorting out who moves.
With ``decide`` its behaviour (percepts, action selection, its actions' ticks) runs once every
2**L ticks too, within ``decide_budget`` creatures a tick (:meth:`Stage.deciding`): hearing
still reaches it every tick, so nothing it hears is lost, only answered later.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

if TYPE_CHECKING:
    from creatures.room.hearing import DistanceLaw


@dataclass(frozen=True)
class Audibility:
    """Whether a listener hears a creature: its note's level (dB re velocity 127 at the
    reference distance) after the room's distance ``law``, against the hearing ``threshold``
    ([room.hearing], the one the creatures' own ears use)."""

    law: "DistanceLaw"
    threshold: float

    def heard(self, loudness: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """(N,) bool: sounding at ``loudness`` dB (−inf: silent), heard ``distance`` m away."""
        return loudness + self.law.db(distance) >= self.threshold


class Sounding:
    """What each creature sounds now, for :attr:`LevelOfDetail.unheard`: its latest note's
    level (dB re velocity 127) and span (told by :meth:`play` as the creature plays)."""

    def __init__(self, n: int) -> None:
        self.db = np.full(n, -np.inf)
        self.start = np.full(n, np.inf)
        self.end = np.full(n, -np.inf)

    def play(self, i: int, start: float, end: float, db: float) -> None:
        self.db[i], self.start[i], self.end[i] = db, start, end

    def loudness(self, t: float) -> np.ndarray:
        """(N,) each creature's level at ``t``, dB: its note's while it sounds, else −inf."""
        return np.where((self.start <= t) & (t < self.end), self.db, -np.inf)


@dataclass(frozen=True)
class LevelOfDetail:
    """``near`` m: within it a creature steers every sub-step; each further ``near`` m halves
    its rate, down to once in 2**``levels`` sub-steps. ``budget``: most creatures steering per
    sub-step (the farthest due ones wait; None = no limit). ``unheard``: levels added for a
    creature the nearest listener does not hear (0 = by distance alone)."""

    near: float = 4.0
    levels: int = 3
    budget: int | None = None
    unheard: int = 0

    @property
    def replan(self) -> int:
        """Sub-steps between two plannings of the levels: the slowest level's period, so every
        creature is due at least once under each plan (the levels change as slowly as people
        walk; a tree query of every creature per sub-step would cost more than it buys)."""
        return 1 << self.levels

    def level(self, pos: np.ndarray, listeners: np.ndarray, loudness: np.ndarray | None = None,
              audibility: Audibility | None = None) -> np.ndarray:
        """Each creature's level from its distance to the nearest listener (the visitors and
        out.wav's listening point: a creature far from all of them is neither seen nor heard
        closely), ``unheard`` levels more where that listener does not hear it by
        ``audibility`` (``loudness``: each one's note now, dB, −inf when silent; None: not
        asked); with no listener at all, every creature at the slowest level."""
        if len(listeners) == 0:
            return np.full(len(pos), self.levels, dtype=np.int64)
        d, _ = cKDTree(listeners).query(pos)
        level = (d // self.near).astype(np.int64)
        if self.unheard and audibility is not None and loudness is not None:
            level += self.unheard * ~audibility.heard(loudness, d)
        return np.clip(level, 0, self.levels)

    def due(self, step: int, level: np.ndarray, last: np.ndarray) -> np.ndarray:
        """Indices of the creatures that steer on sub-step ``step``: those whose phase comes
        round (creature i at level L when (step + i) % 2**L == 0, so a level's creatures are
        spread over its sub-steps) and those a full budget made miss theirs (``last``: the
        sub-step each last steered), cut to the budget by :func:`overdue_first`."""
        period = np.left_shift(1, level)
        waited = step - last
        due = np.nonzero(((step + np.arange(len(level))) % period == 0) | (waited > period))[0]
        return overdue_first(due, waited, period, level, step, self.budget)


def overdue_first(due: np.ndarray, waited: np.ndarray, period: np.ndarray, level: np.ndarray, turn: int,
                  budget: int | None) -> np.ndarray:
    """The ``due`` creatures (sorted indices) cut to ``budget``: the most overdue (waited /
    period) first, the nearer level on a tie, then in turn (``turn``, the step or tick number,
    rotates who goes first among equals). So a creature cut once is first in line the next
    time and none starves; ranking equals by index left the highest indices of a full
    level waiting for ever."""
    if budget is None or len(due) <= budget:
        return due
    order = np.lexsort(((due + turn) % len(waited), level[due], -waited[due] / period[due]))
    return np.sort(due[order[:budget]])
