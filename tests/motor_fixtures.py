"""Helpers shared by the motor tests."""

from __future__ import annotations

import numpy as np

from creatures.motor import quaternion as quat
from creatures.motor.animations import creature_skeleton, example_animations


def fastest_source_step(frame: float) -> float:
    """Largest joint rotation per frame in the source animations sampled at ``1/frame`` Hz."""
    dense = example_animations(creature_skeleton())
    steps = []
    for animation in dense:
        times = np.arange(animation.times[0], animation.times[-1], frame)
        index = np.clip(np.searchsorted(animation.times, times, side="right") - 1, 0, len(animation) - 2)
        span = animation.times[index + 1] - animation.times[index]
        u = (times - animation.times[index]) / span
        rotations = quat.slerp(animation.rotations[index], animation.rotations[index + 1], u[:, None])
        steps.append(quat.angle_between(rotations[1:], rotations[:-1]).max())
    return float(max(steps))
