"""What the body generators share: a joint list that becomes a BVH hierarchy, planar leg
inverse kinematics, clips laid end to end, and the labels file beside the BVH.

The shipped bodies are made by the project (issue 16: no third-party motion data): each
generator poses its skeleton frame by frame in plain numpy and writes one BVH file of
clips laid end to end plus ``<name>.labels.toml``, which says which frames make which clip
and which frames carry which label (the thesis's animator marks such as "low energy",
figure 30). Loading lives elsewhere (:mod:`creatures.kinds.figures`), so a generated body is
read exactly as a user's own BVH would be.

Conventions: metres, y up, the body faces +z. Leg joints turn about x only (pitch), so a
leg is a chain in the y–z plane; :func:`planar_leg` solves it so that a planted foot stays
exactly where it was put, which is what makes root motion free of foot sliding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from creatures.motor import quaternion as quat
from creatures.motor.bvh import save_bvh
from creatures.motor.pose import PoseSet
from creatures.motor.skeleton import Skeleton, subtree_sizes

FPS = 15.0
"""Frames per second of every generated clip: low, so the shipped files stay small; the
motor graph interpolates between key-frames anyway (squad)."""

X = np.array([1.0, 0.0, 0.0])
Y = np.array([0.0, 1.0, 0.0])
Z = np.array([0.0, 0.0, 1.0])


def about(axis: np.ndarray, angle: float | np.ndarray) -> np.ndarray:
    """Quaternion(s) turning by ``angle`` radians about ``axis``."""
    angle = np.asarray(angle, dtype=float)
    return quat.from_axis_angle(np.broadcast_to(axis, (*angle.shape, 3)), angle)


def smooth(u: float | np.ndarray) -> np.ndarray:
    """Smoothstep of ``u`` clipped to [0, 1]: eases in and out, so clips start and end still."""
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


@dataclass
class Rig:
    """A skeleton under construction: joints in parent-before-child order. Joints named
    ``*_end`` with no children become BVH ``End Site``s (and end-effectors)."""

    names: list[str] = field(default_factory=list)
    parents: list[int] = field(default_factory=list)
    offsets: list[tuple[float, float, float]] = field(default_factory=list)

    def joint(self, name: str, parent: str | None, offset: tuple[float, float, float]) -> str:
        self.names.append(name)
        self.parents.append(-1 if parent is None else self.names.index(parent))
        self.offsets.append(offset)
        return name

    def chain(self, parent: str | None, *joints: tuple[str, tuple[float, float, float]]) -> None:
        """Joints each the child of the one before, the first of ``parent``: a spine, a tail, a leg."""
        for name, offset in joints:
            parent = self.joint(name, parent, offset)

    def skeleton(self) -> Skeleton:
        parents = np.array(self.parents)
        effectors = tuple(n for n in self.names if n.endswith("_end"))
        return Skeleton(tuple(self.names), parents, np.array(self.offsets), subtree_sizes(parents), effectors)


@dataclass
class Frame:
    """One pose being built: local rotations by joint name (identity when unset) and the root."""

    root: np.ndarray
    turns: dict[str, np.ndarray] = field(default_factory=dict)

    def pitch(self, joint: str, angle: float) -> None:
        self.turns[joint] = quat.multiply(self.turns.get(joint, quat.identity(())), about(X, angle))

    def turn(self, joint: str, axis: np.ndarray, angle: float) -> None:
        self.turns[joint] = quat.multiply(self.turns.get(joint, quat.identity(())), about(axis, angle))

    def rotations(self, skeleton: Skeleton) -> np.ndarray:
        """Every joint's local rotation ``(J, 4)``: the turns set, the identity elsewhere."""
        rotations = quat.identity((skeleton.joint_count,))
        for name, q in self.turns.items():
            rotations[skeleton.index(name)] = q
        return rotations


def planar_leg(hip: np.ndarray, target: np.ndarray, upper: float, lower: float, bend: float) -> tuple[float, float]:
    """World pitch angles of a two-bone leg from ``hip`` to ``target`` (``(y, z)`` points).

    A bone pointing straight down has pitch 0; pitch ``w`` points it along
    ``(z, y) = (−sin w, −cos w)`` (a turn of ``w`` about +x). ``bend`` = +1 puts the middle
    joint behind the line hip–target, −1 in front (a dog's elbow: +1, its stifle: −1).
    Out of reach the leg is straight toward the target (the foot then falls short).
    """
    dy, dz = target[0] - hip[0], target[1] - hip[1]
    reach = min(max(math.hypot(dy, dz), abs(upper - lower) + 1e-6), upper + lower - 1e-6)
    line = math.atan2(-dz, -dy)  # pitch of the line hip → target
    inner = math.acos((upper * upper + reach * reach - lower * lower) / (2.0 * upper * reach))
    first = line + bend * inner
    knee = (hip[0] - upper * math.cos(first), hip[1] - upper * math.sin(first))
    second = math.atan2(-(target[1] - knee[1]), -(target[0] - knee[0]))
    return first, second


@dataclass
class Clip:
    """Frames of one source animation with labels on some of them."""

    name: str
    frames: list[Frame]
    labels: dict[str, list[int]] = field(default_factory=dict)
    root_motion: bool = False
    """The root's horizontal travel is the body's walking (``root_motion = true`` in the labels file)."""

    def label(self, name: str, frames: range | list[int]) -> None:
        self.labels.setdefault(name, []).extend(int(f) for f in frames)


def pose_set(skeleton: Skeleton, clips: list[Clip]) -> PoseSet:
    """Every clip's frames, end to end, as one pose set (the BVH file's MOTION)."""
    frames = [f for clip in clips for f in clip.frames]
    rotations = np.array([frame.rotations(skeleton) for frame in frames]).reshape(len(frames), skeleton.joint_count, 4)
    roots = np.array([f.root for f in frames])
    return PoseSet.animation(skeleton, rotations, roots, np.arange(len(frames)) / FPS, "generated")


def write_body(directory: Path, name: str, skeleton: Skeleton, clips: list[Clip], about_text: str) -> list[Path]:
    """Write ``<name>.bvh`` and ``<name>.labels.toml`` into ``directory``; returns both paths."""
    directory.mkdir(parents=True, exist_ok=True)
    bvh = directory / f"{name}.bvh"
    save_bvh(bvh, pose_set(skeleton, clips), frame_time=1.0 / FPS)
    lines = [f"# {line}".rstrip() for line in about_text.strip().splitlines()]
    lines += ["# Generated by `python -m creatures.body.generate`; frames count from 0, ranges are inclusive.",
              f'bvh = "{bvh.name}"', ""]
    first = 0
    for clip in clips:
        last = first + len(clip.frames) - 1
        lines += ["[[clip]]", f'name = "{clip.name}"', f"frames = [{first}, {last}]"]
        lines += ["root_motion = true", ""] if clip.root_motion else [""]
        for label, frames in sorted(clip.labels.items()):
            for a, b in _runs(sorted(set(frames))):
                lines += ["[[label]]", f'name = "{label}"', f"frames = [{first + a}, {first + b}]", ""]
        first = last + 1
    labels = directory / f"{name}.labels.toml"
    labels.write_text("\n".join(lines), encoding="utf-8")
    return [bvh, labels]


def _runs(frames: list[int]) -> list[tuple[int, int]]:
    """Consecutive frame numbers as inclusive ``(first, last)`` ranges."""
    runs: list[tuple[int, int]] = []
    for f in frames:
        if runs and f == runs[-1][1] + 1:
            runs[-1] = (runs[-1][0], f)
        else:
            runs.append((f, f))
    return runs
