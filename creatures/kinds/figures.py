"""The bodies a creature may have: ``[creature.body] figure = "stick" | "dog" | "bird"``.

``stick`` is the procedural figure every embodied creature had before (sway, reach, strike;
:mod:`creatures.motor.animations`). ``dog`` and ``bird`` are bodies from files like a user's
own: a BVH of clips in ``installations/bodies/`` (made by :mod:`creatures.body.generate`) and
its clips file (``<name>.labels.toml``: which frames make which clip, which carry which label,
"low energy" for rest, "sit", "beg", …), read by :func:`creatures.motor.material.read_clips`
and built by :mod:`creatures.motor.body_build` exactly as ``[creature.body] clips`` would be.

Root motion (thesis: walking creatures; the stick figure's root is fixed). A clip marked
``root_motion = true`` keeps its root's height but gives its horizontal travel to
:class:`~creatures.motor.root_motion.RootMotion`: the nodes stand in place, and each step to a node's successor in the
source moves the body on by the step the source took (see
:meth:`creatures.kinds.parts.Body.update`); the other clips move in place as recorded (the
hips lower to sit). A walk cycle's end and start are then the same pose, the graph joins them,
and the body walks on through the seam as it does within a cycle. Travel is along the world
axes (the generated bodies walk straight, facing +z).

A figure alone is one graph per process, shared by its creatures. With any other material key
(edits, joint limits, effectors, rest labels …) the figure's clips are that creature's body from
files, edited and cached beside its config (:class:`FigureBodySpec`).
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

import installations
from creatures.kinds.body_source import MATERIAL_KEYS
from creatures.kinds.layers import BodySpec
from creatures.motor.body_build import Sources, load_or_build
from creatures.motor.graph import MotorGraph
from creatures.motor.line_metric import Content
from creatures.motor.material import read_clips
from creatures.motor.pose import LOW_ENERGY

Figure = Literal["stick", "dog", "bird"]
"""The names ``[creature.body] figure`` accepts."""


class FigureBodySpec(BodySpec):
    """``[creature.body]`` of a creature that may have any figure (``figure`` and the layers)."""

    figure: Figure = Field("stick", description="the body: 'stick' (the procedural figure: sway, reach, "
                                                "strike), 'dog' (stand, walk, sit, lie down, beg, roll over) "
                                                "or 'bird' (perch, peck, flap, hop), the last two generated BVH "
                                                "in installations/bodies/")

    @property
    def custom(self) -> bool:
        """A shipped BVH figure with material keys (edits, joint limits, effectors, rest labels …)
        is built as a body from files: its own clips file, edited by them."""
        return super().custom or self.shipped_clips() is not None

    def shipped_clips(self) -> Path | None:
        edited = [k for k in MATERIAL_KEYS if k in self.model_fields_set and k != "cache"]
        return BODIES / f"{self.figure}.labels.toml" if self.figure != "stick" and edited else None

    def default_effectors(self, graph: MotorGraph) -> tuple[str, ...]:
        return (EFFECTORS[self.figure],) if self.figure != "stick" else super().default_effectors(graph)

    @model_validator(mode="after")
    def _one_body(self) -> "FigureBodySpec":
        """A shipped figure and a body from files are two answers to one question: give one (the
        other material keys edit the figure's body)."""
        named = [k for k in ("animations", "clips", "skeleton") if k in self.model_fields_set]
        if self.figure != "stick" and named:
            raise ValueError(f"figure = {self.figure!r} and {', '.join(named)} both name the body: give one "
                             "(a shipped figure, which the other [creature.body] keys can edit, or files of its "
                             "own: docs/bodies.md)")
        if self.figure != "stick" and "root_motion" in self.model_fields_set:
            raise ValueError(f"root_motion: the {self.figure}'s clips file says which of its clips walk")
        units = [k for k in ("scale", "up_axis") if k in self.model_fields_set]
        if self.figure != "stick" and units:
            raise ValueError(f"{' and '.join(units)}: the {self.figure}'s own clips are in metres, y up, and these keys "
                             "would convert them too; give files an edit adds in metres, y up")
        return self


EFFECTORS: dict[str, str] = {"stick": "hand_r", "dog": "nose_end", "bird": "beak_end"}
"""The joint that strikes notes on each figure: the stick figure's right hand, the dog's nose
(thesis: "Duncan tries to get his nose near the red marker"), the bird's beak."""


BODIES = Path(installations.__file__).parent / "bodies"
"""Where the shipped BVH bodies and their labels files live."""


def figure_sources(figure: str, ratios: bool = False, metric: Content = "rotations") -> Sources:
    """A BVH figure's material as a body from files: its clips file's takes (the same path a
    user's own ``clips`` or ``animations`` take; :func:`creatures.motor.material.read_clips`)."""
    return Sources(tuple(read_clips(BODIES / f"{figure}.labels.toml")), ratios=ratios, metric=metric)


def body_graph(body: object) -> MotorGraph:
    """The motor graph of a creature's ``body`` key: its own material's (files named in
    ``[creature.body]``, resolved at config load) or its figure's (config checks)."""
    if isinstance(body, BodySpec) and body.custom:
        return body.material().graph
    return figure_graph(figure_of(body), metric=metric_of(body))


def body_labels(body: object) -> set[str]:
    """Every motor label of a creature's ``body`` key."""
    return set(body_graph(body).poses.every_label) | {LOW_ENERGY}


def figure_of(body: object) -> Figure:
    """The figure a creature's ``body`` key asks for (``true`` or a table without one: the stick)."""
    return getattr(body, "figure", "stick")


def metric_of(body: object) -> Content:
    """What a creature's ``body`` key has its graph measure between poses (``metric``; none: the rotations)."""
    return getattr(body, "metric", "rotations")


def figure_graph(figure: str, ratios: bool = False, metric: Content = "rotations") -> MotorGraph:
    """One motor graph per figure and metric (``ratios``: exchange's time term; ``metric``: the
    pose content measured, ``MetricWeights.content``), built once from its material (read-only)."""
    return _figure_graph(figure, bool(ratios), metric)  # one cache key however it is called


@functools.lru_cache(maxsize=12)
def _figure_graph(figure: str, ratios: bool, metric: Content) -> MotorGraph:
    if figure == "stick":
        from creatures.kinds.parts import shared_graph

        return shared_graph(ratios, metric)
    return load_or_build(figure_sources(figure, ratios, metric), None)
