"""Neighbours from a spatial index (REACT 2.5.1, "KD-Trees": the organizer keeps the agents
pre-sorted in a kd-tree, and each agent asks it for its neighbourhood).

:class:`Neighbours` is rebuilt once per sub-step over the whole crowd (O(n log n)) and asked,
for the creatures that steer on that sub-step, for their ``k`` nearest within a radius
(O(log n) each), as fixed-width index arrays so the steering behaviours stay vectorised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class Neighbourhood:
    """For M asking creatures: ``index`` (M, k) of neighbours in the crowd, padded with ``n``
    (one past the end: index a crowd's rows with a zero row appended) where there are fewer
    than k, ``mask`` (M, k) of real ones, and their ``distance`` (M, k; inf where padded)."""

    index: np.ndarray
    mask: np.ndarray
    distance: np.ndarray


class Neighbours:
    """A kd-tree over the crowd's positions at one instant."""

    def __init__(self, pos: np.ndarray) -> None:
        self.n = len(pos)
        self.tree = cKDTree(pos)

    def near(self, who: np.ndarray, pos: np.ndarray, *, k: int, radius: float) -> Neighbourhood:
        """The ``k`` nearest others within ``radius`` of each creature ``who`` (indices into the
        crowd, at positions ``pos`` (M, 2)); a creature is never its own neighbour."""
        kk = min(k + 1, self.n)
        if kk == 0 or len(who) == 0:
            empty = np.zeros((len(who), k), dtype=np.intp)
            return Neighbourhood(empty + self.n, empty.astype(bool), np.full((len(who), k), np.inf))
        dist, index = self.tree.query(pos, k=kk, distance_upper_bound=radius)
        dist, index = dist.reshape(len(who), kk), index.reshape(len(who), kk)
        if (index[:, 0] == who).all():  # each is its own nearest (no two share a position)
            dist, index = dist[:, 1:], index[:, 1:]
        else:
            dist = np.where(index == who[:, None], np.inf, dist)
            order = np.argsort(dist, axis=1, kind="stable")[:, :k]
            dist = np.take_along_axis(dist, order, axis=1)
            index = np.take_along_axis(index, order, axis=1)
        mask = np.isfinite(dist)
        index = np.where(mask, index, self.n)
        if index.shape[1] < k:
            pad = k - index.shape[1]
            index = np.pad(index, ((0, 0), (0, pad)), constant_values=self.n)
            mask = np.pad(mask, ((0, 0), (0, pad)))
            dist = np.pad(dist, ((0, 0), (0, pad)), constant_values=np.inf)
        return Neighbourhood(index, mask, dist)
