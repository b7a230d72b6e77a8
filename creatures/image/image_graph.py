"""The image graph: a tangled, directed graph of frames (thesis, "off-line image processing –
image creatures").

"From a low resolution sub-sampling (120 frames) of this video stream a tangled, directed
graph was created … The distance metric is based on the sum of the squared differences
between frames." Distances between every pair of frames would be "prohibitively expensive",
so, as the thesis did, only every ``subsample``-th frame (a *key*) is compared, at low
resolution, and "the in-between frames" are added back "to the graph … not too dissimilar to
the *spokes*": each in-between frame lies on the natural chain between two keys.

Edges:

* **natural**: frame ``f → f + 1``, costing the SSD between them (the footage as it ran);
* **jumps**: key ``a → b`` where the frame after ``a``'s key step looks like ``b`` (the motor
  graph's rule: a transition is good when where you would go next resembles where you jump
  to). Each key keeps its ``jumps`` best such edges, so the graph is tangled wherever the
  footage repeats itself (a turning cube, a statue returning to a pose). The footage's last
  frame, which has no next, jumps to the keys that look like it.

Every edge costs one *hop* plus its dissimilarity (SSD normalised by the median step between
neighbouring keys): the walk must reach the time its EDL names within a frame or two, so the
cheapest path is the one with few, well-matched transitions, as a film editor would cut.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from creatures.image.footage import Footage

LOW = (32, 24)
"""Width and height frames are compared at (the thesis's "low resolution sub-sampling")."""


LOW_CHUNK = 64
"""Frames made grey and small at a time: the whole footage as float32 grey was 4/3 of its own
size again at once (a 5-minute cube's graph peaked at 2.7 GB, an hour's would need 32 GB)."""


def low_resolution(frames: np.ndarray, size: tuple[int, int] = LOW) -> np.ndarray:
    """Frames as flat grey vectors at ``size`` (box-averaged), float32 in [0, 1]."""
    n, h, w, _ = frames.shape
    width, height = min(size[0], w), min(size[1], h)
    rows = np.linspace(0, h, height + 1).astype(int)
    cols = np.linspace(0, w, width + 1).astype(int)
    low = np.empty((n, height * width), np.float32)
    for start in range(0, n, LOW_CHUNK):
        grey = frames[start : start + LOW_CHUNK].astype(np.float32).mean(axis=3) / 255.0
        # box average: sums over row bands, then over column bands
        banded = np.add.reduceat(grey, rows[:-1], axis=1) / np.diff(rows)[None, :, None]
        boxed = np.add.reduceat(banded, cols[:-1], axis=2) / np.diff(cols)[None, None, :]
        low[start : start + LOW_CHUNK] = boxed.reshape(len(grey), -1)
    return low


def squared_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Sum of squared differences between every row of ``a`` and every row of ``b``."""
    d = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.maximum(d, 0.0)


@dataclass
class ImageGraph:
    """Frames as nodes (node ``f`` is footage frame ``f``), natural edges and key jumps."""

    count: int
    keys: np.ndarray  # frame indices of the keys
    matrix: csr_matrix  # (count, count) edge costs
    jumps: int  # jump edges in the graph

    @classmethod
    def build(cls, footage: Footage, *, subsample: int = 10, jumps: int = 3) -> "ImageGraph":
        if subsample < 1 or jumps < 0:
            raise ValueError(f"subsample must be ≥ 1 and jumps ≥ 0 (got {subsample}, {jumps})")
        low = low_resolution(footage.frames)
        n = len(low)
        natural = ((low[1:] - low[:-1]) ** 2).sum(1)
        keys = np.arange(0, n, subsample)
        key_steps = squared_distances(low[keys], low[keys])
        step = np.median(np.diag(key_steps, 1)) if len(keys) > 1 else 1.0
        scale = 1.0 / max(float(step), 1e-9)
        rows, cols, costs = [np.arange(n - 1)], [np.arange(1, n)], [1.0 + natural * scale]
        if jumps and len(keys) > 2:
            # from key a (all but the last), where a would be next (its following key) compared
            # with every key b; from the footage's final frame, which has no next, the keys that
            # look like it (so the walk can go on where the footage ends)
            origins = np.append(keys[:-1], n - 1)
            looks = np.vstack([key_steps[1:], squared_distances(low[n - 1:], low[keys])])
            looks[np.arange(len(keys) - 1), np.arange(1, len(keys))] = np.inf  # playing on: the chain
            looks[origins[:, None] == keys[None, :]] = np.inf  # no jump to itself
            best = np.argsort(looks, axis=1)[:, :jumps]
            finite = np.isfinite(np.take_along_axis(looks, best, 1))
            a = np.repeat(np.arange(len(origins)), jumps).reshape(len(origins), jumps)[finite]
            b = best[finite]
            rows.append(origins[a])
            cols.append(keys[b])
            costs.append(1.0 + looks[a, b] * scale)
        matrix = csr_matrix((np.concatenate(costs), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
        return cls(n, keys, matrix, int(sum(len(r) for r in rows[1:])))

    def path(self, start: int, goal: int) -> list[int] | None:
        """Nodes from ``start`` (excluded) to ``goal`` (included) by the cheapest edges; ``[]``
        when already there, None when the graph has no way (the walker then cuts)."""
        if start == goal:
            return []
        dist, previous = dijkstra(self.matrix, indices=start, return_predecessors=True)
        if not np.isfinite(dist[goal]):
            return None
        nodes = [goal]
        while previous[nodes[-1]] != start:
            nodes.append(int(previous[nodes[-1]]))
        return nodes[::-1]
