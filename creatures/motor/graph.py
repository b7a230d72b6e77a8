"""MotorGraph: the directed, weighted graph of BodyPoses (thesis "graph-based motor systems").

Nodes are the key-frames of the source animations (a :class:`PoseSet`); edges come from
*automatic topology generation* — each pose joins its ``k`` nearest poses under the
:mod:`~creatures.motor.metric` plus its successor in its own source animation. The graph
can then be *re-edited* as the thesis describes: edges forbidden (and never re-forged),
forged, reweighted, whole nodes favoured or disfavoured (a multiplier on their outgoing
edges), and new material added as nodes.

Searching needs compact arrays, so the graph keeps its edges as a CSR adjacency
(``indptr``/``indices``/``costs``), rebuilt lazily after edits. It saves as diffable JSON
through :mod:`creatures.persist`: one short object per node (a line per field, so an edit
to one node's favour or labels is a small diff) and one line per edge; reading it back is
checked element by element (:mod:`~creatures.motor.graph_file`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from creatures.motor import metric
from creatures.motor.metric import MetricWeights
from creatures.motor.neighbours import nearest_edge_arrays, nearest_edges
from creatures.motor.pose import LOW_ENERGY, PoseSet
from creatures.motor.graph_file import read_graph
from creatures.motor.skeleton import Skeleton
from creatures.persist import load_json, save_json

KIND = "motor-graph"


@dataclass(frozen=True)
class Adjacency:
    """CSR view of the edges: out-edges of node ``n`` are ``indptr[n]:indptr[n+1]``.

    Plain arrays because the compiled A* kernel (:mod:`creatures.motor.search`) and
    scipy's graph routines both read exactly this layout.
    """

    indptr: np.ndarray
    indices: np.ndarray
    costs: np.ndarray


class MotorGraph:
    """BodyPose nodes, weighted edges, animator edits and a cached CSR adjacency."""

    def __init__(
        self,
        poses: PoseSet,
        edges: dict[tuple[int, int], float],
        *,
        weights: MetricWeights | None = None,
        scales: dict[tuple[int, int], float] | None = None,
        forbidden: set[tuple[int, int]] | None = None,
        favour: np.ndarray | None = None,
        advances: np.ndarray | None = None,
    ) -> None:
        self.poses = poses
        self.weights = weights or MetricWeights()
        self._edge_dict: dict[tuple[int, int], float] | None = dict(edges)
        self._edge_arrays: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._scales = dict(scales or {})
        self.forbidden = set(forbidden or ())
        self.favour = np.ones(len(poses)) if favour is None else np.asarray(favour, dtype=float)
        self.advances = np.zeros((len(poses), 3)) if advances is None else np.asarray(advances, dtype=float)
        """Per node, the horizontal step its source takes to its next frame: a walking body's
        root motion (:func:`~creatures.motor.material.walking_in_place`); zero for a fixed root."""
        self._adjacency: Adjacency | None = None
        self._timing: metric.Timing | None = None
        self.version = 0
        self.landmark_tables: Any = None
        """A* landmark distances made for this graph (:class:`~creatures.motor.search.LandmarkTables`,
        kept with it in a body's cache so a restart does not search the whole graph again);
        valid for the version they name, so any edit retires them."""

    # --- construction ---------------------------------------------------------------------

    @classmethod
    def build(
        cls, poses: PoseSet, *, k: int = 6, weights: MetricWeights | None = None, oversample: int = 3
    ) -> MotorGraph:
        """Automatic topology: each pose to its ``k`` nearest poses plus its source successor.

        The nearest are exact up to :data:`~creatures.motor.neighbours.EXACT_BELOW` poses
        and found among ``oversample × k`` KD-tree candidates beyond
        (:mod:`~creatures.motor.neighbours`). Every edge then gets its reverse and separate
        islands are bridged (see :meth:`_complete`), so the body can never be stranded in a
        corner of the graph.
        """
        weights = weights or MetricWeights()
        graph = cls(poses, {}, weights=weights)
        a, b, costs = nearest_edge_arrays(poses, np.arange(len(poses)), np.arange(len(poses)), k, weights, oversample)
        graph._edge_dict, graph._edge_arrays = None, (a, b, costs, np.ones(len(a)))
        graph._complete()
        return graph

    @property
    def _base(self) -> dict[tuple[int, int], float]:
        """Base edge costs by ``(from, to)``. A graph read from the binary cache keeps its edges
        as arrays until something asks for the dict (an edit, a listing): half a million edge
        tuples were most of a cached reload, and search needs only the arrays."""
        if self._edge_dict is None:
            a, b, costs, _ = self._edge_arrays
            self._edge_dict = dict(zip(zip(a.tolist(), b.tolist()), costs.tolist()))
            self._edge_arrays = None
        return self._edge_dict

    @_base.setter
    def _base(self, edges: dict[tuple[int, int], float]) -> None:
        self._edge_dict, self._edge_arrays = edges, None

    @property
    def skeleton(self) -> Skeleton:
        return self.poses.skeleton

    def __len__(self) -> int:
        return len(self.poses)

    def edges(self) -> dict[tuple[int, int], float]:
        """Current edge costs (base metric × edge scale × node favour)."""
        return {
            (a, b): cost * self._scales.get((a, b), 1.0) * float(self.favour[a])
            for (a, b), cost in self._base.items()
        }

    def has_edge(self, a: int, b: int) -> bool:
        if self._edge_dict is None:
            return self._adjacent(a, b) is not None
        return (a, b) in self._base

    def _adjacent(self, a: int, b: int) -> int | None:
        """Where ``a → b`` is in the CSR adjacency (None: no such edge); a graph still in arrays
        answers without a dict of its half-million edges."""
        if not (0 <= a < len(self.poses)):
            return None
        adj = self.adjacency
        lo = int(adj.indptr[a])
        at = np.flatnonzero(adj.indices[lo:int(adj.indptr[a + 1])] == b)
        return lo + int(at[0]) if at.size else None

    # --- editing ("re-editing animation data") --------------------------------------------

    def forbid(self, a: int, b: int) -> None:
        """Remove ``a → b`` and refuse to forge it again (e.g. a self-penetrating blend)."""
        self._check_nodes(a, b)
        self._base.pop((a, b), None)
        self._scales.pop((a, b), None)
        self.forbidden.add((a, b))
        self._changed()

    def connect(self, a: int, b: int, cost: float | None = None) -> None:
        """Forge ``a → b`` with ``cost`` (default: the metric); lifts a previous ban."""
        self._check_nodes(a, b)
        if a == b:
            raise ValueError(f"a motor graph edge joins two different nodes (got {a} → {a})")
        if cost is None:
            cost = float(metric.edge_costs(self.poses, np.array([a]), np.array([b]), self.weights)[0])
        if not (math.isfinite(cost) and cost >= 0.0):
            raise ValueError(f"edge cost must be finite and non-negative (got {cost!r})")
        self.forbidden.discard((a, b))
        self._base[(a, b)] = float(cost)
        self._changed()

    def reweight(self, a: int, b: int, scale: float) -> None:
        """Multiply the cost of ``a → b`` by ``scale`` (makes the route less or more likely)."""
        if (a, b) not in self._base:
            raise KeyError(f"no edge {a} → {b}")
        if not (math.isfinite(scale) and scale > 0.0):
            raise ValueError(f"edge scale must be finite and positive (got {scale!r})")
        self._scales[(a, b)] = float(scale)
        self._changed()

    def set_favour(self, node: int, multiplier: float) -> None:
        """Scale all of ``node``'s outgoing edges: < 1 favours the node, > 1 avoids it."""
        self._check_nodes(node)
        if not (math.isfinite(multiplier) and multiplier > 0.0):
            raise ValueError(f"favour multiplier must be finite and positive (got {multiplier!r})")
        self.favour[node] = multiplier
        self._changed()

    def copy(self) -> MotorGraph:
        """An independent graph with the same nodes, edges and edits: a body that learns new
        material at run time (complex shaping) edits its own copy, never a graph its kind shares."""
        p = self.poses
        poses = PoseSet(p.skeleton, p.rotations.copy(), p.velocities.copy(), p.roots.copy(), p.times.copy(),
                        p.source_ids.copy(), list(p.sources), list(p.labels), p.positions.copy())
        graph = MotorGraph(poses, self._base, weights=self.weights, scales=self._scales, forbidden=self.forbidden,
                           favour=self.favour.copy())
        graph._timing = self._timing
        return graph

    def add_poses(self, material: PoseSet, *, k: int = 6, oversample: int = 3) -> np.ndarray:
        """Patch new material into the graph (edit form 4); returns the new node indices.

        New nodes join their ``k`` nearest nodes (old or new) in both directions, and their
        own successors; existing edges are kept.
        """
        first = len(self.poses)
        self.poses = PoseSet.concatenate([self.poses, material])
        self._timing = None
        new = np.arange(first, len(self.poses))
        self.favour = np.concatenate((self.favour, np.ones(len(new))))
        self.advances = np.concatenate((self.advances, np.zeros((len(new), 3))))
        found = nearest_edges(self.poses, new, np.arange(len(self.poses)), k, self.weights, oversample)
        self._base.update({edge: cost for edge, cost in found.items() if edge not in self.forbidden})
        self._complete()
        return new

    def reconnect(self) -> None:
        """After edits (a forbidden edge can cut an island off): reverse edges and bridges
        again, never re-forging a forbidden edge (see :meth:`_complete`)."""
        self._complete()

    def _complete(self) -> None:
        """Give every edge its reverse, then bridge islands until the graph is strongly connected.

        The thesis notes a missing connection "might not be *that* bad" because the body can
        always interpolate across it; bridging makes that edge explicit. Each island joins
        the pose nearest to it (pose term on the metric's content, sampled) elsewhere, in both
        directions. Forbidden edges are never re-forged.
        """
        self._add_reverses()
        self._changed()
        rng = np.random.default_rng(0)
        while True:
            adj = self.adjacency
            n = len(self.poses)
            count, component = connected_components(
                csr_matrix((adj.costs, adj.indices, adj.indptr), shape=(n, n)), directed=True, connection="strong"
            )
            if count == 1:
                return
            smallest = np.argmin(np.bincount(component))
            inside = np.flatnonzero(component == smallest)
            outside = np.flatnonzero(component != smallest)
            inside = rng.choice(inside, min(len(inside), 200), replace=False)
            outside = rng.choice(outside, min(len(outside), 2000), replace=False)
            gap = metric.pose_gap(self.poses, inside, outside, self.weights)
            for flat in np.argsort(gap, axis=None):
                i, j = np.unravel_index(flat, gap.shape)
                a, b = int(inside[i]), int(outside[j])
                if (a, b) not in self.forbidden and (b, a) not in self.forbidden:
                    break
            else:
                raise ValueError("cannot connect the motor graph: every bridge is forbidden")
            pair = np.array([a, b])
            costs = metric.edge_costs(self.poses, pair, pair[::-1], self.weights)
            self._set_edge(a, b, float(costs[0]))
            self._set_edge(b, a, float(costs[1]))
            self._changed()

    def _add_reverses(self) -> None:
        """Every edge's reverse (at the metric's cost) where it is missing and not forbidden."""
        if self._edge_dict is not None:
            missing = [(b, a) for (a, b) in self._base if (b, a) not in self._base and (b, a) not in self.forbidden]
            missing = np.array(missing, dtype=np.int64).reshape(-1, 2)
            if len(missing):
                costs = metric.edge_costs(self.poses, missing[:, 0], missing[:, 1], self.weights)
                self._base.update(zip(map(tuple, missing.tolist()), costs.tolist()))
            return
        # The same on the arrays (a freshly built or cached graph): edges as codes a·n + b.
        a, b, costs, scales = self._edge_arrays
        n = len(self.poses)
        missing = ~np.isin(b * n + a, a * n + b)
        if self.forbidden:
            banned = np.array([x * n + y for x, y in self.forbidden], dtype=np.int64)
            missing &= ~np.isin(b * n + a, banned)
        if missing.any():
            fresh = metric.edge_costs(self.poses, b[missing], a[missing], self.weights)
            self._edge_arrays = (np.concatenate((a, b[missing])), np.concatenate((b, a[missing])),
                                 np.concatenate((costs, fresh)), np.concatenate((scales, np.ones(len(fresh)))))

    def _set_edge(self, a: int, b: int, cost: float) -> None:
        """Base cost of ``a → b`` (a new edge, or a new cost for an existing one), in either store."""
        if self._edge_dict is not None:
            self._base[(a, b)] = cost
            return
        froms, tos, costs, scales = self._edge_arrays
        at = np.flatnonzero((froms == a) & (tos == b))
        if at.size:
            costs = costs.copy()
            costs[at] = cost
            self._edge_arrays = (froms, tos, costs, scales)
        else:
            self._edge_arrays = (np.append(froms, a), np.append(tos, b), np.append(costs, cost), np.append(scales, 1.0))

    def label(self, node: int, label: str) -> None:
        """Attach ``label`` to ``node`` (e.g. an animator marking a low-energy state)."""
        self._check_nodes(node)
        self.poses.labels[node] = self.poses.labels[node] | {label}
        self._changed()

    def annotate_low_energy(self, *, speed: float = 0.05, label: str = LOW_ENERGY) -> np.ndarray:
        """Label near-still poses (mass-weighted joint speed below ``speed`` rad/s) as low energy."""
        masses = self.skeleton.masses
        still = np.linalg.norm(self.poses.velocities, axis=-1) @ masses / masses.sum() < speed
        nodes = np.flatnonzero(still)
        for node in nodes:
            self.poses.labels[node] = self.poses.labels[node] | {label}
        self._changed()
        return nodes

    def _check_nodes(self, *nodes: int) -> None:
        for node in nodes:
            if not 0 <= node < len(self.poses):
                raise IndexError(f"no node {node} (graph has {len(self.poses)} nodes)")

    def _changed(self) -> None:
        self._adjacency = None
        self.version += 1

    # --- compact arrays for search --------------------------------------------------------

    @property
    def adjacency(self) -> Adjacency:
        """CSR adjacency of the current edges (cached until the next edit)."""
        if self._adjacency is None:
            if self._edge_dict is None:  # straight from the cached arrays
                a, b, base, scales = self._edge_arrays
                pairs, costs = np.stack((a, b), axis=1), base * scales * self.favour[a]
            else:
                edges = self.edges()
                pairs = np.array(list(edges), dtype=np.int64).reshape(-1, 2)
                costs = np.fromiter(edges.values(), dtype=float, count=len(edges))
            order = np.lexsort((pairs[:, 1], pairs[:, 0]))
            pairs, costs = pairs[order], costs[order]
            indptr = np.zeros(len(self.poses) + 1, dtype=np.int64)
            np.cumsum(np.bincount(pairs[:, 0], minlength=len(self.poses)), out=indptr[1:])
            self._adjacency = Adjacency(indptr, pairs[:, 1].copy(), costs)
        return self._adjacency

    @property
    def timing(self) -> metric.Timing:
        """Successors and speed limits of the poses (cached until poses are added: it walks
        every fast source step's squad curve, ~0.3 s at 10,000 nodes, and no other edit changes it)."""
        if self._timing is None:
            self._timing = metric.Timing.of(self.poses)
        return self._timing

    def transit_times(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Seconds to move ``a[i] → b[i]`` (:func:`metric.transit_time`, with cached inputs)."""
        return metric.transit_time(self.poses, a, b, self.weights, self.timing)

    def edge_cost(self, a: int, b: int) -> float:
        """Current cost of ``a → b`` (KeyError when there is no such edge)."""
        if self._edge_dict is None:
            at = self._adjacent(a, b)
            if at is None:
                raise KeyError(f"no edge {a} → {b}")
            return float(self.adjacency.costs[at])
        if (a, b) not in self._base:
            raise KeyError(f"no edge {a} → {b}")
        return self._base[(a, b)] * self._scales.get((a, b), 1.0) * float(self.favour[a])

    # --- persistence ----------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """Diffable plain data: one string per node and per edge, sorted."""
        p = self.poses
        nodes = [
            {
                "source": p.sources[p.source_ids[i]],
                "time": float(p.times[i]),
                "labels": sorted(p.labels[i]),
                "root": _floats(p.roots[i]),
                "rotations": _floats(p.rotations[i]),
                "velocities": _floats(p.velocities[i]),
                **({"favour": float(self.favour[i])} if self.favour[i] != 1.0 else {}),
            }
            for i in range(len(p))
        ]
        edges = [
            f"{a} {b} {cost!r} {self._scales.get((a, b), 1.0)!r}" for (a, b), cost in sorted(self._base.items())
        ]
        return {
            "skeleton": self.skeleton.to_dict(),
            "weights": self.weights.to_dict(),
            "nodes": nodes,
            "edges": edges,
            "forbidden": [f"{a} {b}" for a, b in sorted(self.forbidden)],
        }

    def edges_arrays(self) -> dict[str, np.ndarray]:
        """The edges as arrays (``edge_from``, ``edge_to``, ``edge_cost``, ``edge_scale``): the
        binary cache's layout (:mod:`~creatures.motor.body_build`)."""
        if self._edge_dict is None:
            return dict(zip(("edge_from", "edge_to", "edge_cost", "edge_scale"), self._edge_arrays))
        pairs = np.array(list(self._base), dtype=np.int64).reshape(-1, 2)
        costs = np.fromiter(self._base.values(), dtype=float, count=len(self._base))
        scales = np.array([self._scales.get(edge, 1.0) for edge in self._base], dtype=float)
        return {"edge_from": pairs[:, 0], "edge_to": pairs[:, 1], "edge_cost": costs, "edge_scale": scales}

    @classmethod
    def from_arrays(cls, poses: PoseSet, data: Any, *, weights: MetricWeights | None = None) -> MotorGraph:
        """A graph from :meth:`edges_arrays` plus ``favour``, ``forbidden``, ``advances`` and ``speeds``
        (:attr:`timing`'s typical and top speed, which take seconds to measure on a long take)
        arrays, every array checked (ValueError names the first problem): a damaged cache must
        not become a wrong body."""
        n, joints = len(poses), poses.skeleton.joint_count
        if poses.rotations.shape != (n, joints, 4) or poses.velocities.shape != (n, joints, 3):
            raise ValueError(f"pose arrays do not fit a {joints}-joint skeleton")
        for name in ("rotations", "velocities", "roots", "times", "positions"):
            if not np.all(np.isfinite(getattr(poses, name))):
                raise ValueError(f"non-finite {name}")
        a, b = np.asarray(data["edge_from"]), np.asarray(data["edge_to"])
        costs, scales = np.asarray(data["edge_cost"], dtype=float), np.asarray(data["edge_scale"], dtype=float)
        favour = np.asarray(data["favour"], dtype=float)
        forbidden = np.asarray(data["forbidden"]).reshape(-1, 2)
        if not (a.shape == b.shape == costs.shape == scales.shape and a.ndim == 1 and favour.shape == (n,)):
            raise ValueError("edge arrays disagree in length")
        for name, nodes in (("edge", np.concatenate((a, b))), ("forbidden", forbidden.ravel())):
            if nodes.size and not (nodes.dtype.kind == "i" and nodes.min() >= 0 and nodes.max() < n):
                raise ValueError(f"{name} names a node outside 0..{n - 1}")
        if not (np.all(np.isfinite(costs) & (costs >= 0)) and np.all(np.isfinite(scales) & (scales > 0))
                and np.all(np.isfinite(favour) & (favour > 0))):
            raise ValueError("edge costs, scales or favours out of range")
        advances = np.asarray(data["advances"], dtype=float)
        if not (advances.shape == (n, 3) and np.all(np.isfinite(advances))):
            raise ValueError("root-motion steps do not fit the poses")
        scaled = np.flatnonzero(scales != 1.0)
        graph = cls(poses, {}, weights=weights, advances=advances,
                    scales={(int(a[i]), int(b[i])): float(scales[i]) for i in scaled},
                    forbidden={(int(x), int(y)) for x, y in forbidden.tolist()}, favour=favour)
        graph._edge_dict, graph._edge_arrays = None, (a.astype(np.int64), b.astype(np.int64), costs, scales)
        speeds = np.asarray(data["speeds"], dtype=float)
        if not (speeds.shape == (2,) and np.all(np.isfinite(speeds) & (speeds > 0))):
            raise ValueError("speeds must be two positive numbers")
        graph._timing = metric.Timing(metric.successors(poses), float(speeds[0]), float(speeds[1]))
        return graph

    def save(self, path: str | os.PathLike) -> None:
        """Write the graph atomically as JSON (``creatures.persist``)."""
        save_json(path, self.to_dict(), kind=KIND)

    @classmethod
    def load(cls, path: str | os.PathLike) -> MotorGraph:
        """Read a graph saved by :meth:`save`; errors name the file and the offending line."""
        path = Path(path)
        document = load_json(path, kind=KIND)
        return cls.from_dict(document, source=str(path), text=path.read_text(encoding="utf-8"))

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "<motor graph>", text: str = "") -> MotorGraph:
        """Build from :meth:`to_dict` data, checked element by element (:mod:`~creatures.motor.graph_file`)."""
        parts = read_graph(data, source=source, text=text)
        return cls(
            parts.poses,
            parts.edges,
            weights=parts.weights,
            scales=parts.scales,
            forbidden=parts.forbidden,
            favour=parts.favour,
        )


def _floats(array: np.ndarray) -> str:
    return " ".join(f"{x:.9g}" for x in np.ravel(array))
