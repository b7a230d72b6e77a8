"""Motor-graph edit files (thesis "re-editing animation data": the four forms of editing).

An edit file is TOML written against one body (its ``skeleton`` fingerprint, see
:func:`~creatures.motor.material.fingerprint`) and names nodes the way an animator does,
never by index, so that two people's files written independently against the same graph
merge: a node reference is ``"walk@12"`` (frame 12 of source ``walk``), ``"walk@10..30"``
(those frames of it that are nodes) or a label such as ``"sit"`` (every node carrying it)::

    skeleton = "3fa9c2d1e0b4"

    [[forbid]]                 # remove edges and never forge them again
    from = "walk@10"
    to = "sit"
    [[forge]]                  # add edges (cost: the metric's unless given)
    from = "sit"
    to = "walk@0"
    cost = 0.5
    [[reweight]]               # multiply edge costs
    from = "walk@10"
    to = "walk@11"
    scale = 2.0
    [[favour]]                 # multiply every outgoing edge of nodes (< 1 favours them)
    node = "beg"
    multiplier = 0.5
    [[add]]                    # new material as nodes (paths relative to the edit file)
    file = "beg_higher.bvh"
    labels = { beg = [[0, 12]] }
    [[blend]]                  # node contents pulled toward new material (the third form)
    nodes = "beg"
    file = "beg_higher.bvh"
    frames = [0, 12]           # spread over the nodes in source order
    weight = 0.5

Edits are sets: applying files in any order gives the same graph (material is added in
source-name order before the graph is built, blends then, edge edits last), and two files
that disagree about the same edge or node are a :class:`EditError` naming both places.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from creatures.config import ConfigError, nearest, read_toml
from creatures.motor import quaternion as quat
from creatures.motor.graph import MotorGraph
from creatures.motor.material import Animation, Conventions, Material, MaterialError, read_animation
from creatures.motor.pose import PoseSet, estimate_velocities
from creatures.motor.skeleton import Skeleton

OPS = {
    "forbid": {"from": str, "to": str},
    "forge": {"from": str, "to": str, "cost": float},
    "reweight": {"from": str, "to": str, "scale": float},
    "favour": {"node": str, "multiplier": float},
    "add": {"file": str, "labels": dict, "name": str, "step": int},
    "blend": {"nodes": str, "file": str, "frames": list, "weight": float},
}
REQUIRED = {"forbid": ("from", "to"), "forge": ("from", "to"), "reweight": ("from", "to", "scale"),
            "favour": ("node", "multiplier"), "add": ("file",), "blend": ("nodes", "file", "frames", "weight")}


class EditError(ValueError):
    """An edit file is malformed, names nodes the graph lacks, or conflicts with another."""


@dataclass(frozen=True)
class Edit:
    """One table of an edit file: its operation, fields and where it was written."""

    op: str
    fields: dict[str, Any]
    where: str  # "file:line" of the table
    lines: dict[str, str] = field(default_factory=dict)  # "file:line" of each field

    def at(self, name: str) -> str:
        return self.lines.get(name, self.where)


@dataclass
class EditFile:
    """A parsed edit file: the skeleton it was written for and its edits in file order."""

    path: Path
    skeleton: str | None  # None: the config's own edits, written for this body
    edits: list[Edit] = field(default_factory=list)

    def of(self, op: str) -> list[Edit]:
        return [e for e in self.edits if e.op == op]


def read_edits(path: Path) -> EditFile:
    """Parse and check one edit file (shape only: nodes are resolved against the graph later)."""
    try:
        data, where = read_toml(path)  # size cap, regular files only, UTF-8, nesting: as configs
    except ConfigError as exc:
        raise EditError(str(exc)) from None
    lines = {key: line for key, (_, line) in where.items()}
    skeleton = data.get("skeleton")
    if not isinstance(skeleton, str):
        raise EditError(f"{path}:{lines.get(('skeleton',), 1)}: an edit file starts with skeleton = \"<fingerprint>\" "
                        "(the body it was written for)")
    return edits_from({k: v for k, v in data.items() if k != "skeleton"}, path, lines, skeleton)


def edits_from(data: dict[str, Any], path: Path, lines: dict[tuple, int], skeleton: str | None) -> EditFile:
    """Edit tables (``forbid = [{...}]``, ...) as an :class:`EditFile`: from a file, or from the
    config's own ``[creature.body] edits`` (``skeleton`` None: written for this very body; files
    they name are relative to ``path``'s directory)."""

    def at(*key: str | int) -> str:
        for end in range(len(key), 0, -1):
            if key[:end] in lines:
                return f"{path}:{lines[key[:end]]}"
        return f"{path}: {'.'.join(map(str, key))}" if key else str(path)

    result = EditFile(path, skeleton)
    for key, tables in data.items():
        if key not in OPS:
            raise EditError(f"{at(key)}: unknown edit {key!r} (edits: {', '.join(OPS)})")
        if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
            raise EditError(f"{at(key)}: {key!r} must be tables [[{key}]]")
        for i, table in enumerate(tables):
            fields = _checked(key, table, lambda *k, i=i, key=key: at(key, i, *k))
            result.edits.append(Edit(key, fields, at(key, i), {name: at(key, i, name) for name in fields}))
    return result


def _checked(op: str, table: dict[str, Any], at) -> dict[str, Any]:
    """One edit table's fields, each of the type its operation takes."""
    for name in REQUIRED[op]:
        if name not in table:
            raise EditError(f"{at()}: [[{op}]] needs {name!r}")
    for name, value in table.items():
        kind = OPS[op].get(name)
        if kind is None:
            raise EditError(f"{at(name)}: [[{op}]] has no field {name!r} (fields: {', '.join(OPS[op])})")
        if kind is float:
            good = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            good = good and (value >= 0 if name == "cost" else 0 <= value <= 1 if name == "weight" else value > 0)
        elif kind is int:
            good = isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= 1000
        elif name == "frames":  # its kind is checked first: ``frames = 3`` was a TypeError, not a line
            good = _frame_range(value)
        elif name == "labels":
            good = isinstance(value, dict) and all(isinstance(r, list) and all(_frame_range(x) for x in r)
                                                   for r in value.values())
        else:
            good = isinstance(value, kind) and bool(value)
        if not good:
            raise EditError(f"{at(name)}: [[{op}]] {name} = {value!r:.60} is not {_HELP[name]}")
    return dict(table)


def _frame_range(value: Any) -> bool:
    return (isinstance(value, list) and len(value) == 2
            and all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in value) and value[0] <= value[1])


_HELP = {
    "from": "a node reference", "to": "a node reference", "node": "a node reference", "nodes": "a node reference",
    "cost": "a finite cost ≥ 0", "scale": "a finite scale > 0", "multiplier": "a finite multiplier > 0",
    "weight": "a weight in [0, 1]", "file": "a file name", "name": "a source name", "step": "a step in 1..1000",
    "frames": "[first, last] frames", "labels": "label = [[first, last], ...] frame ranges",
}


def check_skeleton(edits: EditFile, skeleton: Skeleton, expected: str) -> None:
    """Refuse a file written for another body (its joints would be other joints)."""
    if edits.skeleton is not None and edits.skeleton != expected:
        raise EditError(f"{edits.path}:1: edit file is for skeleton {edits.skeleton!r}, but this body's skeleton "
                        f"is {expected!r} ({skeleton.joint_count} joints: {', '.join(skeleton.names[:6])}...)")


def added_material(files: list[EditFile], skeleton: Skeleton, conventions: Conventions,
                   known: set[str]) -> list[tuple[PoseSet, float]]:
    """Every ``[[add]]`` take (in source-name order, so file order does not matter)."""
    takes: dict[str, tuple[Edit, Animation]] = {}
    for edit_file in files:
        for edit in edit_file.of("add"):
            animation = _animation(edit, edit_file.path)
            if animation.source in known or animation.source in takes:
                other = takes[animation.source][0].where if animation.source in takes else "the body's animations"
                raise EditError(f"{edit.where}: [[add]] source {animation.source!r} is already {other}'s "
                                "(give it a 'name')")
            takes[animation.source] = (edit, animation)
    found = []
    for source in sorted(takes):
        edit, animation = takes[source]
        found.append(_read(edit, animation, skeleton, conventions))
    return found


def _animation(edit: Edit, path: Path) -> Animation:
    labels = {k: tuple(tuple(r) for r in v) for k, v in edit.fields.get("labels", {}).items()}
    return Animation(path.parent / edit.fields["file"], labels, edit.fields.get("name"), edit.fields.get("step", 1))


def _read(edit: Edit, animation: Animation, skeleton: Skeleton, conventions: Conventions) -> tuple[PoseSet, float]:
    try:
        return read_animation(animation, skeleton, conventions)
    except MaterialError as exc:
        raise EditError(f"{edit.where}: {exc}") from None


class Nodes:
    """Node references resolved against a material: ``source@frame``, ``source@a..b``, a label."""

    def __init__(self, material: Material) -> None:
        self.material = material
        frames = material.frames()
        poses = material.poses
        self._at = {(poses.sources[s], int(f)): i for i, (s, f) in enumerate(zip(poses.source_ids.tolist(), frames))}
        self._frames = frames

    def name(self, node: int) -> str:
        """A node as an edit names it (``walk@12``): errors never show the graph's indices, which
        no author sees and which change when a take is added."""
        poses = self.material.poses
        return f"{poses.sources[poses.source_ids[node]]}@{int(self._frames[node])}"

    def __call__(self, reference: str, where: str) -> np.ndarray:
        poses = self.material.poses
        if "@" in reference:
            source, _, frames = reference.rpartition("@")
            first, _, last = frames.partition("..")
            try:
                lo, hi = int(first), int(last or first)
            except ValueError:
                raise EditError(f"{where}: node {reference!r} must be source@frame or source@first..last") from None
            if source not in poses.sources:
                raise EditError(f"{where}: node {reference!r}: no source {source!r} "
                                f"(sources: {', '.join(poses.sources)})")
            sid = poses.sources.index(source)
            found = np.flatnonzero((poses.source_ids == sid) & (self._frames >= lo) & (self._frames <= hi))
            if not found.size:
                have = self._frames[poses.source_ids == sid]
                raise EditError(f"{where}: node {reference!r}: source {source!r} has no node at frame "
                                f"{frames} (its nodes are frames {int(have.min())}..{int(have.max())})")
            return found
        found = poses.labelled(reference)
        if not found.size:
            raise EditError(f"{where}: node {reference!r}: no node carries that label (and it is not source@frame)"
                            f"{nearest(reference, sorted(poses.every_label), 'labels')}")
        return found


def blended(material: Material, files: list[EditFile], skeleton: Skeleton, conventions: Conventions) -> Material:
    """The material with every ``[[blend]]`` applied: each named node turned ``weight`` of the
    way toward its frame of the new take (slerp per joint), velocities re-estimated along
    each source. A node blended by two edits is a conflict."""
    nodes = Nodes(material)
    poses = material.poses
    rotations = poses.rotations.copy()
    owner: dict[int, str] = {}
    for edit_file in files:
        for edit in edit_file.of("blend"):
            targets = nodes(edit.fields["nodes"], edit.at("nodes"))
            animation = Animation(edit_file.path.parent / edit.fields["file"])
            take, _ = _read(edit, animation, skeleton, conventions)
            first, last = edit.fields["frames"]
            if last >= len(take):
                raise EditError(f"{edit.where}: [[blend]] frames {first}..{last}, but {animation.file} has frames "
                                f"0..{len(take) - 1}")
            order = targets[np.lexsort((poses.times[targets], poses.source_ids[targets]))]
            picks = np.rint(np.linspace(first, last, len(order))).astype(np.int64)
            for node in order.tolist():
                if node in owner:
                    raise EditError(f"{edit.where}: [[blend]] conflicts with {owner[node]}: both blend node "
                                    f"{poses.sources[poses.source_ids[node]]}@{int(nodes._frames[node])}")
                owner[node] = edit.where
            rotations[order] = quat.slerp(rotations[order], take.rotations[picks], edit.fields["weight"])
    if not owner:
        return material
    velocities = poses.velocities.copy()
    for sid in np.unique(poses.source_ids[list(owner)]):
        members = np.flatnonzero(poses.source_ids == sid)
        members = members[np.argsort(poses.times[members], kind="stable")]
        velocities[members] = estimate_velocities(rotations[members], poses.times[members])
    changed = PoseSet(poses.skeleton, rotations, velocities, poses.roots, poses.times, poses.source_ids,
                      list(poses.sources), list(poses.labels))
    return Material(changed, material.frame_times, material.walking)


def apply_edges(graph: MotorGraph, material: Material, files: list[EditFile]) -> None:
    """Forbid, forge, reweight and favour, resolved to node pairs; two edits that disagree
    about one edge or node (a forbidden edge forged, two costs, two scales, two favours)
    are a conflict naming both."""
    nodes = Nodes(material)
    decided: dict[tuple[str, Any], tuple[Any, str]] = {}

    def decide(key: tuple[str, Any], value: Any, where: str) -> bool:
        """Record one decision; False when the same one is already recorded."""
        if key in decided:
            if decided[key][0] != value:
                what, at = key
                about = f"{nodes.name(at[0])} → {nodes.name(at[1])}" if isinstance(at, tuple) else nodes.name(at)
                about = f"the edge {about}" if what == "edge" else f"the {what} of {about}"
                raise EditError(f"{where}: conflicts with {decided[key][1]} about {about}")
            return False
        decided[key] = (value, where)
        return True

    def pairs(edit: Edit) -> list[tuple[int, int]]:
        sources = nodes(edit.fields["from"], edit.at("from"))
        targets = nodes(edit.fields["to"], edit.at("to"))
        return [(int(a), int(b)) for a in sources for b in targets if a != b]

    every = [edit for edit_file in files for edit in edit_file.edits]
    for edit in every:
        if edit.op == "forbid":
            for a, b in pairs(edit):
                if decide(("edge", (a, b)), "forbidden", edit.where):
                    graph.forbid(a, b)
    for edit in every:
        if edit.op == "forge":
            for a, b in pairs(edit):
                if decide(("edge", (a, b)), ("forged", edit.fields.get("cost")), edit.where):
                    graph.connect(a, b, edit.fields.get("cost"))
    for edit in every:
        if edit.op == "reweight":
            for a, b in pairs(edit):
                if not graph.has_edge(a, b):
                    forbidden = decided.get(("edge", (a, b)), (None, ""))
                    why = (f"conflicts with {forbidden[1]}, which forbids it" if forbidden[0] == "forbidden"
                           else "forge it first")
                    raise EditError(f"{edit.where}: [[reweight]] {edit.fields['from']} → {edit.fields['to']}: "
                                    f"the graph has no edge {nodes.name(a)} → {nodes.name(b)} ({why})")
                if decide(("scale", (a, b)), edit.fields["scale"], edit.where):
                    graph.reweight(a, b, edit.fields["scale"])
        elif edit.op == "favour":
            for node in nodes(edit.fields["node"], edit.at("node")).tolist():
                if decide(("favour", node), edit.fields["multiplier"], edit.where):
                    graph.set_favour(node, edit.fields["multiplier"])
