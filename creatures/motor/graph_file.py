"""Reading a saved motor graph back, element by element, with errors that name file and line.

A graph file (:meth:`MotorGraph.to_dict <creatures.motor.graph.MotorGraph.to_dict>`) holds
the skeleton, the metric weights, one object per node (a few lines each: source, time,
labels, root, rotations, velocities and an optional favour), one string per edge
(``"from to cost scale"``) and one per forbidden edge (``"from to"``). Animators edit these
files by hand, so every element is checked for what the graph relies on — a negative cost,
scale or favour would make A* inexact, a zero quaternion is no rotation — and any problem
raises :class:`~creatures.persist.StateFileError` naming the line of that element itself
(located by its path in the JSON, :mod:`creatures.motor.json_lines`), never a raw
``TypeError`` or ``KeyError``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from creatures.motor.json_lines import JsonPath, line_at
from creatures.motor.metric import MetricWeights, WeightError
from creatures.motor.pose import PoseSet
from creatures.motor.skeleton import Skeleton, SkeletonFileError
from creatures.persist import StateFileError

Fail = Callable[..., StateFileError]
"""``fail(message, *path)``: the error to raise, placed at the JSON element at ``path``."""

_REQUIRED = object()


@dataclass(frozen=True)
class GraphData:
    """Everything a :class:`~creatures.motor.graph.MotorGraph` is built from."""

    poses: PoseSet
    edges: dict[tuple[int, int], float]
    scales: dict[tuple[int, int], float]
    forbidden: set[tuple[int, int]]
    favour: np.ndarray
    weights: MetricWeights | None


def read_graph(data: Any, *, source: str, text: str = "") -> GraphData:
    """Check and convert graph-file ``data``; errors name ``source`` and, given the JSON
    ``text`` it was parsed from, the offending line."""

    def fail(message: str, *path: str | int) -> StateFileError:
        line = line_at(text, path)
        return StateFileError(f"{source}:{line}: {message}" if line else f"{source}: {message}")

    if not isinstance(data, dict):
        raise fail("a motor graph must be a JSON object")
    for key in ("skeleton", "nodes", "edges"):
        if key not in data:
            raise fail(f"missing key {key!r}")
    try:
        skeleton = Skeleton.from_dict(data["skeleton"], source=source, text=text, at=("skeleton",))
    except SkeletonFileError as exc:
        raise StateFileError(str(exc)) from None
    poses, favour = _read_nodes(data["nodes"], skeleton, fail)
    edges: dict[tuple[int, int], float] = {}
    scales: dict[tuple[int, int], float] = {}
    for a, b, (cost, scale) in _read_pairs(data, "edges", len(poses), fail):
        edges[(a, b)] = cost
        if scale != 1.0:
            scales[(a, b)] = scale
    forbidden = {(a, b) for a, b, _ in _read_pairs(data, "forbidden", len(poses), fail)}
    try:
        weights = MetricWeights.from_dict(data["weights"]) if "weights" in data else None
    except WeightError as exc:
        raise fail(str(exc), "weights", *([exc.key] if exc.key is not None else [])) from None
    return GraphData(poses, edges, scales, forbidden, favour, weights)


def _read_nodes(nodes: Any, skeleton: Skeleton, fail: Fail) -> tuple[PoseSet, np.ndarray]:
    """The node objects as a PoseSet, plus each node's favour multiplier."""
    if not isinstance(nodes, list) or not nodes:
        raise fail("'nodes' must be a non-empty list", "nodes")
    joints = skeleton.joint_count
    fields: dict[str, tuple[Callable[[Any], Any], Any]] = {
        "source": (_string, _REQUIRED),
        "time": (_number, _REQUIRED),
        "labels": (_labels, frozenset()),
        "root": (lambda v: _parse_floats(v, (3,)), _REQUIRED),
        "rotations": (lambda v: _rotations(v, joints), _REQUIRED),
        "velocities": (lambda v: _parse_floats(v, (joints, 3)), _REQUIRED),
        "favour": (_positive, 1.0),
    }
    columns: dict[str, list] = {key: [] for key in fields}
    for i, node in enumerate(nodes):
        if not isinstance(node, dict):
            raise fail(f"node {i} is malformed: expected an object", "nodes", i)
        for key, (parse, default) in fields.items():
            if key not in node:
                if default is _REQUIRED:
                    raise fail(f"node {i} is malformed: no {key!r}", "nodes", i)
                columns[key].append(default)
                continue
            try:
                columns[key].append(parse(node[key]))
            except (TypeError, ValueError) as exc:
                raise fail(f"node {i} is malformed: {key!r} {exc}", "nodes", i, key) from None
    sources = list(dict.fromkeys(columns["source"]))
    ids = {name: k for k, name in enumerate(sources)}
    poses = PoseSet(
        skeleton=skeleton,
        rotations=np.array(columns["rotations"]),
        velocities=np.array(columns["velocities"]),
        roots=np.array(columns["root"]),
        times=np.array(columns["time"]),
        source_ids=np.array([ids[name] for name in columns["source"]]),
        sources=sources,
        labels=columns["labels"],
    )
    return poses, np.array(columns["favour"])


def _read_pairs(data: dict[str, Any], key: str, nodes: int, fail: Fail) -> list[tuple[int, int, list[float]]]:
    """The ``"edges"`` (``"from to cost scale"``) or ``"forbidden"`` (``"from to"``) list."""
    form = "from to cost scale" if key == "edges" else "from to"
    entries = data.get(key, [])
    if not isinstance(entries, list):
        raise fail(f"{key!r} must be a list of '{form}' strings", key)
    return [_parse_edge(entry, form, nodes, fail, (key, j)) for j, entry in enumerate(entries)]


def _parse_edge(entry: Any, form: str, nodes: int, fail: Fail, path: JsonPath) -> tuple[int, int, list[float]]:
    """One edge string: two node indices, then (for edges) a cost ≥ 0 and a scale > 0."""
    parts = entry.split() if isinstance(entry, str) else []
    try:
        if len(parts) != len(form.split()):
            raise ValueError
        a, b = int(parts[0]), int(parts[1])
        rest = [float(x) for x in parts[2:]]
    except ValueError:
        raise fail(f"edge {entry!r:.60} must be {len(form.split())} numbers '{form}'", *path) from None
    if not (0 <= a < nodes and 0 <= b < nodes):
        raise fail(f"edge {entry!r} names a node outside 0..{nodes - 1}", *path)
    if rest:
        cost, scale = rest
        if a == b:
            raise fail(f"edge {entry!r} joins node {a} to itself", *path)
        if not (math.isfinite(cost) and cost >= 0.0 and math.isfinite(scale) and scale > 0.0):
            raise fail(f"edge {entry!r} needs a finite cost ≥ 0 and a finite scale > 0", *path)
    return a, b, rest


def _string(value: Any) -> str:
    if not isinstance(value, str):
        raise TypeError(f"must be a string, got {value!r:.40}")
    return value


def _number(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise TypeError(f"must be a finite number, got {value!r:.40}")
    return float(value)


def _positive(value: Any) -> float:
    if not _number(value) > 0.0:
        raise ValueError(f"must be positive (a multiplier on the node's edge costs), got {value!r}")
    return float(value)


def _labels(value: Any) -> frozenset[str]:
    if not isinstance(value, list) or not all(isinstance(x, str) for x in value):
        raise TypeError(f"must be a list of strings, got {value!r:.40}")
    return frozenset(value)


def _parse_floats(text: Any, shape: tuple[int, ...]) -> np.ndarray:
    if not isinstance(text, str):
        raise TypeError(f"expected a string of numbers, got {type(text).__name__}")
    values = np.array([float(x) for x in text.split()])
    if values.size != math.prod(shape) or not np.all(np.isfinite(values)):
        raise ValueError(f"expected {math.prod(shape)} finite numbers, got {values.size}")
    return values.reshape(shape)


def _rotations(text: Any, joints: int) -> np.ndarray:
    rotations = _parse_floats(text, (joints, 4))
    if np.any(np.linalg.norm(rotations, axis=1) < 1e-6):
        raise ValueError("holds a zero quaternion, which is no rotation")
    return rotations
