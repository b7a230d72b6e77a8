"""Building a body's motor graph from its files, once: cached on disk by a hash of its sources.

A graph from ten minutes of capture takes seconds to build (nearest poses, costs, the
playback speed limit), and an installation restarts every morning. So the graph is built at
config load and written to ``<cache>/<body>.npz`` with the hash of everything it was built
from — the bytes of the skeleton, every animation, every edit file and every file those
edits add or blend, and the parameters (labels, frame steps, scale, up axis, root motion,
rest pose, neighbours). A restart whose sources hash the same loads the graph; a cache
whose hash differs (a file changed: stale) or that does not read back (truncated, foreign,
damaged: corrupt) is never trusted — the graph is rebuilt and the reason logged. The cache
is NPZ (arrays plus JSON strings), written atomically, read with ``allow_pickle=False``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from creatures.config import nearest
from creatures.motor.graph import MotorGraph
from creatures.motor.graph_edits import (EditError, EditFile, added_material, apply_edges, blended, check_skeleton,
                                         edits_from, read_edits)
from creatures.motor.material import (WALKING_FAVOUR, Animation, Conventions, Material, MaterialError,
                                      convert_skeleton, fingerprint, load_material, load_skeleton, read_take,
                                      walking_in_place)
from creatures.motor.line_metric import Content
from creatures.motor.metric import MetricWeights, successors
from creatures.motor.note_space import exchange_metric
from creatures.motor.pose import LOW_ENERGY, PoseSet
from creatures.motor.search import LandmarkTables, PathFinder
from creatures.motor.skeleton import Skeleton
from creatures.persist import StateFileError, atomic_write, each_holds_what_it_claims

logger = logging.getLogger(__name__)

CACHE_VERSION = 8

INLINE_EDITS = "[creature.body] edits"
"""How errors name the edits written in the config itself (as if a file of that name)."""
"""Bumped whenever the cache layout or the graph builder changes what a cache holds."""


@dataclass(frozen=True)
class Sources:
    """Everything a body's graph is built from (resolved paths)."""

    animations: tuple[Animation, ...]
    skeleton: Path | None = None
    edits: tuple[Path, ...] = ()
    conventions: Conventions = Conventions()
    rest: tuple[tuple[str, tuple[float, float, float]], ...] | None = None
    rest_labels: tuple[str, ...] = ()
    neighbours: int = 6
    inline: str = ""  # the config's own edits as JSON, files they name relative to inline_base
    inline_base: Path | None = None
    ratios: bool = False  # the exchange metric (moves at low-integer ratios of a take: note_space.exchange_metric)
    metric: Content = "rotations"  # what the metric measures between poses (MetricWeights.content)

    @property
    def inline_path(self) -> Path:
        """The config's own edits as an edit file is named (the files they name are beside it)."""
        return (self.inline_base or Path(".")) / INLINE_EDITS

    def key(self, edit_files: list[EditFile]) -> str:
        """Hash of the parameters and the bytes of every file the graph reads (BLAKE2b: a ten-minute
        take is 70 MB of text, and SHA-256 of it was a third of a cached reload)."""
        digest = hashlib.blake2b(digest_size=32)
        parameters = {
            "version": CACHE_VERSION, "conventions": vars(self.conventions), "rest": self.rest,
            "rest_labels": self.rest_labels, "neighbours": self.neighbours, "ratios": self.ratios, "metric": self.metric,
            "animations": [(str(a.file), sorted(a.labels.items()), a.name, a.step, a.frames, a.root)
                           for a in self.animations],
            "edits": [str(p) for p in self.edits], "inline": self.inline,
        }
        digest.update(json.dumps(parameters, sort_keys=True, default=str).encode())
        files = [*([self.skeleton] if self.skeleton else []), *(a.file for a in self.animations), *self.edits]
        files += [f.path.parent / e.fields["file"] for f in edit_files for e in f.edits if "file" in e.fields]
        for path in dict.fromkeys(files):  # a file of many clips is read once
            digest.update(str(path).encode() + b"\0")
            try:
                digest.update(path.read_bytes())
            except OSError:
                digest.update(b"<unreadable>")  # the build names the file when it reads it
        return digest.hexdigest()


def keep_own_edges(graph: MotorGraph, own: PoseSet, k: int, weights: MetricWeights | None = None) -> None:
    """Every edge the body's own takes make among themselves, kept in a graph that added or
    blended material has reshaped (at the metric's cost between the poses as they are now).

    An edit file is written against the body's graph, and another file's ``[[add]]`` or
    ``[[blend]]`` moved some own poses' nearest neighbours: a reweight of an edge between two
    of them then found no edge ("forge it first") though each file alone loaded (the audit
    found 50 of 1,766 edges gone). Adding material adds; it never takes an edge away. The own
    poses keep their indices (added takes come after them)."""
    for a, b in MotorGraph.build(own, k=k, weights=weights).edges():
        if not graph.has_edge(a, b):
            graph.connect(a, b)


def build(sources: Sources, edit_files: list[EditFile]) -> MotorGraph:
    """Material → added takes → blends → root motion out of the poses → graph → rest labels →
    edge edits (see :mod:`graph_edits`)."""
    conventions = sources.conventions
    first = read_take(sources.animations[0], ("animations", 0))  # read once, for the skeleton too
    if sources.skeleton is not None:
        skeleton = load_skeleton(sources.skeleton, conventions)
    else:
        skeleton = convert_skeleton(first.skeleton, conventions)
    material = load_material(skeleton, list(sources.animations), conventions,
                             rest=dict(sources.rest) if sources.rest is not None else None,
                             rest_labels=sources.rest_labels, parsed={sources.animations[0].file: first})
    expected = fingerprint(skeleton)
    for i, edit_file in enumerate(edit_files):
        _as_material_error(lambda: check_skeleton(edit_file, skeleton, expected), i)
    takes = _as_material_error(lambda: added_material(edit_files, skeleton, conventions,
                                                      set(material.poses.sources)), None, sources.inline_path)
    own = material.poses  # the body's own takes, before any edit file adds to or blends them
    if takes:
        poses = PoseSet.concatenate([material.poses, *(t for t, _ in takes)])
        added = frozenset(t.sources[0] for t, _ in takes) if conventions.root_motion else frozenset()
        material = Material(poses, {**material.frame_times, **{t.sources[0]: ft for t, ft in takes}},
                            material.walking | added)
    material = _as_material_error(lambda: blended(material, edit_files, skeleton, conventions), None,
                                  sources.inline_path)
    walking = material.walking
    poses, advances = walking_in_place(material.poses, walking) if walking else (material.poses, None)
    weights = MetricWeights(content=sources.metric)
    weights = exchange_metric(weights) if sources.ratios else weights
    graph = MotorGraph.build(poses, k=sources.neighbours, weights=weights)
    if takes or any(f.of("blend") for f in edit_files):
        keep_own_edges(graph, walking_in_place(own, walking)[0] if walking else own, sources.neighbours, weights)
    if advances is not None:  # a walking body: its own steps carry it, so A* keeps to them
        graph.advances = advances
        following = successors(poses)  # not graph.timing: its speed limit is measured once, for the cache
        for node in np.flatnonzero(advances.any(axis=1)).tolist():
            graph.reweight(node, int(following[node]), WALKING_FAVOUR)
    graph.annotate_low_energy()
    for label in sources.rest_labels:
        nodes = material.poses.labelled(label)
        if not nodes.size:
            known = sorted(material.poses.every_label)
            raise MaterialError(f"rest label {label!r} is on no frame of the animations"
                                f"{nearest(label, known, 'labels')}", ("rest_labels",))
        for node in nodes.tolist():
            graph.label(node, LOW_ENERGY)
    _as_material_error(lambda: apply_edges(graph, material, edit_files), None, sources.inline_path)
    try:
        graph.reconnect()
    except ValueError as exc:  # the forbids left a pose (or an island) with no way out
        forbidding = [str(f.path) for f in edit_files if f.of("forbid")]
        raise MaterialError(f"{exc}: the [[forbid]] edits of {', '.join(forbidding) or 'the edits'} leave part of "
                            "the graph with no way to the rest; forbid fewer edges", ("graph_edits",)) from None
    if not np.isfinite(graph.poses.positions).all():
        raise MaterialError("the body's poses are not finite numbers (a rest_pose, scale or take too large to "
                            "compute with)", ("rest_pose",) if sources.rest is not None else ("animations",))
    if not graph.poses.labelled(LOW_ENERGY).size:
        raise MaterialError("the body has no pose to rest in: no frame is still, so give rest_labels "
                            "(labels of frames to rest in) or a rest_pose", ("rest_labels",))
    return graph


def _as_material_error(step: Callable, index: int | None, inline: Path | None = None):
    """Run ``step``; an :class:`EditError` becomes a MaterialError at ``graph_edits`` (its message
    names the edit file and line), or, for an edit written in the config itself (named as the
    file ``inline``: :attr:`Sources.inline_path`), at its own key, which the config's error
    names before the message: so each ``<inline>: blend.0`` in it is said ``edits.blend.0``, the
    one of that key left out."""
    try:
        return step()
    except EditError as exc:
        text = str(exc)
        if inline is not None and f"{inline}: " in text:
            where = text.split(f"{inline}: ", 1)[1].split(":", 1)[0]
            key = tuple(int(part) if part.isdigit() else part for part in where.split(".") if part)
            said = text.replace(f"{inline}: ", "edits.")
            raise MaterialError(said.removeprefix(f"edits.{where}: "), ("edits", *key)) from None
        raise MaterialError(text, ("graph_edits", *([index] if index is not None else []))) from None


def load_or_build(sources: Sources, cache: Path | None) -> MotorGraph:
    """The body's graph: from ``cache`` when its hash matches the sources, else built (and cached)."""
    edit_files = []
    for i, path in enumerate(sources.edits):
        edit_files.append(_as_material_error(lambda path=path: read_edits(path), i))
    if sources.inline:
        where = sources.inline_path
        edit_files.append(_as_material_error(lambda: edits_from(json.loads(sources.inline), where, {}, None), None,
                                             where))
    key = sources.key(edit_files)
    if cache is not None and cache.exists():
        graph = read_cache(cache, key)
        if graph is not None:
            return graph
    graph = build(sources, edit_files)
    if cache is not None:
        try:
            cache.parent.mkdir(parents=True, exist_ok=True)
            write_cache(cache, key, graph)
        except OSError as exc:  # a read-only installation directory: the body still works, rebuilt each start
            logger.warning("%s: cannot write the motor-graph cache (%s); it will be rebuilt next start", cache, exc)
    return graph


def write_cache(path: Path, key: str, graph: MotorGraph) -> None:
    """The graph as NPZ arrays (atomic)."""
    p = graph.poses
    edges = graph.edges_arrays()
    PathFinder(graph).prepare()  # its A* landmark tables, kept beside it (a restart does not search the graph)
    tables = graph.landmark_tables
    kinds = sorted({tuple(sorted(x)) for x in p.labels})  # few distinct label sets: one entry each
    index = {k: i for i, k in enumerate(kinds)}
    arrays = {
        "key": np.array(key), "skeleton": np.array(json.dumps(graph.skeleton.to_dict())),
        "weights": np.array(json.dumps(graph.weights.to_dict())), "sources": np.array(json.dumps(p.sources)),
        "label_sets": np.array(json.dumps(kinds)),
        "label_ids": np.array([index[tuple(sorted(x))] for x in p.labels], dtype=np.int64),
        "rotations": p.rotations, "velocities": p.velocities, "roots": p.roots, "times": p.times,
        "positions": p.positions,
        "source_ids": p.source_ids, "favour": graph.favour, "advances": graph.advances,
        "forbidden": np.array(sorted(graph.forbidden), dtype=np.int64).reshape(-1, 2), **edges,
        "speeds": np.array([graph.timing.typical_speed, graph.timing.max_speed]),
        "landmark_seed": np.array(tables.seed), "landmark_nodes": tables.nodes,
        "landmark_forward": tables.forward, "landmark_backward": tables.backward,
    }
    atomic_write(path, lambda handle: np.savez(handle, **arrays), "wb")


def read_cache(path: Path, key: str) -> MotorGraph | None:
    """The cached graph, or None (with a log line saying why) when it is stale or corrupt."""
    try:
        with np.load(path, allow_pickle=False) as data:
            each_holds_what_it_claims(path, data.zip)  # a damaged shape would ask for terabytes
            if str(data["key"]) != key:
                logger.warning("%s: motor-graph cache is stale (its sources changed); rebuilding", path)
                return None
            skeleton = Skeleton.from_dict(json.loads(str(data["skeleton"])), source=str(path))
            sets = [frozenset(x) for x in json.loads(str(data["label_sets"]))]
            ids, source_ids = data["label_ids"], data["source_ids"]
            sources = json.loads(str(data["sources"]))
            if ids.size and (ids.min() < 0 or ids.max() >= len(sets)) or source_ids.size and (
                    source_ids.min() < 0 or source_ids.max() >= len(sources)) or len(ids) != len(source_ids):
                raise ValueError("label or source numbers outside the cache's own tables")
            labels = [sets[i] for i in ids.tolist()]
            # Every member's CRC is checked as it is read (zipfile), so the arrays are the ones written:
            # a damaged file fails here, and the pose set is not normalised nor its kinematics run again.
            poses = PoseSet.from_checked(skeleton, _c(data["rotations"]), _c(data["velocities"]), _c(data["roots"]),
                                         _c(data["times"]), source_ids.astype(np.int64, copy=False),
                                         sources, labels, _c(data["positions"]))
            graph = MotorGraph.from_arrays(poses, data, weights=MetricWeights.from_dict(json.loads(str(data["weights"]))))
            nodes, forward, backward = (_c(data[f"landmark_{x}"]) for x in ("nodes", "forward", "backward"))
            if forward.shape != (len(poses), len(nodes)) or backward.shape != forward.shape or not (
                    0 <= nodes.min(initial=0) and nodes.max(initial=0) < len(poses)):
                raise ValueError(f"landmark tables of shape {forward.shape} for {len(poses)} nodes")
            graph.landmark_tables = LandmarkTables(graph.version, int(data["landmark_seed"]), len(nodes),
                                                   nodes.astype(np.int64, copy=False), forward, backward)
    except (OSError, KeyError, IndexError, ValueError, TypeError, EOFError, zipfile.BadZipFile, StateFileError) as exc:
        logger.warning("%s: motor-graph cache is corrupt (%s); rebuilding", path, str(exc)[:200])
        return None
    return graph


def _c(array: np.ndarray) -> np.ndarray:
    """A float array read from the cache, C order (as the compiled kernels read it)."""
    return np.ascontiguousarray(array, dtype=float)
