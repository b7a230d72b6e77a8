"""Where a walking body has got to (thesis "graph-based motor systems": the graph's nodes are
poses wherever they were recorded; the travel is the source's own).

A walking body's graph keeps its poses in place and, per node, the horizontal step its source
takes to the next frame (:attr:`~creatures.motor.graph.MotorGraph.advances`). A step along a
source successor adds that step; any other edge (a jump between takes, a blend) adds nothing,
so the body turns or changes gait where it stands and never teleports to where a take was
recorded. Bodies on the shipped figures and bodies from files walk the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from creatures.motor.graph import MotorGraph


@dataclass(frozen=True)
class RootMotion:
    """Travel along paths: ``advances`` per node, ``successors`` its source's next node."""

    advances: np.ndarray  # (N, 3)
    successors: np.ndarray  # (N,)

    @classmethod
    def of(cls, graph: MotorGraph) -> "RootMotion | None":
        """The root motion on ``graph``, or None when nothing in it travels."""
        if not graph.advances.any():
            return None
        return cls(graph.advances, graph.timing.next_frame)

    def along(self, before: int, nodes: np.ndarray, fraction: float = 0.0) -> np.ndarray:
        """Travel ``(K + 1, 3)`` at the start position (node ``before``, ``fraction`` on toward
        ``nodes[0]``) and at each of the ``K`` path nodes, relative to the start."""
        nodes = np.asarray(nodes, dtype=np.int64)
        previous = np.concatenate(([before], nodes[:-1]))
        steps = np.where((self.successors[previous] == nodes)[:, None], self.advances[previous], 0.0)
        steps[0] *= 1.0 - fraction
        return np.concatenate((np.zeros((1, 3)), np.cumsum(steps, axis=0)))
