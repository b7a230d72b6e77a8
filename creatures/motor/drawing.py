"""Drawings read in as animation: SVG paths become a line creature's body (thesis, "curve
(technology)": "With the addition of the ability to read Postscript the animation tools now
become incredibly simple – a piece of paper, a pen and a scanner").

SVG is what today's pens and scanners (Inkscape, Illustrator, a vectorised scan) write, so
the drawing is SVG, parsed by svgelements (transforms applied, units in user units). Every
shape in the document (a path, polyline, polygon or line), in document order, is one *frame*
of the animation: an animator draws one line per layer, as on onion-skin paper.

Each frame is resampled by arc length to ``joints`` points and becomes a pose of a *chain*
skeleton: joint 0 (``root``) at the line's start, each bone one equal step along it, the last
joint (``tip``) its end effector. 48 points keep a drawn curve within 1 % of its size
(measured on cubic Béziers with an S-turn; 24 points were 3.7 % off). A joint's rotation turns its bone from the previous bone's
direction (about the drawing's normal, z), so the chain *is* the line: forward kinematics
give back the resampled points, placed so the first frame's line starts at the origin (the
page is not the room; with ``root_motion`` the line's start moves as it moves on the page). Bone length is the mean over frames: a line creature's body
does not stretch, so a frame a little longer or shorter than the mean plays back as its own
shape scaled to the mean length about its start; one that differs by more than 10 % is
refused, naming it (a body that silently shrank a drawing by half would not be the drawing). The SVG's y axis points down; here y is up. Everything else a body from files
has follows: a ``[creature.body]`` names the drawing as its skeleton and as an animation,
with labels over frame ranges, scale (SVG user units to metres), and the motor graph built
from the frames as from any BVH take.

Optional attributes on the ``<svg>`` element: ``data-joints`` (points per line, 3…256,
default 48) and ``data-frame-time`` (seconds per frame, default 1/12: drawn on twos at 24
frames a second).
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np

from creatures.motor import quaternion as quat
from creatures.motor.bvh import BVHError, Take
from creatures.motor.skeleton import Skeleton

JOINTS = 48
FRAME_TIME = 1.0 / 12.0
STRETCH = 0.10
"""Largest difference of a frame's length from the mean, as a fraction of it."""
DENSE = 2048
"""Points each shape is first sampled at, before resampling by arc length."""


class DrawingError(BVHError):
    """A drawing that cannot be a body: the file and why (a BVHError, so every loader that
    reports a bad take reports this the same way)."""


def read_drawing(path: str | os.PathLike) -> Take:
    """The drawing at ``path`` as a take of a chain skeleton, one frame per shape."""
    path = Path(path)
    lines, joints, frame_time = drawing_lines(path)
    lengths = np.array([_length(line) for line in lines])
    mean = float(lengths.mean())
    for k, length in enumerate(lengths):
        if abs(length - mean) > STRETCH * mean:
            raise DrawingError(f"{path}: shape {k + 1} is {length:.4g} long, the frames' mean is {mean:.4g}: a line "
                               f"body does not stretch (allowed ±{STRETCH:.0%})")
    names = ("root", *(f"s{j:02d}" for j in range(1, joints - 1)), "tip")
    points = np.stack([resample(line, joints) for line in lines])  # (F, J, 2)
    steps = np.diff(points, axis=1)
    offsets = np.zeros((joints, 3))
    offsets[1:, 0] = np.linalg.norm(steps, axis=2).mean(axis=0)  # each bone: its chord, over the frames
    skeleton = Skeleton(names, np.arange(-1, joints - 1), offsets, np.ones(joints), ("tip",))
    angles = np.arctan2(steps[..., 1], steps[..., 0])  # (F, J-1): each bone's direction
    turns = np.zeros((len(lines), joints))
    turns[:, 0] = angles[:, 0]
    turns[:, 1:-1] = np.diff(angles, axis=1)
    rotations = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), turns)
    roots = np.zeros((len(lines), 3))
    roots[:, :2] = points[:, 0] - points[0, 0]  # where it was drawn on the page is not where it stands
    return Take(skeleton, rotations, roots, frame_time)


def drawing_lines(path: Path) -> tuple[list[np.ndarray], int, float]:
    """Every shape of the SVG at ``path`` as dense (n, 2) points, y up; the joint count and
    frame time its ``<svg>`` element asks for. DrawingError names the file (and the line of
    an XML error)."""
    import xml.etree.ElementTree as ET

    import svgelements

    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DrawingError(f"{path}: cannot read the drawing ({exc})") from None
    try:
        ET.fromstring(text)  # well-formed XML first: its error has a line
    except ET.ParseError as exc:
        raise DrawingError(f"{path}:{exc.position[0]}: not well-formed SVG ({exc})") from None
    try:
        svg = svgelements.SVG.parse(path, reify=True)
    except Exception as exc:  # svgelements raises many kinds for a broken document
        raise DrawingError(f"{path}: not a readable SVG ({type(exc).__name__}: {exc})") from None
    if not isinstance(svg, svgelements.SVG):
        raise DrawingError(f"{path}: not an SVG document (its root element is not <svg>)")
    joints = _attribute(svg, "data-joints", JOINTS, 3, 256, path, integer=True)
    frame_time = _attribute(svg, "data-frame-time", FRAME_TIME, 1e-3, 60.0, path)
    lines = []
    for element in svg.elements():
        if not isinstance(element, svgelements.Shape) or isinstance(element, svgelements.SVG):
            continue
        try:
            shape = svgelements.Path(element)
            dense = np.asarray(shape.npoint(np.linspace(0.0, 1.0, DENSE)), dtype=float) if len(shape) else None
        except Exception as exc:  # path data svgelements cannot follow
            raise DrawingError(f"{path}: shape {len(lines) + 1} cannot be traced ({type(exc).__name__}: {exc})") from None
        if dense is None:
            continue
        if dense.ndim != 2 or not np.isfinite(dense).all():
            raise DrawingError(f"{path}: shape {len(lines) + 1} has points that are not numbers")
        dense[:, 1] = -dense[:, 1]  # SVG's y points down
        if _length(dense) <= 0:
            continue
        lines.append(dense)
    if not lines:
        raise DrawingError(f"{path}: holds no path, polyline, polygon or line to draw a body from")
    return lines, int(joints), float(frame_time)


def _attribute(svg, name: str, default: float, low: float, high: float, path: Path, *,
               integer: bool = False) -> float:
    raw = svg.values.get(name)
    if raw is None:
        return default
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not (low <= value <= high) or (integer and value != int(value)):
        raise DrawingError(f"{path}: {name}={raw!r} must be {'a whole number' if integer else 'a number'} in "
                           f"{low:g}…{high:g}")
    return value


def _length(line: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(line, axis=0), axis=1).sum())


def resample(line: np.ndarray, count: int) -> np.ndarray:
    """``count`` points equally spaced by arc length along ``line`` (n, 2)."""
    along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(line, axis=0), axis=1))])
    at = np.linspace(0.0, along[-1], count)
    return np.stack([np.interp(at, along, line[:, 0]), np.interp(at, along, line[:, 1])], axis=1)


def is_drawing(path: str | os.PathLike) -> bool:
    return bool(re.search(r"\.svg$", str(path), re.IGNORECASE))
