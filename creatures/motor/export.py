"""The path a creature actually took, as BVH for animation tools (thesis figure 31: "the path
through the graph ... exported back" to the animator, re-edited and reloaded).

The events log holds every motor-graph node a body reached, in order (``motor`` events'
``reached``: :class:`~creatures.kinds.report_parts.MotorTrail`, consecutive nodes always
joined by an edge). Played through the graph as the body plays a course (squad, recaptured
source timing, the speed limit) and sampled at ``fps``, that is the motion the creature
showed, minus its layers. It is written in the body's own file conventions (scale and up
axis undone), so the file loads back as one more ``[[creature.body.animations]]`` take —
and its frames become nodes of the graph.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from creatures.motor import quaternion as quat
from creatures.motor.bvh import save_bvh
from creatures.motor.graph import MotorGraph
from creatures.motor.material import UP, Conventions
from creatures.motor.playback import Playback
from creatures.motor.pose import PoseSet
from creatures.motor.root_motion import RootMotion
from creatures.motor.search import GraphPosition, Path as GraphPath
from creatures.motor.skeleton import Skeleton


class ExportError(ValueError):
    """The log holds no path for that creature (or names nodes its graph lacks)."""


def taken_nodes(events: list[dict[str, Any]], creature: str, nodes: int) -> list[int]:
    """The nodes ``creature`` reached, in order, from its ``motor`` events."""
    reached: list[int] = []
    for event in events:
        if event.get("kind") == "motor" and event.get("creature") == creature:
            for node in event.get("reached", []):
                if not (isinstance(node, int) and 0 <= node < nodes):
                    raise ExportError(f"motor event at t={event.get('t')} names node {node!r}, but {creature}'s "
                                      f"graph has nodes 0..{nodes - 1} (was the body changed since the run?)")
                if not reached or reached[-1] != node:
                    reached.append(node)
    if not reached:
        raise ExportError(f"the events log has no motor path for creature {creature!r}")
    return reached


def played(graph: MotorGraph, nodes: list[int], fps: float) -> PoseSet:
    """The path played as a course from time 0 and sampled every ``1/fps`` seconds (a walking
    body's root carrying the travel its source steps add)."""
    playback = Playback(graph, GraphPath(GraphPosition(nodes[0]), tuple(nodes), 0.0), 0.0)
    times = np.arange(int(np.floor(playback.end_time * fps)) + 1) / fps
    rotations, roots = playback.sample_rotations(times)
    motion = RootMotion.of(graph)
    if motion is not None:  # a walking body's travel, as the body showed it (linear between keys)
        travel = motion.along(nodes[0], playback.key_nodes)
        roots = roots + np.stack([np.interp(times, playback.key_times, travel[:, c]) for c in range(3)], axis=1)
    return PoseSet.animation(graph.skeleton, rotations, roots, times, "motion")


def in_file_conventions(poses: PoseSet, conventions: Conventions) -> PoseSet:
    """Undo what loading did (:mod:`~creatures.motor.material`): metres → file units, y up → the
    file's up axis, so the exported take imports through the same ``[creature.body]``."""
    back = quat.conjugate(UP[conventions.up_axis])
    skeleton = poses.skeleton
    root = skeleton.parents < 0
    offsets = skeleton.offsets / conventions.scale
    offsets[root] = quat.rotate(back, offsets[root])
    file_skeleton = Skeleton(skeleton.names, skeleton.parents, offsets, skeleton.masses, skeleton.end_effectors)
    rotations = poses.rotations.copy()
    rotations[:, root] = quat.multiply(back, rotations[:, root])
    roots = quat.rotate(back, poses.roots) / conventions.scale
    return PoseSet.animation(file_skeleton, rotations, roots, poses.times, poses.sources[0])


def export_motion(graph: MotorGraph, nodes: list[int], out: Path, *, fps: float = 30.0,
                  conventions: Conventions = Conventions()) -> PoseSet:
    """Write the path through ``nodes`` to ``out`` as BVH; returns the poses written (metres, y up)."""
    poses = played(graph, nodes, fps)
    save_bvh(out, in_file_conventions(poses, conventions), frame_time=1.0 / fps)
    return poses
