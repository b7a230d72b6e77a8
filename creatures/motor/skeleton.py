"""The body's joint hierarchy and forward kinematics (thesis "graph-based motor systems").

A :class:`Skeleton` is the fixed part of a body: joint names, parents, bone offsets, the
per-joint mass weights the pose metric uses ("weight joints that move more body mass",
figure 28) and the end-effectors that reach for notes. Poses (:mod:`creatures.motor.pose`)
are only the changing part: joint rotations and root position.

Skeleton files are JSON or TOML with one table per joint::

    end_effectors = ["hand"]
    [[joints]]
    name = "root"
    offset = [0, 0, 0]
    [[joints]]
    name = "hand"
    parent = "root"
    offset = [0, 1, 0]
    mass = 0.5          # optional; defaults to the joint's subtree size

Joints must be listed parent-before-child.
"""

from __future__ import annotations

import json
import math
import os
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numba
import numpy as np

from creatures.motor import quaternion as quat
from creatures.motor.json_lines import JsonPath, line_at


class SkeletonFileError(ValueError):
    """A skeleton description is malformed; the message names the file (and line)."""


@dataclass(frozen=True, eq=False)
class Skeleton:
    """A joint tree with bone offsets, mass weights and named end-effectors."""

    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    masses: np.ndarray
    end_effectors: tuple[str, ...] = ()
    _index: dict[str, int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        names = tuple(self.names)
        parents = np.asarray(self.parents, dtype=np.int64)
        offsets = np.asarray(self.offsets, dtype=float)
        masses = np.asarray(self.masses, dtype=float)
        count = len(names)
        if parents.shape != (count,) or offsets.shape != (count, 3) or masses.shape != (count,):
            raise ValueError(
                f"skeleton arrays disagree: {count} names, parents {parents.shape},"
                f" offsets {offsets.shape}, masses {masses.shape}"
            )
        if len(set(names)) != count:
            raise ValueError("skeleton joint names must be unique")
        for j, p in enumerate(parents):
            if not -1 <= p < j:
                raise ValueError(
                    f"joint {names[j]!r}: parent index {p} must come before the joint (or be -1)"
                )
        index = {name: j for j, name in enumerate(names)}
        for name in self.end_effectors:
            if name not in index:
                raise ValueError(f"end-effector {name!r} is not a joint of this skeleton")
        for name, value in (
            ("names", names),
            ("parents", parents),
            ("offsets", offsets),
            ("masses", masses),
            ("end_effectors", tuple(self.end_effectors)),
            ("_index", index),
        ):
            object.__setattr__(self, name, value)
        for array in (parents, offsets, masses):
            array.flags.writeable = False

    @property
    def joint_count(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Joint index of ``name`` (KeyError lists the joints when it is unknown)."""
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"no joint {name!r}; joints are {', '.join(self.names)}") from None

    def forward_kinematics(self, rotations: np.ndarray, root: np.ndarray) -> np.ndarray:
        """World joint positions from local joint rotations and the root translation.

        ``rotations`` is ``(J, 4)`` or batched ``(N, J, 4)``; ``root`` is ``(3,)`` or
        ``(N, 3)``. Each joint sits at its parent's position plus its offset rotated by the
        parent's world rotation; the root sits at ``root + offsets[0]`` (BVH convention).
        Compiled, one joint after another (parents come first): a body samples a pose per
        tick, where numpy's per-call overhead on a few joints cost more than the maths.
        """
        rotations = np.asarray(rotations, dtype=float)
        if rotations.ndim == 2 and rotations.flags.c_contiguous:  # one pose (a tick's): no broadcasting
            root = np.asarray(root, dtype=float)
            if root.shape == (3,):
                return _forward_kinematics(rotations[None], root[None], self.parents, self.offsets)[0]
        lead = rotations.shape[:-2]
        flat = np.ascontiguousarray(rotations).reshape(-1, self.joint_count, 4)
        roots = np.ascontiguousarray(np.broadcast_to(np.asarray(root, dtype=float), (*lead, 3))).reshape(-1, 3)
        return _forward_kinematics(flat, roots, self.parents, self.offsets).reshape((*lead, self.joint_count, 3))

    # --- files --------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """Plain-data description (the file format above)."""
        joints = []
        for j, name in enumerate(self.names):
            joint: dict[str, Any] = {
                "name": name,
                "offset": [float(x) for x in self.offsets[j]],
                "mass": float(self.masses[j]),
            }
            if self.parents[j] >= 0:
                joint["parent"] = self.names[self.parents[j]]
            joints.append(joint)
        return {"joints": joints, "end_effectors": list(self.end_effectors)}

    @classmethod
    def from_dict(
        cls, data: dict[str, Any], *, source: str = "<skeleton>", text: str = "", at: JsonPath | None = None
    ) -> Skeleton:
        """Build from :meth:`to_dict` data; errors name ``source`` and, given ``text``, a line.

        ``at`` is where ``data`` sits in ``text`` when that is JSON (``()`` for a skeleton
        file, ``("skeleton",)`` inside a saved graph): each error then names its element's
        own line. Otherwise (TOML) the line is found by searching for the joint's name.
        """

        def fail(message: str, path: JsonPath, needle: str | None = None) -> SkeletonFileError:
            if at is not None:
                line = line_at(text, at + path)
            else:
                line = line_of(text, needle) if needle else None
            where = f"{source}:{line}" if line else source
            return SkeletonFileError(f"{where}: {message}")

        joints = data.get("joints") if isinstance(data, dict) else None
        if not isinstance(joints, list) or not joints:
            raise fail("expected a non-empty list 'joints'", ("joints",), "joints")
        names: list[str] = []
        parents: list[int] = []
        offsets: list[list[float]] = []
        masses: list[float | None] = []
        for k, joint in enumerate(joints):
            if not isinstance(joint, dict) or not isinstance(joint.get("name"), str):
                raise fail(f"joints[{k}] needs a string 'name'", ("joints", k))
            name = joint["name"]
            if name in names:
                raise fail(f"joint {name!r} is listed twice", ("joints", k), name)
            parent = joint.get("parent")
            if parent is None:
                parents.append(-1)
            elif parent in names:
                parents.append(names.index(parent))
            else:
                raise fail(f"joint {name!r}: parent {parent!r} is not listed before it", ("joints", k, "parent"), name)
            offset = joint.get("offset", [0.0, 0.0, 0.0])
            if not (isinstance(offset, list) and len(offset) == 3 and all(_finite(x) for x in offset)):
                raise fail(f"joint {name!r}: 'offset' must be three numbers", ("joints", k, "offset"), name)
            mass = joint.get("mass")
            if mass is not None and not (_finite(mass) and mass >= 0):
                raise fail(f"joint {name!r}: 'mass' must be a non-negative number", ("joints", k, "mass"), name)
            names.append(name)
            offsets.append([float(x) for x in offset])
            masses.append(None if mass is None else float(mass))
        effectors = data.get("end_effectors", [])
        if not isinstance(effectors, list) or not all(isinstance(e, str) for e in effectors):
            raise fail("'end_effectors' must be a list of joint names", ("end_effectors",), "end_effectors")
        for e, name in enumerate(effectors):
            if name not in names:
                raise fail(f"end-effector {name!r} is not a joint", ("end_effectors", e), "end_effectors")
        parents_array = np.asarray(parents, dtype=np.int64)
        default = subtree_sizes(parents_array)
        mass_array = np.array([default[j] if m is None else m for j, m in enumerate(masses)])
        return cls(tuple(names), parents_array, np.asarray(offsets), mass_array, tuple(effectors))

    @classmethod
    def load(cls, path: str | os.PathLike) -> Skeleton:
        """Read a JSON (``.json``) or TOML (any other suffix) skeleton description."""
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8-sig")  # as configs: a byte-order mark is dropped
        except (OSError, UnicodeDecodeError) as exc:
            raise SkeletonFileError(f"{path}: cannot read skeleton file ({exc})") from None
        if path.suffix.lower() == ".json":
            try:
                data = json.loads(text)
            except json.JSONDecodeError as exc:
                raise SkeletonFileError(f"{path}:{exc.lineno}: malformed JSON ({exc.msg})") from None
        else:
            try:
                data = tomllib.loads(text)
            except tomllib.TOMLDecodeError as exc:
                raise SkeletonFileError(f"{path}:{_toml_line(exc, text)}: malformed TOML ({exc})") from None
        return cls.from_dict(data, source=str(path), text=text, at=() if path.suffix.lower() == ".json" else None)


def _finite(value: Any) -> bool:
    """A real number a file may give for an offset or mass (not a bool, not infinite)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def subtree_sizes(parents: np.ndarray) -> np.ndarray:
    """Number of joints at or below each joint: the default "mass moved" weight."""
    sizes = np.ones(len(parents))
    for j in range(len(parents) - 1, -1, -1):
        if parents[j] >= 0:
            sizes[parents[j]] += sizes[j]
    return sizes


def _toml_line(exc: tomllib.TOMLDecodeError, text: str) -> int:
    """The line tomllib's message points at ("at line N" or "at end of document")."""
    found = re.search(r"at line (\d+)", str(exc))
    return int(found.group(1)) if found else max(1, len(text.splitlines()))


def line_of(text: str, needle: str) -> int | None:
    """1-based line where ``needle`` first appears quoted, or as a key, in ``text``."""
    for number, line in enumerate(text.splitlines(), start=1):
        if f'"{needle}"' in line or f"'{needle}'" in line or line.lstrip().startswith(needle):
            return number
    return None


@numba.njit(cache=True)
def _forward_kinematics(rotations, roots, parents, offsets):  # pragma: no cover - compiled
    """:meth:`Skeleton.forward_kinematics` of ``(N, J, 4)`` rotations and ``(N, 3)`` roots."""
    count, joints = rotations.shape[0], rotations.shape[1]
    positions = np.empty((count, joints, 3))
    world = np.empty((joints, 4))
    for n in range(count):
        for j in range(joints):
            local = (rotations[n, j, 0], rotations[n, j, 1], rotations[n, j, 2], rotations[n, j, 3])
            offset = (offsets[j, 0], offsets[j, 1], offsets[j, 2])
            p = parents[j]
            if p < 0:
                turn = local
                place = (offset[0] + roots[n, 0], offset[1] + roots[n, 1], offset[2] + roots[n, 2])
            else:
                parent = (world[p, 0], world[p, 1], world[p, 2], world[p, 3])
                turn = quat.multiply_one(parent, local)
                bone = quat.rotate_one(parent, offset)
                place = (positions[n, p, 0] + bone[0], positions[n, p, 1] + bone[1], positions[n, p, 2] + bone[2])
            for c in range(4):
                world[j, c] = turn[c]
            for c in range(3):
                positions[n, j, c] = place[c]
    return positions
