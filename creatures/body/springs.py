"""Bodies as spring systems (thesis, "curve (technology)": "concentrating on abstract lines as a
body enables us to explore simple physical constraints with the introduction of 'spring
physics' into the world ... spring system and optic flow based dynamics").

The motor system says where each joint should be (the BodyPose); the body that is drawn and
that pushes and shapes the strings is its *realisation*: each joint a point mass pulled toward
its pose by a damped spring, its bones kept at their lengths and the floor kept under it by
constraint projection (position-based dynamics: after each integration step every bone is
restored to its rest length, the parent and child moved in proportion to their freedom (a root
is held where the pose puts it), and
no joint goes below the floor). So a fast move overshoots and rings, a limb flung down stops at
the floor, and a still pose settles onto the BodyPose — the "static differences between
BodyPose and pose realization" the thesis says the motor system may come to learn.

Integration runs in fixed sub-steps on the clock (semi-implicit Euler, stable for the stiff
springs here), so a run ticked at 0.02 s and one at 0.04 s realise the same body.
"""

from __future__ import annotations

import numba
import numpy as np
from pydantic import BaseModel, Field

from creatures.bounds import FINITE
from creatures.clock import clock_gap

SUBSTEP = 0.002
"""Seconds per integration step: well inside the stability limit 2/√k of the stiffest spring
allowed (k ≤ 20,000 → 14 ms)."""


class SpringSpec(BaseModel):
    """``springs``: the body realised as a spring system (curve)."""

    model_config = FINITE

    stiffness: float = Field(400.0, gt=0, le=20_000, description="spring pulling each joint to its pose (1/s², per unit mass)")
    damping: float = Field(12.0, ge=0, le=1_000, description="damping of each joint's movement (1/s): 2√stiffness is critical")
    floor: float | None = Field(0.0, ge=-10, le=10, description="height of the floor no joint goes below (m); none = no floor")
    iterations: int = Field(4, ge=1, le=64, description="constraint projections per sub-step (more: stiffer bones)")


class SpringBody:
    """Point masses at the joints, springs to the pose, bones as distance constraints."""

    def __init__(self, spec: SpringSpec, parents: np.ndarray, rest: np.ndarray, t: float = 0.0) -> None:
        self.spec = spec
        self.parents = np.asarray(parents, dtype=np.int64)
        self.positions = np.array(rest, dtype=float)
        self.velocities = np.zeros_like(self.positions)
        self.t = t
        child = np.flatnonzero(self.parents >= 0)
        self.bones = np.stack([self.parents[child], child], axis=1)
        self.lengths = np.linalg.norm(self.positions[child] - self.positions[self.parents[child]], axis=1)
        self.roots = np.flatnonzero(self.parents < 0)
        self.free = np.ones(len(self.positions))  # inverse masses: a root is held where the pose puts it
        self.free[self.roots] = 0.0

    def follow(self, t: float, pose: np.ndarray) -> np.ndarray:
        """Integrate up to ``t`` toward ``pose`` (J, 3); returns the realised positions. Across a
        clock gap (a night, a suspended machine) the body has long come to rest: it stands in
        the pose, not integrated through hours of sub-steps."""
        if clock_gap(self.t, t):
            self.positions[:] = pose
            self.velocities[:] = 0.0
            self.t = float(t)
            return self.positions
        steps = max(int(np.floor((t - self.t) / SUBSTEP + 1e-9)), 0)
        floor = self.spec.floor
        _integrate(self.positions, self.velocities, np.asarray(pose, dtype=float), self.bones, self.lengths,
                   self.free, self.spec.stiffness, self.spec.damping, SUBSTEP, steps, self.spec.iterations,
                   -np.inf if floor is None else float(floor))
        self.t += steps * SUBSTEP
        return self.positions


@numba.njit(cache=True)
def _integrate(x, v, target, bones, lengths, free, k, c, dt, steps, iterations, floor):  # pragma: no cover - compiled
    """``steps`` sub-steps: springs and damping (semi-implicit Euler), then the bones projected
    one after another (Gauss–Seidel: projecting them all at once let a chest with four bones
    overshoot and gain energy), then the floor; the velocity is what the step moved."""
    joints = x.shape[0]
    before = np.empty_like(x)
    for _ in range(steps):
        for j in range(joints):
            for d in range(3):
                v[j, d] += (k * (target[j, d] - x[j, d]) - c * v[j, d]) * dt
                before[j, d] = x[j, d]
                x[j, d] = target[j, d] if free[j] == 0.0 else x[j, d] + v[j, d] * dt
        for _ in range(iterations):
            for i in range(bones.shape[0]):
                a, b = bones[i, 0], bones[i, 1]
                share = free[a] + free[b]
                dx, dy, dz = x[b, 0] - x[a, 0], x[b, 1] - x[a, 1], x[b, 2] - x[a, 2]
                length = np.sqrt(dx * dx + dy * dy + dz * dz)
                if share == 0.0 or length < 1e-12:
                    continue
                m = (length - lengths[i]) / length / share
                x[a, 0] += free[a] * m * dx
                x[a, 1] += free[a] * m * dy
                x[a, 2] += free[a] * m * dz
                x[b, 0] -= free[b] * m * dx
                x[b, 1] -= free[b] * m * dy
                x[b, 2] -= free[b] * m * dz
        for j in range(joints):
            if x[j, 1] < floor:
                x[j, 1] = floor
            for d in range(3):
                v[j, d] = (x[j, d] - before[j, d]) / dt
