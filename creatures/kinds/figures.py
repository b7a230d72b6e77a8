"""The bodies a creature may have: ``[creature.body] figure = "stick" | "dog" | "bird"``.

``stick`` is the procedural figure every embodied creature had before (sway, reach, strike;
:mod:`creatures.motor.animations`). ``dog`` and ``bird`` are read from the shipped BVH files
in ``installations/bodies/`` (made by :mod:`creatures.body.generate`) exactly as a user's
own BVH would be: :func:`creatures.motor.bvh.load_bvh_set` for the motion, and the labels
file beside it (``<name>.labels.toml``) for which frames make which clip and which frames
carry which label ("low energy" for rest, "sit", "beg", …).

Root motion (thesis: walking creatures; the stick figure's root is fixed). A clip marked
``root_motion = true`` keeps its root's height but gives its horizontal travel to
:class:`~creatures.motor.root_motion.RootMotion`: the nodes stand in place, and each step to a node's successor in the
source moves the body on by the step the source took (see
:meth:`creatures.kinds.parts.Body.update`). A walk cycle's end and start are then the same
pose, the graph joins them, and the body walks on through the seam as it does within a
cycle. Travel is along the world axes (the generated bodies walk straight, facing +z).

The config keys here are one ``figure`` name; the generic ``[creature.body]`` keys
(skeleton, animation files, labels, edits) belong to the body-config work, which these
files can be handed to unchanged.
"""

from __future__ import annotations

import functools
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

import installations
from creatures.kinds.layers import BodySpec
from creatures.motor.bvh import load_bvh_set
from creatures.motor.graph import MotorGraph
from creatures.motor.material import WALKING_FAVOUR
from creatures.motor.note_space import exchange_metric
from creatures.motor.pose import LOW_ENERGY, PoseSet

Figure = Literal["stick", "dog", "bird"]
"""The names ``[creature.body] figure`` accepts."""


class FigureBodySpec(BodySpec):
    """``[creature.body]`` of a creature that may have any figure (``figure`` and the layers)."""

    figure: Figure = Field("stick", description="the body: 'stick' (the procedural figure: sway, reach, "
                                                "strike), 'dog' (stand, walk, sit, lie down, beg, roll over) "
                                                "or 'bird' (perch, peck, flap, hop), the last two generated BVH "
                                                "in installations/bodies/")

    @model_validator(mode="after")
    def _one_body(self) -> "FigureBodySpec":
        """A shipped figure and a body from files are two answers to one question: give one."""
        if self.figure != "stick" and self.custom:
            raise ValueError(f"figure = {self.figure!r} and animations both name the body: give one "
                             "(a shipped figure, or files of its own: docs/bodies.md)")
        return self


EFFECTORS: dict[str, str] = {"stick": "hand_r", "dog": "nose_end", "bird": "beak_end"}
"""The joint that strikes notes on each figure: the stick figure's right hand, the dog's nose
(thesis: "Duncan tries to get his nose near the red marker"), the bird's beak."""


BODIES = Path(installations.__file__).parent / "bodies"
"""Where the shipped BVH bodies and their labels files live."""


class BodyFileError(ValueError):
    """A labels file is malformed or does not fit its BVH; the message starts ``file:line:``."""


@dataclass(frozen=True)
class Range:
    """``[[clip]]`` or ``[[label]]`` of a labels file: a name over inclusive frames."""

    name: str
    first: int
    last: int
    line: int
    root_motion: bool = False


def read_labels(path: Path, frames: int) -> tuple[list[Range], list[Range]]:
    """The clips and labels of ``path`` for a BVH of ``frames`` frames, checked: every frame
    range inside the file, clips in order without gaps or overlaps, covering every frame."""
    try:
        text = path.read_text(encoding="utf-8")
        data = tomllib.loads(text)
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise BodyFileError(f"{path}:1: cannot read labels file ({exc})") from None
    headers = {kind: [n for n, line in enumerate(text.splitlines(), 1) if line.strip() == f"[[{kind}]]"]
               for kind in ("clip", "label")}
    found: dict[str, list[Range]] = {}
    for kind in ("clip", "label"):
        tables = data.get(kind, [])
        if not isinstance(tables, list):
            raise BodyFileError(f"{path}:1: '{kind}' must be an array of tables ([[{kind}]])")
        found[kind] = []
        for k, table in enumerate(tables):
            line = headers[kind][k] if k < len(headers[kind]) else 1
            span = table.get("frames") if isinstance(table, dict) else None
            if not isinstance(table, dict) or not isinstance(table.get("name"), str) or not (
                    isinstance(span, list) and len(span) == 2 and all(type(f) is int for f in span)):
                raise BodyFileError(f"{path}:{line}: a [[{kind}]] needs a string 'name' and 'frames = [first, last]'")
            if not isinstance(table.get("root_motion", False), bool):
                raise BodyFileError(f"{path}:{line}: 'root_motion' must be true or false")
            first, last = span
            if not 0 <= first <= last < frames:
                raise BodyFileError(f"{path}:{line}: {kind} {table['name']!r}: frames [{first}, {last}] are not "
                                    f"within the BVH's {frames} frames (0..{frames - 1})")
            found[kind].append(Range(table["name"], first, last, line, table.get("root_motion", False)))
    clips = found["clip"]
    expected = 0
    for clip in clips:
        if clip.first != expected:
            raise BodyFileError(f"{path}:{clip.line}: clip {clip.name!r} starts at frame {clip.first}, "
                                f"the clips before it end at {expected - 1}")
        expected = clip.last + 1
    if expected != frames:
        raise BodyFileError(f"{path}:1: the clips cover frames 0..{expected - 1} of the BVH's {frames}")
    return clips, found["label"]


@dataclass(frozen=True)
class Material:
    """A figure's source animations and, per node, the horizontal step its source takes to
    the next frame (zero outside root-motion clips and at the end of every clip)."""

    poses: PoseSet
    advances: np.ndarray  # (N, 3)


def load_material(bvh: Path, labels: Path) -> Material:
    """Read a BVH body and its labels file into one pose set of clips (one source each)."""
    whole = load_bvh_set(bvh)
    clips, marks = read_labels(labels, len(whole))
    sets, advances = [], []
    for clip in clips:
        frames = np.arange(clip.first, clip.last + 1)
        roots = whole.roots[frames].copy()
        step = np.zeros_like(roots)
        if clip.root_motion:
            step[:-1, [0, 2]] = np.diff(roots[:, [0, 2]], axis=0)
            roots[:, [0, 2]] = 0.0
        tags = [frozenset(m.name for m in marks if m.first <= f <= m.last) for f in frames.tolist()]
        sets.append(PoseSet.animation(whole.skeleton, whole.rotations[frames], roots,
                                      whole.times[frames] - whole.times[clip.first], clip.name, tags))
        advances.append(step)
    return Material(PoseSet.concatenate(sets), np.concatenate(advances))


@functools.lru_cache(maxsize=4)
def figure_material(figure: str) -> Material:
    """The shipped material of a BVH figure (read once per process)."""
    return load_material(BODIES / f"{figure}.bvh", BODIES / f"{figure}.labels.toml")


def figure_labels(figure: str) -> set[str]:
    """Every motor label of a figure's body, read without building its graph (config checks)."""
    if figure == "stick":
        from creatures.kinds.parts import shared_graph

        return set().union(*shared_graph().poses.labels)
    return set().union(*figure_material(figure).poses.labels) | {LOW_ENERGY}


def body_labels(body: object) -> set[str]:
    """Every motor label of a creature's ``body`` key: its own material's (files named in
    ``[creature.body]``, resolved at config load) or its figure's."""
    if isinstance(body, BodySpec) and body.custom:
        return set().union(*body.material().graph.poses.labels) | {LOW_ENERGY}
    return figure_labels(figure_of(body))
def figure_joints(figure: str) -> tuple[str, ...]:
    """Every joint name of a figure's skeleton (config checks of joint variables)."""
    if figure == "stick":
        from creatures.motor.animations import creature_skeleton

        return creature_skeleton().names
    return figure_material(figure).poses.skeleton.names


def figure_of(body: object) -> Figure:
    """The figure a creature's ``body`` key asks for (``true`` or a table without one: the stick)."""
    return getattr(body, "figure", "stick")


@functools.lru_cache(maxsize=8)
def figure_graph(figure: str, ratios: bool = False) -> MotorGraph:
    """One motor graph per figure and metric, built once from its material (read-only)."""
    if figure == "stick":
        from creatures.kinds.parts import shared_graph

        return shared_graph(ratios)
    material = figure_material(figure)
    graph = MotorGraph.build(material.poses, k=6, weights=exchange_metric() if ratios else None)
    graph.annotate_low_energy()
    graph.advances = material.advances
    successors = graph.timing.next_frame
    for node in np.flatnonzero(material.advances.any(axis=1)).tolist():
        graph.reweight(node, int(successors[node]), WALKING_FAVOUR)
    return graph
