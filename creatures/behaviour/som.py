"""Self-organising maps (Kohonen 1995, the thesis's [51]) on a grid: one of feature vectors,
one of BodyPoses (thesis "listen (installation)", "extensions"; figure captions 1 and 2 there).

"Two self-organising maps are used to simultaneously learn two distributions. Firstly, the
temporally local distribution of musical material and secondly a map of body movement derived
from an animation playing continuously in the background." Design decisions:

* **One grid, two maps** ("connected by strict topology to the pose SOM"): both maps share the
  grid, so a node of the music map and the node of the pose map at the same place are one
  music-pose pair. Training one map at a grid place and the other at the same place is what
  ties a note to a pose.
* **Constant plasticity and radius.** Textbook SOMs anneal both to converge on a stationary
  distribution presented in random order. The thesis wants the opposite: "we are interested
  in tracking *non-stationary* distributions – and seek to use the artifacts above as a memory
  of pose configuration", so the rate and the neighbourhood stay as authored and the map
  follows what is heard now, forgetting at that rate.
* **Plasticity per sample.** Each update takes its own rate: the caller scales it by the
  sample's salience ("SOM node plasticity can be connected to the saliency of note events").
* **Poses are unit quaternions per joint.** The distance is the sum over joints of
  ``1 - (q·p)²`` (sign-free: q and -q are one rotation; small angles give θ²/4), and a node
  moves toward a pose by normalised lerp after aligning signs, so nodes stay rotations.
  Vectorised over nodes and joints: a 6×6 map of a 31-joint body trains in a few µs.
"""

from __future__ import annotations

import numpy as np


def _grid(rows: int, cols: int) -> np.ndarray:
    """Each node's place on the grid ``(rows*cols, 2)``, row-major."""
    r, c = np.divmod(np.arange(rows * cols), cols)
    return np.stack([r, c], axis=1).astype(float)


class _Grid:
    """The shared topology: node places and the Gaussian neighbourhood around a winner."""

    def __init__(self, rows: int, cols: int, radius: float) -> None:
        if rows < 1 or cols < 1 or radius <= 0:
            raise ValueError(f"a map needs rows, cols >= 1 and radius > 0, got {rows}, {cols}, {radius}")
        self.rows, self.cols, self.radius = rows, cols, float(radius)
        places = _grid(rows, cols)
        squared = ((places[:, None, :] - places[None, :, :]) ** 2).sum(axis=2)
        self.neighbourhood = np.exp(-squared / (2 * self.radius**2))
        """``[winner, node]``: how much a node moves with the winner (1 at the winner)."""

    @property
    def size(self) -> int:
        return self.rows * self.cols


class SelfOrganisingMap(_Grid):
    """A map of feature vectors ``(nodes, dims)`` in Euclidean space."""

    def __init__(self, rows: int, cols: int, radius: float, vectors: np.ndarray) -> None:
        super().__init__(rows, cols, radius)
        vectors = np.array(vectors, dtype=float)
        if vectors.ndim != 2 or len(vectors) != self.size or not np.isfinite(vectors).all():
            raise ValueError(f"a {rows}×{cols} map needs {self.size} finite vectors, got shape {vectors.shape}")
        self.vectors = vectors

    @classmethod
    def spanning(cls, rows: int, cols: int, radius: float, low: np.ndarray, high: np.ndarray) -> SelfOrganisingMap:
        """Nodes laid out linearly between ``low`` and ``high``: the first two dimensions along
        the rows and the columns, the rest at their middle (Kohonen's linear initialisation:
        the map starts ordered, so it orders itself at once)."""
        low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
        places = _grid(rows, cols)
        span = np.repeat(0.5, len(low))[None, :].repeat(rows * cols, axis=0)
        span[:, 0] = places[:, 0] / max(rows - 1, 1)
        if len(low) > 1:
            span[:, 1] = places[:, 1] / max(cols - 1, 1)
        return cls(rows, cols, radius, low + span * (high - low))

    def distances(self, x: np.ndarray) -> np.ndarray:
        return np.sqrt(((self.vectors - x) ** 2).sum(axis=1))

    def winner(self, x: np.ndarray) -> tuple[int, float]:
        """The best-matching node and its distance (the sample's quantisation error)."""
        d = self.distances(x)
        best = int(np.argmin(d))
        return best, float(d[best])

    def train(self, x: np.ndarray, rate: float, at: int) -> float:
        """Move every node toward ``x`` by ``rate`` × its neighbourhood around node ``at``;
        returns how far the nodes moved in all."""
        step = (rate * self.neighbourhood[at])[:, None] * (x - self.vectors)
        self.vectors += step
        return float(np.sqrt((step**2).sum(axis=1)).sum())


def pose_distances(nodes: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Distance of each pose in ``nodes`` ``(N, J, 4)`` to ``rotations`` ``(J, 4)``: the sum over
    joints of ``1 - (q·p)²``."""
    dots = np.einsum("njk,jk->nj", nodes, rotations)
    return (1.0 - dots**2).sum(axis=1)


class PoseMap(_Grid):
    """A map of BodyPoses: each node holds one unit quaternion per joint ``(nodes, J, 4)``."""

    def __init__(self, rows: int, cols: int, radius: float, rotations: np.ndarray) -> None:
        super().__init__(rows, cols, radius)
        rotations = np.array(rotations, dtype=float)
        if rotations.ndim != 3 or rotations.shape[0] != self.size or rotations.shape[2] != 4 \
                or not np.isfinite(rotations).all():
            raise ValueError(f"a {rows}×{cols} pose map needs {self.size} finite poses (J, 4), "
                             f"got shape {rotations.shape}")
        norms = np.linalg.norm(rotations, axis=2, keepdims=True)
        if (norms < 1e-9).any():
            raise ValueError("a pose map's rotations must be non-zero quaternions")
        self.rotations = rotations / norms

    def winner(self, rotations: np.ndarray) -> tuple[int, float]:
        d = pose_distances(self.rotations, rotations)
        best = int(np.argmin(d))
        return best, float(d[best])

    def train(self, rotations: np.ndarray, rate: float, at: int) -> float:
        """Move every node toward the pose by ``rate`` × its neighbourhood around ``at`` (each
        joint by normalised lerp, signs aligned); returns how far the nodes moved in all (each
        node's quaternion components as one vector)."""
        signs = np.sign(np.einsum("njk,jk->nj", self.rotations, rotations))
        signs[signs == 0] = 1.0
        target = signs[:, :, None] * rotations[None, :, :]
        before = self.rotations
        moved = before + (rate * self.neighbourhood[at])[:, None, None] * (target - before)
        moved /= np.linalg.norm(moved, axis=2, keepdims=True)
        self.rotations = moved
        return float(np.sqrt(((moved - before) ** 2).sum(axis=(1, 2))).sum())
