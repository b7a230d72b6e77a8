"""The tile graph: tiles as nodes, the successions a layer may make as edges, and A* to the
nearest tile with a tag (thesis, "(void *)": "only the very lowest level representation (the
content and metrics for BodyPose) need be changed for the new motor system to produce notes";
"towards a complete motor system: moving around the graph").

The metric is the musical one a film composer splices by: one step costs 1, plus how far the
next tile's key is round the circle of fifths from this one's (``key_weight`` per six fifths),
plus how far its opening notes lie from this one's closing notes (``voice_weight`` per octave
of mean movement). A succession the composer wrote (``follows``) costs ``favour`` times as
much. Each tile keeps its ``k`` cheapest successors in its layer and every written one, so the
graph stays sparse and a walk prefers smooth joins, as the motor graph keeps only its
k nearest transitions; a silent tile (a tacet) joins every tile of its layer both ways. A tile
follows itself only where the composer wrote so (``follows`` naming it: a vamp, a held bar).

A tile file is small (tens to hundreds of tiles), so the exact distances between every pair
are computed once (scipy's Dijkstra) and serve A* as its heuristic: admissible and exact, A*
then expands only the tiles of the path it returns, well inside the issue's 1 ms per tile.
"""

from __future__ import annotations

import heapq

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from creatures.motor.search import NoPath
from creatures.score.tiles import Tile, TileSet
from midi.fifths import STEPS, circular_distance


def voice_leading(closing: np.ndarray, opening: np.ndarray) -> float:
    """Mean semitones each opening note lies from the nearest closing note (0 if either is silent)."""
    if not len(closing) or not len(opening):
        return 0.0
    return float(np.abs(opening[:, None] - closing[None, :]).min(axis=1).mean())


class TileGraph:
    """Edges between the tiles of each layer, their costs, and shortest paths."""

    def __init__(self, tiles: TileSet, *, k: int = 4, key_weight: float = 1.0, voice_weight: float = 1.0,
                 favour: float = 0.4) -> None:
        self.tiles = tiles
        n = len(tiles)
        keys = [t.key() for t in tiles.tiles]
        cost = np.full((n, n), np.inf)
        for a, ta in enumerate(tiles.tiles):
            for b, tb in enumerate(tiles.tiles):
                if ta.layer == tb.layer and (a != b or ta.name in ta.follows):
                    cost[a, b] = self.metric(ta, tb, keys[a], keys[b], key_weight, voice_weight)
        # A silence joins anything: after a tacet any tile may start, and any may stop into one.
        silent = np.array([t.silent for t in tiles.tiles])
        keep = np.isfinite(cost) & (silent[:, None] | silent[None, :])
        for a, ta in enumerate(tiles.tiles):
            order = np.argsort(cost[a], kind="stable")
            keep[a, order[:k]] = np.isfinite(cost[a, order[:k]])
            for name in ta.follows:
                b = tiles.index(name)
                keep[a, b] = True
                cost[a, b] *= favour
        self.cost = np.where(keep, cost, np.inf)
        self.successors = [np.flatnonzero(keep[a]) for a in range(n)]
        rows, cols = np.nonzero(keep)
        graph = csr_matrix((np.maximum(self.cost[rows, cols], 1e-9), (rows, cols)), shape=(n, n))
        self.distance = dijkstra(graph, directed=True)
        self._goals: dict[str, np.ndarray] = {}

    @staticmethod
    def metric(a: Tile, b: Tile, key_a: np.ndarray, key_b: np.ndarray, key_weight: float,
               voice_weight: float) -> float:
        """Cost of following ``a`` with ``b`` (see the module docstring)."""
        key = 0.0 if a.silent or b.silent else circular_distance(key_a, key_b) / (STEPS / 2)
        return 1.0 + key_weight * key + voice_weight * voice_leading(a.closing(), b.opening()) / 12.0

    def goals(self, tag: str) -> np.ndarray:
        """The tiles that carry ``tag``."""
        if tag not in self._goals:
            self._goals[tag] = np.array([i for i, t in enumerate(self.tiles.tiles) if tag in t.tags], dtype=np.intp)
        return self._goals[tag]

    def walk(self, start: int | None, layer: str, tags: list[str], *, furthest: bool = False) -> list[int]:
        """The tiles from ``start`` (excluded; None: a layer with nothing laid yet) to the
        nearest tile of ``layer`` carrying any of ``tags`` — or, ``furthest``, to the one
        farthest by the metric that can still be reached (the motor programs' getToFurthest)."""
        goals = np.unique(np.concatenate([self.goals(tag) for tag in tags]))
        goals = goals[[self.tiles.tiles[g].layer == layer for g in goals]] if len(goals) else goals
        if not len(goals):
            raise NoPath(f"layer {layer!r} has no tile tagged {' or '.join(map(repr, tags))}")
        if start is None:
            return [int(goals[0])]
        if furthest:
            reach = self.distance[start, goals]
            if not np.isfinite(reach).any():
                raise NoPath(f"no succession from tile {self.tiles.tiles[start].name!r} reaches {tags}")
            goals = goals[[int(np.argmax(np.where(np.isfinite(reach), reach, -np.inf)))]]
        return self.path(start, goals)

    def path(self, start: int, goals: np.ndarray) -> list[int]:
        """The cheapest walk of at least one step from tile ``start`` to any of ``goals``
        (its tiles after ``start``); :class:`~creatures.motor.search.NoPath` if there is none."""
        bound = self.distance[:, goals].min(axis=1)
        is_goal = np.zeros(len(self.tiles), dtype=bool)
        is_goal[goals] = True
        # The first step is taken before the goal test: a tile already at a goal still moves
        # on (a leitmotif asked for again is played again, not "already there").
        frontier: list[tuple[float, float, int]] = []
        came: dict[int, int] = {}
        best: dict[int, float] = {}
        for s in self.successors[start]:
            g = float(self.cost[start, s])
            if g < best.get(s, np.inf):
                best[s], came[s] = g, -1
                heapq.heappush(frontier, (g + (0.0 if is_goal[s] else bound[s]), g, int(s)))
        while frontier:
            _, g, node = heapq.heappop(frontier)
            if g > best.get(node, np.inf):
                continue
            if is_goal[node]:
                walk = [node]
                while came[walk[-1]] != -1:
                    walk.append(came[walk[-1]])
                return walk[::-1]
            for s in self.successors[node]:
                gs = g + float(self.cost[node, s])
                if gs < best.get(s, np.inf):
                    best[s], came[s] = gs, node
                    heapq.heappush(frontier, (gs + (0.0 if is_goal[s] else bound[s]), gs, int(s)))
        names = sorted({t for g in goals for t in self.tiles.tiles[g].tags})
        raise NoPath(f"no succession from tile {self.tiles.tiles[start].name!r} reaches a tile tagged {names}")

    def entry(self, layer: str, tag: str) -> int:
        """Where a layer with nothing laid yet starts: its first tile tagged ``tag``."""
        return self.walk(None, layer, [tag])[0]
