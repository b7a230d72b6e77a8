"""Adverb blending of example animations (thesis "blend based motor systems", figures 20–21).

Examples of one verb in different styles (``beg(low)``, ``beg(high)``; ``walk(happily)``,
``walk(sadly)``) sit at points of a one- or two-axis *adverb* space. Radial-basis-function
interpolation (scipy's ``RBFInterpolator``, with a linear polynomial so the weights sum to
one) turns an adverb point into blend weights that go exactly through the examples.

Blending happens in *neutral time*: each example is time-warped, piecewise-linearly through
its correspondence points, onto [0, 1]; the blended animation lasts the weighted mean of the
example durations (50:50 of a 2 s and a 4 s walk lasts 3 s, and half-way through it reads 1 s
into one and 2 s into the other). Joint rotations are blended in the tangent space of the
most heavily weighted example, which also behaves for the negative weights that RBF
extrapolation produces.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numba
import numpy as np
from scipy.interpolate import RBFInterpolator

from creatures.motor import quaternion as quat
from creatures.motor.pose import PoseSet


@dataclass(frozen=True)
class Example:
    """One example animation at ``adverbs`` (1 or 2 numbers), with optional correspondence
    times (seconds into this animation) that must line up across examples."""

    animation: PoseSet
    adverbs: tuple[float, ...]
    correspondences: tuple[float, ...] = ()

    def keys(self) -> np.ndarray:
        """Correspondence times including start and end (the time-warp knots)."""
        t = self.animation.times
        return np.array([t[0], *self.correspondences, t[-1]])


class AdverbBlend:
    """Generates a verb's animation for any adverb point from its examples."""

    def __init__(self, examples: Sequence[Example], *, kernel: str = "thin_plate_spline") -> None:
        if len(examples) < 2:
            raise ValueError("adverb blending needs at least two examples")
        dims = {len(e.adverbs) for e in examples}
        if len(dims) != 1 or not dims <= {1, 2}:
            raise ValueError("every example needs the same number (1 or 2) of adverb values")
        knots = {len(e.correspondences) for e in examples}
        if len(knots) != 1:
            raise ValueError("every example needs the same number of correspondence points")
        for e in examples:
            keys = e.keys()
            if np.any(np.diff(keys) <= 0.0):
                raise ValueError(f"correspondence times of {e.animation.sources} must increase inside the animation")
        self.examples = list(examples)
        points = np.array([e.adverbs for e in examples], dtype=float)
        degree = 1 if len(examples) > points.shape[1] else 0
        self._rbf = RBFInterpolator(points, np.eye(len(examples)), kernel=kernel, degree=degree)
        self._neutral = np.linspace(0.0, 1.0, len(examples[0].keys()))

    def weights(self, adverbs: Sequence[float]) -> np.ndarray:
        """Blend weights (sum one) at an adverb point; one-hot at each example."""
        return self._rbf(np.atleast_2d(np.asarray(adverbs, dtype=float)))[0]

    def duration(self, weights: np.ndarray) -> float:
        """Blended duration: the weighted mean of example durations."""
        spans = np.array([e.keys()[-1] - e.keys()[0] for e in self.examples])
        return float(max(weights @ spans, 1e-6))

    def _warped_knots(self, weights: np.ndarray) -> np.ndarray:
        """Output-time positions of the correspondence points (blended forward time-warp)."""
        offsets = np.array([e.keys() - e.keys()[0] for e in self.examples])
        return np.maximum.accumulate(weights @ offsets)

    def sample(self, adverbs: Sequence[float], times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations ``(T, J, 4)`` and roots ``(T, 3)`` of the blend at output ``times`` (s)."""
        w = self.weights(adverbs)
        times = np.asarray(times, dtype=float)
        neutral = np.interp(times, self._warped_knots(w), self._neutral)
        at = [_at(example, neutral) for example in self.examples]
        rotations = np.stack([r for r, _ in at])
        roots = np.einsum("e,etc->tc", w, np.stack([root for _, root in at]))
        return _tangent_mean(rotations, np.ascontiguousarray(w, dtype=float), int(np.argmax(w))), roots

    def animation(self, adverbs: Sequence[float], *, fps: float = 10.0, source: str | None = None) -> PoseSet:
        """The blended animation as key-frames, ready to be patched into a motor graph."""
        w = self.weights(adverbs)
        duration = self.duration(w)
        times = np.linspace(0.0, duration, max(2, int(round(duration * fps)) + 1))
        rotations, roots = self.sample(adverbs, times)
        skeleton = self.examples[0].animation.skeleton
        name = source or "blend(" + ", ".join(f"{a:g}" for a in adverbs) + ")"
        return PoseSet.animation(skeleton, rotations, roots, times, name)


def _at(example: Example, neutral: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An example's rotations and roots at neutral times (inverse time-warp, then slerp)."""
    anim = example.animation
    local = np.interp(neutral, np.linspace(0.0, 1.0, len(example.keys())), example.keys())
    frames = np.clip(np.searchsorted(anim.times, local, side="right") - 1, 0, len(anim) - 2)
    span = anim.times[frames + 1] - anim.times[frames]
    u = np.clip((local - anim.times[frames]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
    rotations = _slerp_frames(anim.rotations, frames.astype(np.int64), u)
    roots = (1.0 - u[:, None]) * anim.roots[frames] + u[:, None] * anim.roots[frames + 1]
    return rotations, roots


# --- compiled kernels (a creature's adverb is resampled every cycle, on its tick) -------

@numba.njit(cache=True)
def _slerp_frames(rotations, frames, u):  # pragma: no cover - compiled
    """``slerp(rotations[frames], rotations[frames + 1], u)`` per output time ``(T, J, 4)``."""
    out = np.empty((frames.shape[0], rotations.shape[1], 4))
    for i in range(frames.shape[0]):
        for j in range(rotations.shape[1]):
            q = quat.slerp_one(quat._at(rotations[frames[i]], j), quat._at(rotations[frames[i] + 1], j), u[i])
            for c in range(4):
                out[i, j, c] = q[c]
    return out


@numba.njit(cache=True)
def _tangent_mean(rotations, weights, reference):  # pragma: no cover - compiled
    """The examples' rotations ``(E, T, J, 4)`` blended by ``weights`` in the tangent space of
    the heaviest: ``ref · exp(Σ w log(ref⁻¹ · q))`` per time and joint."""
    e_count, t_count, j_count = rotations.shape[0], rotations.shape[1], rotations.shape[2]
    out = np.empty((t_count, j_count, 4))
    for t in range(t_count):
        for j in range(j_count):
            ref = quat._at(rotations[reference, t], j)
            inverse = (ref[0], -ref[1], -ref[2], -ref[3])
            x = y = z = 0.0
            for e in range(e_count):
                v = quat.log_one(quat.multiply_one(inverse, quat._at(rotations[e, t], j)))
                x += weights[e] * v[0]
                y += weights[e] * v[1]
                z += weights[e] * v[2]
            q = quat.multiply_one(ref, quat.exp_one((x, y, z)))
            for c in range(4):
                out[t, j, c] = q[c]
    return out
