"""A body's source material from files (thesis "re-editing animation data").

The thesis's creatures were built from an animator's takes, labelled, re-edited and
exported back. Here a body is a skeleton (a BVH hierarchy or the skeleton JSON/TOML of
:mod:`~creatures.motor.skeleton`) and any number of BVH animations, each with labels over
ranges of its frames, brought into the framework's conventions: y up, metres, and a fixed
root unless the body walks (``root_motion``). A rest pose can be added for material that
never stands still. The result is one :class:`~creatures.motor.pose.PoseSet` from which a
motor graph is built.

Every node keeps where it came from: its source (the animation's name) and its frame in
that file (``time / frame_time``), which is how graph edits name nodes
(:mod:`~creatures.motor.graph_edits`) without depending on node indices.

Errors are :class:`MaterialError`; the message names the file (and line where there is one),
and ``key`` says which config key it belongs to, so the installation loader can add the
config's own line.
"""

from __future__ import annotations

import hashlib
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation

from creatures.config import nearest
from creatures.motor import quaternion as quat
from creatures.motor.bvh import BVHError, Take, read_bvh, read_bvh_skeleton
from creatures.motor.drawing import is_drawing, read_drawing
from creatures.motor.pose import LOW_ENERGY, PoseSet
from creatures.motor.skeleton import Skeleton, SkeletonFileError

WALKING_FAVOUR = 0.1
"""Scale of the cost of a walking take's own frame-to-frame steps (a graph edit, thesis
"re-editing"). A gait's successive frames differ a lot (the legs swing), so the metric alone
would rather jump out of the walk and back; but only the source's own steps carry its travel,
and any other route moves the legs while the body stands still, which is foot sliding."""

REST_SOURCE = "rest"
"""Source name of the rest pose added for material without a still frame."""

UP = {"y": np.array([1.0, 0.0, 0.0, 0.0]), "z": quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), -np.pi / 2)}
"""The turn that brings a file's up axis to the framework's +y (z-up files turn −90° about x)."""


class MaterialError(ValueError):
    """Source material that cannot make a body; ``key`` is the config key path it came from."""

    def __init__(self, message: str, key: tuple[str | int, ...] = ()) -> None:
        super().__init__(message)
        self.key = key


RootMode = Literal["fixed", "in place", "walk"]
"""What a take's recorded root does: ``fixed`` (the body stands where the take begins, as a
fixed-root creature), ``in place`` (the root moves as recorded, a dog's hips lowering as it
sits, but the creature goes nowhere) or ``walk`` (the height as recorded, the horizontal
travel given to the creature: :func:`walking_in_place`)."""


@dataclass(frozen=True)
class Animation:
    """One BVH take: ``labels`` maps a label to inclusive ``(first, last)`` frame ranges;
    ``step`` keeps every ``step``-th frame as a node (labelled frames are always kept).

    ``frames`` makes the take a range of the file (an animator's one file of many clips, as
    the shipped bodies are: :func:`read_clips`); frame numbers, in labels and in the
    ``name@frame`` of edit files, are always the file's own. ``root`` is the take's
    :data:`RootMode`; ``None`` takes the body's ``root_motion`` (walk, else fixed)."""

    file: Path
    labels: dict[str, tuple[tuple[int, int], ...]] = field(default_factory=dict)
    name: str | None = None
    step: int = 1
    frames: tuple[int, int] | None = None
    root: RootMode | None = None

    @property
    def source(self) -> str:
        return self.name or self.file.stem

    def root_mode(self, conventions: "Conventions") -> RootMode:
        """This take's root: its own, or the body's ``root_motion``."""
        return self.root or ("walk" if conventions.root_motion else "fixed")


@dataclass(frozen=True)
class Conventions:
    """How a file's numbers become the framework's: ``scale`` (file units → metres),
    ``up_axis`` and whether the root's recorded translation is kept (``root_motion``)."""

    scale: float = 1.0
    up_axis: str = "y"
    root_motion: bool = False


@dataclass
class Material:
    """Poses ready for a motor graph, with each source's seconds per file frame and the
    sources that walk (whose horizontal root travel is the creature's: root mode ``walk``)."""

    poses: PoseSet
    frame_times: dict[str, float]
    walking: frozenset[str] = frozenset()

    def frames(self) -> np.ndarray:
        """Each node's frame number in its own source file."""
        step = np.array([self.frame_times[s] for s in self.poses.sources])[self.poses.source_ids]
        return np.rint(self.poses.times / step).astype(np.int64)


def walking_in_place(poses: PoseSet, walking: frozenset[str]) -> tuple[PoseSet, np.ndarray]:
    """Root motion of the ``walking`` sources taken out of their poses and kept as steps (thesis
    "graph-based motor systems": a node is a pose, wherever it was recorded): each of their nodes'
    horizontal step ``(N, 3)`` to its source successor (zero at a take's last frame and on every
    other source), and their poses with the horizontal root where the first take began (height
    kept). A body then walks by adding the steps of the source steps it takes
    (:class:`~creatures.motor.root_motion.RootMotion`), so any route through the graph, and any
    jump between takes, starts from where the body stands instead of teleporting it to where the
    take was recorded."""
    from creatures.motor.metric import successors

    following = successors(poses)
    steps = np.zeros_like(poses.roots)
    mine = np.isin(poses.source_ids, [i for i, s in enumerate(poses.sources) if s in walking])
    moving = np.flatnonzero(mine & (following >= 0))
    for axis in (0, 2):
        steps[moving, axis] = poses.roots[following[moving], axis] - poses.roots[moving, axis]
    roots = poses.roots.copy()
    roots[np.ix_(mine, [0, 2])] = poses.roots[0, [0, 2]]
    return PoseSet(poses.skeleton, poses.rotations, poses.velocities, roots, poses.times, poses.source_ids,
                   list(poses.sources), list(poses.labels)), steps


def fingerprint(skeleton: Skeleton) -> str:
    """Short hash of a skeleton's joint names and parents: edit files carry it, so one
    written for another body is refused rather than applied to the wrong joints."""
    text = ";".join(f"{n}<{p}" for n, p in zip(skeleton.names, skeleton.parents.tolist()))
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def load_skeleton(path: Path, conventions: Conventions) -> Skeleton:
    """A skeleton from a BVH file (its hierarchy) or a skeleton JSON/TOML file, in metres, y up."""
    try:
        if is_drawing(path):
            skeleton = read_drawing(path).skeleton
        else:
            skeleton = read_bvh_skeleton(path) if path.suffix.lower() == ".bvh" else Skeleton.load(path)
    except (BVHError, SkeletonFileError) as exc:
        raise MaterialError(str(exc), ("skeleton",)) from None
    return convert_skeleton(skeleton, conventions)


def convert_skeleton(skeleton: Skeleton, conventions: Conventions) -> Skeleton:
    offsets = skeleton.offsets * conventions.scale
    offsets[skeleton.parents < 0] = quat.rotate(UP[conventions.up_axis], offsets[skeleton.parents < 0])
    return Skeleton(skeleton.names, skeleton.parents, offsets, skeleton.masses, skeleton.end_effectors)


def read_take(animation: Animation, key: tuple[str | int, ...] = ()) -> Take:
    """The take's file as parsed (its own skeleton and frames): a BVH file, or a drawing
    (:mod:`creatures.motor.drawing`); MaterialError at ``key``."""
    try:
        return read_drawing(animation.file) if is_drawing(animation.file) else read_bvh(animation.file)
    except BVHError as exc:
        raise MaterialError(str(exc), (*key, "file")) from None


def read_animation(animation: Animation, skeleton: Skeleton, conventions: Conventions, *,
                   key: tuple[str | int, ...] = (), parsed: Take | None = None) -> tuple[PoseSet, float]:
    """One take as poses on ``skeleton`` (joints matched by name) and its frame time
    (``parsed``: the file already read, e.g. for its skeleton).

    The file's hierarchy must be the skeleton's: the same joints with the same parents
    (offsets come from the skeleton). Labels must name frames the file has.
    """
    take = read_take(animation, key) if parsed is None else parsed
    names = take.skeleton.names
    if set(names) != set(skeleton.names):
        missing = sorted(set(skeleton.names) - set(names))
        extra = sorted(set(names) - set(skeleton.names))
        raise MaterialError(f"{animation.file}: hierarchy is not the body's skeleton (missing joints: "
                            f"{', '.join(missing) or 'none'}; unknown joints: {', '.join(extra) or 'none'})",
                            (*key, "file"))
    order = np.array([names.index(n) for n in skeleton.names])
    for j, name in enumerate(skeleton.names):
        mine = skeleton.parents[j]
        theirs = take.skeleton.parents[order[j]]
        if (mine < 0) != (theirs < 0) or (mine >= 0 and names[theirs] != skeleton.names[mine]):
            parent = "none" if theirs < 0 else names[theirs]
            raise MaterialError(f"{animation.file}: joint {name!r} has parent {parent!r} here, not the skeleton's",
                                (*key, "file"))
    count = len(take)
    frame_time = take.frame_time
    first, last = animation.frames if animation.frames is not None else (0, count - 1)
    if not 0 <= first <= last < count:
        raise MaterialError(f"frames {first}..{last} are not within {animation.file}'s frames 0..{count - 1}",
                            (*key, "frames"))
    kept = set(range(first, last + 1, animation.step))
    labels: dict[int, set[str]] = {f: set() for f in range(first, last + 1)}
    for label, ranges in animation.labels.items():
        for start, end in ranges:
            if not first <= start <= end <= last:
                take_is = (f"{animation.file} has frames" if animation.frames is None
                           else f"the take is {animation.file}'s frames")
                raise MaterialError(f"label {label!r} covers frames {start}..{end}, but {take_is} {first}..{last}",
                                    (*key, "labels", label))
            kept.add(start)
            for frame in range(start, end + 1):
                labels[frame].add(label)
    frames = np.array(sorted(kept))
    rotations = take.rotations[frames][:, order]
    roots = take.roots[frames] * conventions.scale
    up = UP[conventions.up_axis]
    root = np.flatnonzero(skeleton.parents < 0)
    rotations[:, root] = quat.multiply(up, rotations[:, root])
    roots = quat.rotate(up, roots)
    if animation.root_mode(conventions) == "fixed":
        roots = np.broadcast_to(roots[0], roots.shape).copy()  # the body stands where its take began
    poses = PoseSet.animation(skeleton, rotations, roots, frames * frame_time, animation.source,
                              [frozenset(labels[f]) for f in frames.tolist()])
    return poses, frame_time


def rest_pose(skeleton: Skeleton, turns: dict[str, tuple[float, float, float]], root: np.ndarray,
              labels: frozenset[str]) -> PoseSet:
    """A still pose from ``joint → rotation vector in degrees`` (joints not named at rest),
    labelled low energy: the place to rest for material that never stands still."""
    rotations = quat.identity((1, skeleton.joint_count))
    for name, vector in turns.items():
        if name not in skeleton.names:
            raise MaterialError(f"no joint {name!r} in the body{nearest(name, skeleton.names, 'joints')}",
                                ("rest_pose", name))
        xyzw = Rotation.from_rotvec(np.radians(vector)).as_quat()
        rotations[0, skeleton.index(name)] = xyzw[[3, 0, 1, 2]]
    return PoseSet.animation(skeleton, rotations, root[None], np.zeros(1), REST_SOURCE, [labels | {LOW_ENERGY}])


def load_material(skeleton: Skeleton, animations: list[Animation], conventions: Conventions, *,
                  rest: dict[str, tuple[float, float, float]] | None = None,
                  rest_labels: tuple[str, ...] = (), parsed: dict[Path, Take] | None = None) -> Material:
    """Every take (and the rest pose) on one skeleton; sources named twice are refused.
    ``parsed``: files already read (each file is parsed once, however many takes it holds)."""
    sets: list[PoseSet] = []
    frame_times: dict[str, float] = {}
    files = dict(parsed or {})
    for i, animation in enumerate(animations):
        if animation.source == REST_SOURCE:  # reserved for the rest pose, so a take in rest.bvh is renamed
            raise MaterialError(f"{REST_SOURCE!r} names the rest pose's nodes (rest_pose; 'rest@0' in edits): "
                                "give this take another 'name'", ("animations", i, "name"))
        if animation.source in frame_times:
            raise MaterialError(f"two animations are named {animation.source!r} (give one a 'name')",
                                ("animations", i, "name"))
        if animation.file not in files:
            files[animation.file] = read_take(animation, ("animations", i))
        poses, frame_times[animation.source] = read_animation(animation, skeleton, conventions,
                                                              key=("animations", i), parsed=files[animation.file])
        sets.append(poses)
    if rest is not None:
        first = sets[0].roots[0] if sets else np.zeros(3)
        sets.append(rest_pose(skeleton, rest, first, frozenset(rest_labels[:1])))
        frame_times[REST_SOURCE] = 1.0
    if not sets:
        raise MaterialError("a body needs at least one animation", ("animations",))
    walking = frozenset(a.source for a in animations if a.root_mode(conventions) == "walk")
    return Material(PoseSet.concatenate(sets), frame_times, walking)


CLIPS_KEYS = {"": ("bvh", "clip", "label"), "clip": ("name", "frames", "root_motion"), "label": ("name", "frames")}
"""The keys a clips file takes: at its top (``""``) and in each ``[[clip]]`` and ``[[label]]``."""


def _only_keys(path: Path, lines: list[str], header: int, table: dict, known: tuple[str, ...], what: str) -> None:
    """Refuse a key of ``table`` (its header at 1-based line ``header``; 0: the file's top) that
    is not ``known``, at that key's own line, with the nearest known one: a typo read as
    nothing (``root_moton = true``) would leave a walk in place without a word."""
    for key in table:
        if key in known:
            continue
        rows = enumerate(lines[header:], header + 1)
        at = next((n for n, row in rows if row.startswith("[") or row.split("=", 1)[0].strip() == key), None)
        line = at if at is not None and not lines[at - 1].startswith("[") else header or 1
        raise MaterialError(f"{path}:{line}: {what} has no key {key!r}{nearest(key, known, 'keys')}", ("clips",))


def read_clips(path: Path) -> list[Animation]:
    """The takes of a clips file: one BVH of many clips (``bvh``, relative to the file) and
    ``[[clip]]`` tables (a name over inclusive ``frames``, optional ``root_motion``: walk, else
    in place) that follow each other without gaps over every frame, and ``[[label]]`` tables over
    any frames, each given to the clips it overlaps. The shipped bodies are written so
    (installations/bodies/*.labels.toml), as an animator exports one file of named ranges.
    MaterialError names the file and line."""
    try:
        text = path.read_text(encoding="utf-8-sig")  # as configs: a byte-order mark is dropped
        data = tomllib.loads(text)
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise MaterialError(f"{path}:1: cannot read clips file ({exc})", ("clips",)) from None
    lines = text.splitlines()
    _only_keys(path, lines, 0, data, CLIPS_KEYS[""], "a clips file")
    if not isinstance(data.get("bvh"), str):
        raise MaterialError(f"{path}:1: a clips file names its BVH: bvh = \"file.bvh\"", ("clips",))
    bvh = path.parent / data["bvh"]
    count = bvh_frame_count(bvh)
    found: dict[str, list[tuple[str, int, int, int, bool]]] = {}
    for kind in ("clip", "label"):
        headers = [n for n, line in enumerate(lines, 1) if line.strip() == f"[[{kind}]]"]
        tables = data.get(kind, [])
        if not isinstance(tables, list):
            raise MaterialError(f"{path}:1: '{kind}' must be an array of tables ([[{kind}]])", ("clips",))
        found[kind] = []
        for k, table in enumerate(tables):
            line = headers[k] if k < len(headers) else 1
            if isinstance(table, dict):
                _only_keys(path, lines, line, table, CLIPS_KEYS[kind], f"[[{kind}]]")
            span = table.get("frames") if isinstance(table, dict) else None
            if not isinstance(table, dict) or not isinstance(table.get("name"), str) or not (
                    isinstance(span, list) and len(span) == 2 and all(type(f) is int for f in span)):
                raise MaterialError(f"{path}:{line}: a [[{kind}]] needs a string 'name' and 'frames = [first, last]'",
                                    ("clips",))
            if not isinstance(table.get("root_motion", False), bool):
                raise MaterialError(f"{path}:{line}: 'root_motion' must be true or false", ("clips",))
            first, last = span
            if not 0 <= first <= last < count:
                raise MaterialError(f"{path}:{line}: {kind} {table['name']!r}: frames [{first}, {last}] are not "
                                    f"within {bvh.name}'s {count} frames (0..{count - 1})", ("clips",))
            found[kind].append((table["name"], first, last, line, table.get("root_motion", False)))
    expected = 0
    for name, first, last, line, _ in found["clip"]:
        if first != expected:
            raise MaterialError(f"{path}:{line}: clip {name!r} starts at frame {first}, the clips before it end at "
                                f"{expected - 1}", ("clips",))
        expected = last + 1
    if expected != count:
        raise MaterialError(f"{path}:1: the clips cover frames 0..{expected - 1} of {bvh.name}'s {count}", ("clips",))
    takes = []
    for name, first, last, _, walks in found["clip"]:
        labels: dict[str, list[tuple[int, int]]] = {}
        for label, start, end, _, _ in found["label"]:
            if start <= last and end >= first:
                labels.setdefault(label, []).append((max(start, first), min(end, last)))
        takes.append(Animation(bvh, {k: tuple(v) for k, v in labels.items()}, name, frames=(first, last),
                               root="walk" if walks else "in place"))
    return takes


def bvh_frame_count(path: Path) -> int:
    """The ``Frames:`` of a BVH file's header, read without its motion rows (a clips file is
    checked against it at every start, also when the body's graph comes from its cache)."""
    try:
        with path.open(encoding="utf-8", errors="replace") as handle:
            for number, line in enumerate(handle, 1):
                words = line.split()
                if words[:1] == ["Frames:"] and len(words) == 2 and words[1].isdigit():
                    return int(words[1])
                if words[:1] == ["Frame"] or number > 100_000:
                    break
    except OSError as exc:
        raise MaterialError(f"{path}: cannot read ({exc.strerror})", ("clips",)) from None
    raise MaterialError(f"{path}: no 'Frames: N' line in its MOTION header", ("clips",))
