"""The path a creature actually took, as BVH for animation tools (thesis figure 31: "the path
through the graph ... exported back" to the animator, re-edited and reloaded).

The events log holds every motor-graph node a body reached, in order (``motor`` events'
``reached``: :class:`~creatures.kinds.report_parts.MotorTrail`, consecutive nodes always
joined by an edge), and when it reached each. Played through the graph as the body plays a
course (squad, recaptured source timing, the speed limit), waiting where the body waited, held
within the body's joint limits, and sampled at ``fps``, that is the motion the creature showed,
minus its layers (a look, a breath). It is written in the body's own file conventions (scale and up
axis undone), so the file loads back as one more ``[[creature.body.animations]]`` take —
and its frames become nodes of the graph.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from creatures.motor import quaternion as quat
from creatures.motor.blend import Limits
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


HOLD = 0.1
"""Seconds a logged arrival may lag the playback's own pace before the export holds the pose
(the body waited there); a smaller lag is the log's (arrivals are noted at ticks), and the move
is only eased to arrive on time, not stopped and started."""


def taken_path(events: list[dict[str, Any]], creature: str, nodes: int) -> tuple[list[int], list[float] | None]:
    """The nodes ``creature`` reached, in order, from its ``motor`` events, and the clock time
    each was reached (None for a log written before the events carried times)."""
    reached: list[int] = []
    times: list[float] = []
    timed = True
    for event in events:
        if event.get("kind") == "motor" and event.get("creature") == creature:
            at = event.get("at")
            path = event.get("reached", [])
            timed = timed and isinstance(at, list) and len(at) == len(path)
            for k, node in enumerate(path):
                if not (isinstance(node, int) and 0 <= node < nodes):
                    raise ExportError(f"motor event at t={event.get('t')} names node {node!r}, but {creature}'s "
                                      f"graph has nodes 0..{nodes - 1} (was the body changed since the run?)")
                if not reached or reached[-1] != node:
                    reached.append(node)
                    times.append(float(at[k]) if timed and isinstance(at[k], (int, float)) else 0.0)
    if not reached:
        raise ExportError(f"the events log has no motor path for creature {creature!r}")
    return reached, times if timed else None


def played(graph: MotorGraph, nodes: list[int], fps: float, times: list[float] | None = None,
           limits: Limits | None = None) -> PoseSet:
    """The path played as a course from time 0 and sampled every ``1/fps`` seconds (a walking
    body's root carrying the travel its source steps add). With the ``times`` each node was
    reached, the body also waits where it waited (a rest between two courses); with ``limits``
    each frame is held within them as the body's layers held what it showed (joint limits and
    the source's top speed)."""
    playback = Playback(graph, GraphPath(GraphPosition(nodes[0]), tuple(nodes), 0.0), 0.0)
    natural = playback.key_times[1:] - playback.key_times[1]  # when the course reaches each node
    if times is None or len(nodes) < 2:
        timeline, clock = natural, natural
    else:
        arrive = np.asarray(times, dtype=float) - times[0]  # each node is reached when the body reached it …
        for i in range(1, len(arrive)):  # … or as soon after as twice the course's pace allows (two nodes in one tick)
            arrive[i] = max(arrive[i], arrive[i - 1] + 0.5 * (natural[i] - natural[i - 1]))
        waited = np.diff(arrive) - np.diff(natural)
        holds = np.where(waited > HOLD, waited, 0.0)  # else the move is eased to the logged arrival
        timeline = np.column_stack((arrive, np.append(arrive[:-1] + holds, arrive[-1]))).ravel()
        clock = np.repeat(natural, 2)  # playback time: held while the body waits at a node
    frames = np.arange(int(np.floor(timeline[-1] * fps)) + 1) / fps
    at = playback.key_times[1] + np.interp(frames, timeline, clock)
    rotations, roots = playback.sample_rotations(at)
    motion = RootMotion.of(graph)
    if motion is not None:  # a walking body's travel, as the body showed it (linear between keys)
        travel = motion.along(nodes[0], playback.key_nodes)
        roots = roots + np.stack([np.interp(at, playback.key_times, travel[:, c]) for c in range(3)], axis=1)
    if limits is not None:
        held = [limits.apply(rotations[0], None, 0.0)]
        for k in range(1, len(frames)):
            held.append(limits.apply(rotations[k], held[-1], frames[k] - frames[k - 1]))
        rotations = np.array(held)
    return PoseSet.animation(graph.skeleton, rotations, roots, frames, "motion")


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
                  conventions: Conventions = Conventions(), times: list[float] | None = None,
                  limits: Limits | None = None) -> PoseSet:
    """Write the path through ``nodes`` to ``out`` as BVH (see :func:`played`); returns the poses
    written (metres, y up)."""
    poses = played(graph, nodes, fps, times, limits)
    save_bvh(out, in_file_conventions(poses, conventions), frame_time=1.0 / fps)
    return poses
