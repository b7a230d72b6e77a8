"""BVH motion-capture files in and out (thesis "re-editing animation data").

Source animations arrive as BVH (the common text format: a HIERARCHY of joints with
OFFSETs and CHANNELS, then MOTION frames), become a :class:`Skeleton` and key-frame
poses, and paths the creature actually took can be written back out for an animator to
edit and reload (figure 31).

Rotation channels are Euler angles in degrees applied in the listed order (intrinsic:
``Zrotation Xrotation Yrotation`` means ``Rz·Rx·Ry``), converted by a compiled product of
axis turns on the way in and ``scipy.spatial.transform.Rotation`` on the way out. Position channels are read on the root only. An
``End Site`` becomes a joint named ``<parent>_end`` and an end-effector.

Malformed files raise :class:`BVHError`, naming the file and line.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numba
import numpy as np
from scipy.spatial.transform import Rotation

from creatures.motor import quaternion as quat
from creatures.motor.pose import BodyPose, PoseSet
from creatures.motor.skeleton import Skeleton, subtree_sizes
from creatures.persist import atomic_write

_AXES = {"Xrotation": "X", "Yrotation": "Y", "Zrotation": "Z"}
_POSITIONS = ("Xposition", "Yposition", "Zposition")

LARGEST_VALUE = 1e6
"""Largest magnitude an OFFSET or frame value may have (degrees or file units): beyond it a
number is a corrupted file, not a pose (a million degrees is no angle anyone animates)."""


class BVHError(ValueError):
    """A BVH file is malformed; the message starts ``file:line:``."""


@dataclass
class _Joint:
    name: str
    parent: int
    offset: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    channels: list[str] = field(default_factory=list)
    column: int = 0
    end_site: bool = False


class _Tokens:
    """Whitespace tokens with their line numbers, so every error can say where."""

    def __init__(self, lines: list[str], source: str) -> None:
        self.source = source
        self.items = [(tok, n) for n, line in enumerate(lines, start=1) for tok in line.split()]
        self.pos = 0

    @property
    def line(self) -> int:
        if self.pos < len(self.items):
            return self.items[self.pos][1]
        return self.items[-1][1] if self.items else 1

    def error(self, message: str, line: int | None = None) -> BVHError:
        return BVHError(f"{self.source}:{line or self.line}: {message}")

    def next(self, what: str) -> str:
        if self.pos >= len(self.items):
            raise self.error(f"unexpected end of file, expected {what}")
        token = self.items[self.pos][0]
        self.pos += 1
        return token

    def expect(self, word: str) -> None:
        line = self.line
        token = self.next(repr(word))
        if token != word:
            raise self.error(f"expected {word!r}, found {token!r}", line)

    def number(self, what: str) -> float:
        line = self.line
        token = self.next(what)
        try:
            value = float(token)
        except ValueError:
            raise self.error(f"expected a number for {what}, found {token!r}", line) from None
        if not math.isfinite(value) or abs(value) > LARGEST_VALUE:
            raise self.error(f"expected a finite number within ±{LARGEST_VALUE:g} for {what}, found {token!r}", line)
        return value

    @property
    def last_line(self) -> int:
        """Line of the token read last (a joint's name, once read)."""
        return self.items[self.pos - 1][1] if self.pos else 1

    def peek(self) -> str | None:
        return self.items[self.pos][0] if self.pos < len(self.items) else None


def _parse_joint(tokens: _Tokens, joints: list[_Joint], name: str, parent: int, column: int) -> int:
    """Parse one ``{ ... }`` joint body (recursively); returns the next channel column."""
    index = len(joints)
    if any(j.name == name for j in joints):
        raise tokens.error(f"joint {name!r} is named twice (joint names must be unique)", tokens.last_line)
    joint = _Joint(name, parent, column=column)
    joints.append(joint)
    tokens.expect("{")
    tokens.expect("OFFSET")
    joint.offset = [tokens.number(f"{name} OFFSET") for _ in range(3)]
    if tokens.peek() == "CHANNELS":
        tokens.next("CHANNELS")
        line = tokens.line
        count = tokens.number(f"{name} channel count")
        if count != int(count) or not 0 <= count <= 6:
            raise tokens.error(f"joint {name!r}: channel count must be 0..6, found {count:g}", line)
        for _ in range(int(count)):
            line = tokens.line
            channel = tokens.next("a channel name")
            if channel not in _AXES and channel not in _POSITIONS:
                raise tokens.error(f"joint {name!r}: unknown channel {channel!r}", line)
            if channel in joint.channels:
                raise tokens.error(f"joint {name!r}: channel {channel!r} given twice", line)
            if channel in _POSITIONS and parent >= 0:
                raise tokens.error(f"joint {name!r}: position channels are only supported on the root", line)
            joint.channels.append(channel)
        column += len(joint.channels)
    while True:
        line = tokens.line
        word = tokens.next("JOINT, End Site or '}'")
        if word == "}":
            return column
        if word == "JOINT":
            column = _parse_joint(tokens, joints, tokens.next("a joint name"), index, column)
        elif word == "End":
            tokens.expect("Site")
            tokens.expect("{")
            tokens.expect("OFFSET")
            offset = [tokens.number(f"{name} End Site OFFSET") for _ in range(3)]
            tokens.expect("}")
            if any(j.name == f"{name}_end" for j in joints):
                raise tokens.error(f"End Site of {name!r} is named {name + '_end'!r}, which a joint already is")
            joints.append(_Joint(f"{name}_end", index, offset, end_site=True))
        else:
            raise tokens.error(f"expected JOINT, End Site or '}}' in joint {name!r}, found {word!r}", line)


@dataclass(frozen=True)
class Take:
    """A BVH file as read: its skeleton, each frame's joint rotations ``(F, J, 4)`` and root
    position ``(F, 3)``, and the seconds per frame. A body from files re-poses these (its own
    joint order, scale, up axis) before estimating velocities, so they are not estimated twice."""

    skeleton: Skeleton
    rotations: np.ndarray
    roots: np.ndarray
    frame_time: float

    def __len__(self) -> int:
        return len(self.rotations)

    def poses(self, name: str) -> PoseSet:
        """The frames as one source animation named ``name``."""
        times = np.arange(len(self)) * self.frame_time
        return PoseSet.animation(self.skeleton, self.rotations, self.roots, times, name)


def _read_text(path: Path) -> str:
    """A BVH file's text. A UTF-8 byte-order mark is dropped: Windows tools write one before
    ``HIERARCHY``, and it is no part of the first word."""
    try:
        return path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise BVHError(f"{path}: cannot read BVH file ({exc})") from None


def read_bvh(path: str | os.PathLike) -> Take:
    """Read a BVH file as a :class:`Take`."""
    path = Path(path)
    return parse_take(_read_text(path), source=str(path))


def load_bvh_set(path: str | os.PathLike) -> PoseSet:
    """Read a BVH file as a :class:`PoseSet` (source = file stem) ready for a motor graph."""
    return read_bvh(path).poses(Path(path).stem)


def load_bvh(path: str | os.PathLike) -> tuple[Skeleton, list[BodyPose]]:
    """Read a BVH file as its skeleton and one :class:`BodyPose` per frame."""
    poses = load_bvh_set(path)
    return poses.skeleton, [poses.pose(i) for i in range(len(poses))]


def parse_bvh(text: str, *, source: str = "<bvh>", name: str = "bvh") -> PoseSet:
    """Parse BVH text; ``source`` names it in errors, ``name`` becomes the pose source."""
    return parse_take(text, source=source).poses(name)


SHORTEST_FRAME = 1e-4
"""Seconds: the shortest frame time a take may have (10,000 frames a second, beyond any
capture); a smaller one (``Frame Time: 1e-300``) would make the source's top joint speed
astronomical and so no speed limit at all."""


def read_bvh_skeleton(path: str | os.PathLike) -> Skeleton:
    """The skeleton of a BVH file's HIERARCHY, with or without MOTION after it (a hierarchy
    on its own is how a rig is often handed over)."""
    path = Path(path)
    lines = _read_text(path).splitlines()
    end = next((n for n, row in enumerate(lines) if row.strip().startswith("MOTION")), len(lines))
    tokens, joints = _Tokens(lines[:end], str(path)), []
    _hierarchy(tokens, joints)
    if tokens.peek() is not None:
        raise tokens.error(f"unexpected {tokens.peek()!r} after the hierarchy (MOTION or the end of the file)")
    return _skeleton(joints)


def _hierarchy(tokens: "_Tokens", joints: list["_Joint"]) -> int:
    """HIERARCHY and its joints, into ``joints``; returns the channel count."""
    tokens.expect("HIERARCHY")
    tokens.expect("ROOT")
    return _parse_joint(tokens, joints, tokens.next("the root joint name"), -1, 0)


def parse_take(text: str, *, source: str = "<bvh>") -> Take:
    """Parse BVH text as a :class:`Take`; ``source`` names it in errors."""
    lines = text.splitlines()
    # Only the header is tokenised (through the "Frame Time:" line): the frame rows, millions
    # of numbers in a long take, are read by numpy in _frame_rows.
    header = next((n + 1 for n, row in enumerate(lines) if row.lstrip().startswith("Frame Time")), len(lines))
    tokens = _Tokens(lines[:header], source)
    joints: list[_Joint] = []
    columns = _hierarchy(tokens, joints)
    tokens.expect("MOTION")
    tokens.expect("Frames:")
    line = tokens.line
    frames = tokens.number("the frame count")
    if frames != int(frames) or frames < 1:
        raise tokens.error(f"frame count must be a positive integer, found {frames:g}", line)
    tokens.expect("Frame")
    tokens.expect("Time:")
    line = tokens.line
    frame_time = tokens.number("the frame time")
    if not frame_time >= SHORTEST_FRAME:
        raise tokens.error(f"frame time must be at least {SHORTEST_FRAME:g} s (10,000 frames a second), found "
                           f"{frame_time:g}", line)
    if tokens.peek() is not None:
        raise tokens.error(f"unexpected {tokens.peek()!r} after the frame time (frame rows start on the next line)")
    rows = lines[header:]
    available = sum(1 for row in rows if row.strip())
    if not available:
        raise tokens.error(f"'Frames: {int(frames)}' declared but the file has no frame rows")
    if available < frames:  # checked before allocating: "Frames: 1e12" must not exhaust memory
        raise BVHError(f"{source}:{len(lines)}: file ends after {available} of {int(frames)} frames")
    data = _frame_rows(rows, int(frames), columns, source, header + 1)
    return _to_take(joints, data, frame_time)


def _frame_rows(rows: list[str], frames: int, columns: int, source: str, first_line: int) -> np.ndarray:
    """The MOTION rows as a ``(frames, columns)`` array, every row checked (count, numbers,
    magnitude) with its own line in the error. Numbers are converted by numpy in one call
    (10 minutes of 120 fps capture is 7 million of them); a row-by-row pass runs only to
    name the line of a problem."""
    lines = [k for k, row in enumerate(rows) if row.strip()]
    if len(lines) > frames:
        raise BVHError(f"{source}:{first_line + lines[frames]}: more frame rows than 'Frames: {frames}'")
    try:
        text = "\n".join(rows[k] for k in lines).encode("ascii")
    except UnicodeEncodeError:
        text = b""
    if text:
        data = np.empty((frames, columns))
        if _parse_rows(np.frombuffer(text, np.uint8), data):  # plain decimals, every row full: the common case
            if np.all(np.abs(data) <= LARGEST_VALUE):
                return data
    tokens = [row.split() for row in (rows[k] for k in lines)]
    for k, row in zip(lines, tokens):
        if len(row) != columns:
            raise BVHError(f"{source}:{first_line + k}: frame row has {len(row)} values, the hierarchy declares "
                           f"{columns} channels")
    try:
        data = np.array([x for row in tokens for x in row], dtype=float).reshape(frames, columns)
    except ValueError:
        for k, row in zip(lines, tokens):
            try:
                [float(x) for x in row]
            except ValueError:
                raise BVHError(f"{source}:{first_line + k}: frame row contains a non-number") from None
        raise
    bad = ~(np.abs(data) <= LARGEST_VALUE)  # NaN compares false, so it is caught here too
    if bad.any():
        row = int(np.flatnonzero(bad.any(axis=1))[0])
        raise BVHError(f"{source}:{first_line + lines[row]}: frame row contains a non-finite number or one "
                       f"beyond ±{LARGEST_VALUE:g}")
    return data


_POWERS = np.array([10.0 ** k for k in range(23)])
"""Powers of ten a double holds exactly (10^0 … 10^22)."""


@numba.njit(cache=True)
def _parse_rows(text, out):  # pragma: no cover - compiled
    """Frame rows (bytes, one row a line) into ``out`` ``(frames, columns)``; False at anything
    but plain decimal numbers filling every row exactly (the Python pass then names the line).

    Each number is its digits as an integer (at most 15 significant) over a power of ten:
    both exact in a double, so one correctly rounded division or product gives what
    ``float()`` gives (Clinger's fast path); longer numbers fall back. A 72,000-frame take's
    7 million numbers took seconds as Python strings.
    """
    rows, columns = out.shape
    row, column, i, n = 0, 0, 0, text.shape[0]
    while i < n:
        c = text[i]
        if c == 10:  # newline: the row must be full
            if column != columns:
                return False
            row += 1
            column = 0
            i += 1
            continue
        if c == 32 or c == 9 or c == 13:
            i += 1
            continue
        if row >= rows or column >= columns:
            return False
        negative = False
        if c == 45 or c == 43:
            negative = c == 45
            i += 1
        mantissa, digits, scale, seen = 0, 0, 0, False
        while i < n and 48 <= text[i] <= 57:
            if mantissa or text[i] != 48:
                digits += 1
            mantissa = mantissa * 10 + (text[i] - 48)
            seen = True
            i += 1
        if i < n and text[i] == 46:
            i += 1
            while i < n and 48 <= text[i] <= 57:
                if mantissa or text[i] != 48:
                    digits += 1
                mantissa = mantissa * 10 + (text[i] - 48)
                scale += 1
                seen = True
                i += 1
        if i < n and (text[i] == 101 or text[i] == 69):
            i += 1
            sign = 1
            if i < n and (text[i] == 45 or text[i] == 43):
                sign = -1 if text[i] == 45 else 1
                i += 1
            exponent, any_digit = 0, False
            while i < n and 48 <= text[i] <= 57 and exponent < 1000:
                exponent = exponent * 10 + (text[i] - 48)
                any_digit = True
                i += 1
            if not any_digit:
                return False
            scale -= sign * exponent
        if not seen or digits > 15 or (i < n and not (text[i] == 32 or text[i] == 9 or text[i] == 13 or text[i] == 10)):
            return False
        if scale > 22 or scale < -22:
            return False
        value = float(mantissa) / _POWERS[scale] if scale >= 0 else float(mantissa) * _POWERS[-scale]
        out[row, column] = -value if negative else value
        column += 1
    if column:
        if column != columns:
            return False
        row += 1
    return row == rows


def _skeleton(joints: list[_Joint]) -> Skeleton:
    parents = np.array([j.parent for j in joints])
    return Skeleton(
        names=tuple(j.name for j in joints),
        parents=parents,
        offsets=np.array([j.offset for j in joints]),
        masses=subtree_sizes(parents),
        end_effectors=tuple(j.name for j in joints if j.end_site),
    )


def _to_take(joints: list[_Joint], data: np.ndarray, frame_time: float) -> Take:
    skeleton = _skeleton(joints)
    frames = len(data)
    rotations = np.zeros((frames, len(joints), 4))
    rotations[..., 0] = 1.0
    roots = np.zeros((frames, 3))
    for index, joint in enumerate(joints):
        axes = "".join(_AXES[c] for c in joint.channels if c in _AXES)
        angles = np.stack([data[:, joint.column + k] for k, c in enumerate(joint.channels) if c in _AXES], axis=1) if axes else None
        if axes:
            rotations[:, index] = _euler(np.ascontiguousarray(angles), np.array(["XYZ".index(a) for a in axes]))
        for k, channel in enumerate(joint.channels):
            if channel in _POSITIONS:
                roots[:, _POSITIONS.index(channel)] = data[:, joint.column + k]
    return Take(skeleton, rotations, roots, frame_time)


@numba.njit(cache=True)
def _euler(degrees, axes):  # pragma: no cover - compiled
    """Quaternions of intrinsic Euler angles (``axes`` 0, 1, 2 for X, Y, Z, in channel order):
    the product of one turn per channel, left to right. Compiled: scipy's ``from_euler`` on a
    30-joint, 72,000-frame take took seconds."""
    out = np.empty((degrees.shape[0], 4))
    for n in range(degrees.shape[0]):
        q = (1.0, 0.0, 0.0, 0.0)
        for c in range(axes.shape[0]):
            half = 0.5 * math.radians(degrees[n, c])
            turn = [math.cos(half), 0.0, 0.0, 0.0]
            turn[axes[c] + 1] = math.sin(half)
            q = quat.multiply_one(q, (turn[0], turn[1], turn[2], turn[3]))
        for k in range(4):
            out[n, k] = q[k]
    return out


def save_bvh(path: str | os.PathLike, poses: PoseSet, *, frame_time: float | None = None) -> None:
    """Write poses (evenly spaced, ``frame_time`` apart) as BVH with ZXY Euler channels.

    End-site joints (childless joints named ``*_end``) are written as ``End Site``. This is
    how a path through the graph goes back to the animator.
    """
    skeleton = poses.skeleton
    children: dict[int, list[int]] = {j: [] for j in range(skeleton.joint_count)}
    for j, p in enumerate(skeleton.parents):
        if p >= 0:
            children[int(p)].append(j)
    site = {j for j in range(skeleton.joint_count) if not children[j] and skeleton.parents[j] >= 0 and skeleton.names[j].endswith("_end")}
    lines = ["HIERARCHY"]
    order: list[int] = []

    def write(j: int, depth: int) -> None:
        pad = "  " * depth
        offset = " ".join(f"{x:.6f}" for x in skeleton.offsets[j])
        if j in site:
            lines.extend([f"{pad}End Site", f"{pad}{{", f"{pad}  OFFSET {offset}", f"{pad}}}"])
            return
        keyword = "ROOT" if skeleton.parents[j] < 0 else "JOINT"
        channels = "6 Xposition Yposition Zposition" if skeleton.parents[j] < 0 else "3"
        lines.extend([f"{pad}{keyword} {skeleton.names[j]}", f"{pad}{{", f"{pad}  OFFSET {offset}", f"{pad}  CHANNELS {channels} Zrotation Xrotation Yrotation"])
        order.append(j)
        for child in children[j]:
            write(child, depth + 1)
        lines.append(f"{pad}}}")

    roots = [j for j in range(skeleton.joint_count) if skeleton.parents[j] < 0]
    if len(roots) != 1:
        raise ValueError(f"BVH needs exactly one root joint (skeleton has {len(roots)})")
    write(roots[0], 0)
    if frame_time is None:
        frame_time = float(np.median(np.diff(poses.times))) if len(poses) > 1 else 1.0 / 30.0
    angles = Rotation.from_quat(poses.rotations[:, order][..., [1, 2, 3, 0]].reshape(-1, 4)).as_euler("ZXY", degrees=True)
    angles = angles.reshape(len(poses), len(order) * 3)
    table = np.concatenate((poses.roots, angles), axis=1)
    lines += ["MOTION", f"Frames: {len(poses)}", f"Frame Time: {float(frame_time)!r}"]
    lines += [" ".join(f"{x:.9f}" for x in row) for row in table]
    text = "\n".join(lines) + "\n"
    # atomic: a take cut short (Ctrl-C, a full disk) leaves the previous file, never half a take
    atomic_write(Path(path), lambda handle: handle.write(text), "w")
