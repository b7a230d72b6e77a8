"""Procedural example animations for the shipped creature (thesis figure 30's "3 animations").

The thesis builds its motor graph automatically from three hand-crafted animations (sniff,
play, beg). We ship three procedural ones for a small music creature instead, so the
project has source material without an animator: *sway* (a biphasic idle cycle, with the
rest pose marked as a low-energy state), *reach* (the right hand sweeps through the space
in front of the body, where notes live) and *strike* (the right hand winds up and hits
down). Each returns a :class:`~creatures.motor.pose.PoseSet` of key-frames with times,
source name, labels and estimated joint velocities.

The creature faces +z with its arms along ±x at rest; ``data/creature.json`` describes it.
"""

from __future__ import annotations

from importlib import resources
from typing import Callable

import numpy as np

from creatures.motor import quaternion as quat
from creatures.motor.pose import LOW_ENERGY, PoseSet
from creatures.motor.skeleton import Skeleton

X = np.array([1.0, 0.0, 0.0])
Y = np.array([0.0, 1.0, 0.0])
Z = np.array([0.0, 0.0, 1.0])


def creature_skeleton() -> Skeleton:
    """The shipped skeleton, ``creatures/motor/data/creature.json``."""
    with resources.as_file(resources.files("creatures.motor") / "data" / "creature.json") as path:
        return Skeleton.load(path)


def _about(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    return quat.from_axis_angle(np.broadcast_to(axis, (*np.shape(angle), 3)), angle)


def _right_arm(yaw: np.ndarray, droop: np.ndarray) -> np.ndarray:
    """Right shoulder rotation: ``droop`` lowers the arm from horizontal, ``yaw`` swings it forward."""
    return quat.multiply(_about(Y, yaw), _about(Z, droop))


def _left_arm(yaw: np.ndarray, droop: np.ndarray) -> np.ndarray:
    return quat.multiply(_about(Y, -yaw), _about(Z, -droop))


def _animate(
    skeleton: Skeleton,
    source: str,
    times: np.ndarray,
    joints: dict[str, np.ndarray],
    labels: Callable[[np.ndarray], list[frozenset[str]]],
) -> PoseSet:
    """Assemble key-frames: named joints get the given ``(N, 4)`` rotations, others rest."""
    rotations = quat.identity((len(times), skeleton.joint_count))
    for name, q in joints.items():
        rotations[:, skeleton.index(name)] = q
    roots = np.zeros((len(times), 3))
    return PoseSet.animation(skeleton, rotations, roots, times, source, labels(times))


def _frames(duration: float, fps: float) -> np.ndarray:
    return np.arange(int(round(duration * fps)) + 1) / fps


def _resting_arms(n: int) -> dict[str, np.ndarray]:
    down = np.full(n, 1.3)
    return {"shoulder_r": _right_arm(np.zeros(n), down), "shoulder_l": _left_arm(np.zeros(n), down)}


def sway(skeleton: Skeleton, *, duration: float = 4.0, fps: float = 10.0, amplitude: float = 0.25) -> PoseSet:
    """A biphasic idle sway: the torso rocks left and right, the head counterbalances.

    Labels: ``"sway left"`` / ``"sway right"`` at the two extremes (the biphasic pair used by
    the ``walk``-style cycle program) and ``"low energy"`` on the upright rest frames.
    """
    times = _frames(duration, fps)
    phase = 2.0 * np.pi * times / duration
    roll = amplitude * np.sin(phase)
    joints = {
        **_resting_arms(len(times)),
        "spine": _about(Z, 0.6 * roll),
        "chest": _about(Z, 0.4 * roll),
        "neck": _about(Z, -0.5 * roll),
        "hip_l": _about(Z, -0.3 * roll),
        "hip_r": _about(Z, -0.3 * roll),
    }

    def labels(t: np.ndarray) -> list[frozenset[str]]:
        frac = (t / duration) % 1.0
        step = 0.5 / (duration * fps)
        out = []
        for f in frac:
            tags = set()
            if abs(f - 0.25) < step:
                tags.add("sway left")
            if abs(f - 0.75) < step:
                tags.add("sway right")
            if min(f, 1.0 - f) < step:
                tags.add(LOW_ENERGY)
            out.append(frozenset(tags))
        return out

    return _animate(skeleton, "sway", times, joints, labels)


def reach(skeleton: Skeleton, *, duration: float = 12.0, fps: float = 10.0) -> PoseSet:
    """The right hand sweeps the space in front of the creature (where notes are placed).

    Three incommensurate oscillations — the chest twisting side to side, the arm rising
    and falling, the elbow bending — make the hand's path fill a volume of heights,
    azimuths and distances rather than a single curve; every frame is labelled ``"reach"``.
    """
    times = _frames(duration, fps)
    phase = 2.0 * np.pi * times / duration
    twist = 0.7 * np.sin(phase)
    lift = 0.5 * (1.0 - np.cos(5.0 * phase))
    bend = 0.5 * (1.0 - np.cos(13.0 * phase))
    joints = {
        "shoulder_l": _left_arm(np.zeros(len(times)), np.full(len(times), 1.3)),
        "chest": _about(Y, twist),
        "shoulder_r": _right_arm(1.2 - 0.2 * lift, 1.3 - 1.9 * lift),
        "elbow_r": _about(Y, 1.4 * bend),
    }
    return _animate(skeleton, "reach", times, joints, lambda t: [frozenset({"reach"})] * len(t))


def strike(skeleton: Skeleton, *, duration: float = 2.0, fps: float = 15.0) -> PoseSet:
    """The right arm winds up over the head, then strikes down in front of the body.

    Labels: ``"strike ready"`` at the top of the wind-up, ``"strike"`` at the moment of
    impact, ``"low energy"`` on the rest frames at either end.
    """
    times = _frames(duration, fps)
    u = times / duration
    # Slow raise over 60% of the time, fast swing down over 15%, then settle back.
    raise_ = np.clip(u / 0.6, 0.0, 1.0)
    swing = np.clip((u - 0.6) / 0.15, 0.0, 1.0)
    settle = np.clip((u - 0.75) / 0.25, 0.0, 1.0)
    droop = 1.3 - 2.8 * np.sin(0.5 * np.pi * raise_) + 2.6 * swing ** 2 + (1.3 - 1.1) * settle
    yaw = 1.3 * np.sin(0.5 * np.pi * raise_) * (1.0 - settle)
    elbow = 1.2 * np.sin(np.pi * raise_) * (1.0 - swing)
    joints = {
        "shoulder_l": _left_arm(np.zeros(len(times)), np.full(len(times), 1.3)),
        "shoulder_r": _right_arm(yaw, droop),
        "elbow_r": _about(Z, elbow),
        "chest": _about(X, 0.25 * swing * (1.0 - settle)),
    }
    impact = int(np.argmin(np.abs(u - 0.75)))
    ready = int(np.argmin(np.abs(u - 0.6)))

    def labels(t: np.ndarray) -> list[frozenset[str]]:
        out = [set() for _ in t]
        out[impact].add("strike")
        out[ready].add("strike ready")
        out[0].add(LOW_ENERGY)
        out[-1].add(LOW_ENERGY)
        return [frozenset(x) for x in out]

    return _animate(skeleton, "strike", times, joints, labels)


def example_animations(skeleton: Skeleton | None = None) -> list[PoseSet]:
    """The three shipped animations (sway, reach, strike) on ``skeleton`` (default: creature)."""
    skeleton = skeleton or creature_skeleton()
    return [sway(skeleton), reach(skeleton), strike(skeleton)]
