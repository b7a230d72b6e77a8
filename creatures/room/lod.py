"""Level of detail for crowds (REACT's organizer updates only what is dirty; IViHumans'
distant characters act at lower rates): a creature far from every visitor steers less often,
and no more than a budget of creatures steer on one sub-step.

A creature at level L steers (perceives its neighbours, decides its force) once every 2**L
sub-steps and holds that force between; every creature still moves every sub-step, because
the integrator's few array operations over the whole crowd cost less than sorting out who moves.
With ``decide`` its behaviour (percepts, action selection, its actions' ticks) runs once every
2**L ticks too, within ``decide_budget`` creatures a tick (:meth:`Stage.deciding`): hearing
still reaches it every tick, so nothing it hears is lost, only answered later.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class LevelOfDetail:
    """``near`` m: within it a creature steers every sub-step; each further ``near`` m halves
    its rate, down to once in 2**``levels`` sub-steps. ``budget``: most creatures steering per
    sub-step (the farthest due ones wait; None = no limit)."""

    near: float = 4.0
    levels: int = 3
    budget: int | None = None

    def level(self, pos: np.ndarray, listeners: np.ndarray) -> np.ndarray:
        """Each creature's level from its distance to the nearest listener (the visitors and
        out.wav's listening point: a creature far from all of them is neither seen nor heard
        closely); with no listener at all, every creature at the slowest level."""
        if len(listeners) == 0:
            return np.full(len(pos), self.levels, dtype=np.int64)
        d, _ = cKDTree(listeners).query(pos)
        return np.clip((d // self.near).astype(np.int64), 0, self.levels)

    def due(self, step: int, level: np.ndarray, distance_rank: np.ndarray) -> np.ndarray:
        """Indices of the creatures that steer on sub-step ``step``: those whose phase comes
        round (creature i at level L when (step + i) % 2**L == 0, so a level's creatures are
        spread over its sub-steps), cut to the budget nearest first (``distance_rank``: lower
        = nearer)."""
        period = np.left_shift(1, level)
        due = np.nonzero((step + np.arange(len(level))) % period == 0)[0]
        if self.budget is not None and len(due) > self.budget:
            due = np.sort(due[np.argsort(distance_rank[due], kind="stable")[: self.budget]])
        return due
