"""Where notes go in space, and the motor system reaching for them (thesis *exchange*).

*exchange* creatures place every note they hear "in space" and play a note when they
strike it; the motor system answers "what is the closest note object?" in its own metric
and takes the body there. :class:`NotePlacement` decides *where* a heard note is placed, in
cylindrical coordinates about a vertical axis: pitch sets height and azimuth (low notes low
and to one side), key velocity sets the distance from the axis. The note objects
themselves live in :mod:`midi.note_objects`; anything with a ``position`` will do here.
:func:`nearest_note` is "strike the nearest note": one A* search whose goals are the poses
that put the end-effector on any note.

:func:`exchange_metric` is the *exchange* twist on the distance metric: time jumps that are
low-integer ratios of the source animation's length become cheap, so the animator can
"carve the temporal equivalent of note triads out of animation material".
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol, Sequence, TypeVar

import numpy as np

from creatures.motor.metric import MetricWeights, low_integer_ratios
from creatures.motor.search import GraphPosition, NoPath, Path, PathFinder


class Placed(Protocol):
    """A note object as the motor system sees it: somewhere in space."""

    position: np.ndarray


N = TypeVar("N", bound=Placed)


@dataclass(frozen=True)
class NotePlacement:
    """Pitch → (height, azimuth), velocity → distance, about a vertical axis through ``centre``.

    Azimuth is measured about +y from the +z (forward) direction.
    """

    centre: tuple[float, float, float] = (0.0, 1.5, 0.0)
    pitch_range: tuple[int, int] = (48, 84)
    height_range: tuple[float, float] = (-0.4, 0.4)
    azimuth_range: tuple[float, float] = (-1.2, 0.2)
    distance_range: tuple[float, float] = (0.3, 0.7)

    @classmethod
    def around(cls, positions: np.ndarray, *, axis: Sequence[float] = (0.0, 0.0), pitch_range: tuple[int, int] = (48, 84), coverage: float = 10.0) -> NotePlacement:
        """Fit the space to where an end-effector can go (``positions`` ``(N, 3)``).

        Ranges are the ``coverage``..``100 − coverage`` percentiles of the effector's
        height, azimuth and distance about a vertical axis at ``(x, z) = axis``, so the
        notes fall where the body's source material reaches.
        """
        positions = np.asarray(positions, dtype=float)
        x = positions[:, 0] - axis[0]
        z = positions[:, 2] - axis[1]
        height = positions[:, 1]
        azimuth = np.arctan2(x, z)
        distance = np.hypot(x, z)
        lo, hi = coverage, 100.0 - coverage
        centre_y = float(np.median(height))

        def span(values: np.ndarray, shift: float = 0.0) -> tuple[float, float]:
            return (float(np.percentile(values, lo)) - shift, float(np.percentile(values, hi)) - shift)

        return cls(
            centre=(float(axis[0]), centre_y, float(axis[1])),
            pitch_range=pitch_range,
            height_range=span(height, centre_y),
            azimuth_range=span(azimuth),
            distance_range=span(distance),
        )

    def _unit(self, pitch: np.ndarray) -> np.ndarray:
        lo, hi = self.pitch_range
        return np.clip((np.asarray(pitch, dtype=float) - lo) / (hi - lo), 0.0, 1.0)

    def place(self, pitch: np.ndarray | int, velocity: np.ndarray | int) -> np.ndarray:
        """World position(s) of notes ``(..., 3)``."""
        u = self._unit(pitch)
        v = np.clip(np.asarray(velocity, dtype=float) / 127.0, 0.0, 1.0)
        height = np.interp(u, [0.0, 1.0], self.height_range)
        azimuth = np.interp(u, [0.0, 1.0], self.azimuth_range)
        distance = np.interp(v, [0.0, 1.0], self.distance_range)
        cx, cy, cz = self.centre
        return np.stack((cx + distance * np.sin(azimuth), cy + height, cz + distance * np.cos(azimuth)), axis=-1)

    def note_at(self, position: np.ndarray) -> tuple[int, int]:
        """The (pitch, velocity) whose place is nearest ``position`` (the inverse mapping).

        Pitch is read from height and azimuth together (least squares on the pitch line),
        velocity from the distance to the axis.
        """
        cx, cy, cz = self.centre
        x, y, z = np.asarray(position, dtype=float) - np.array([cx, cy, cz])
        candidates = np.arange(self.pitch_range[0], self.pitch_range[1] + 1)
        u = self._unit(candidates)
        heights = np.interp(u, [0.0, 1.0], self.height_range)
        azimuths = np.interp(u, [0.0, 1.0], self.azimuth_range)
        distance = float(np.hypot(x, z))
        gap = np.hypot(heights - y, distance * (azimuths - np.arctan2(x, z)))
        pitch = int(candidates[np.argmin(gap)])
        lo, hi = self.distance_range
        velocity = int(round(127.0 * np.clip((distance - lo) / (hi - lo) if hi > lo else 0.5, 0.0, 1.0)))
        return pitch, velocity


def nearest_note(
    finder: PathFinder,
    start: GraphPosition | int,
    effector: str,
    notes: Sequence[N],
    *,
    tolerance: float = 0.1,
) -> tuple[N, Path]:
    """"Strike the nearest note": the note reachable by the cheapest path, and that path.

    Each note's goals are the poses putting ``effector`` within ``tolerance`` of it (or
    the single closest pose); a single A* search over all goals finds the nearest.
    """
    if not notes:
        raise NoPath("there are no notes in space")
    owner: dict[int, int] = {}
    for k, note in enumerate(notes):
        for node in finder.effector_goals(effector, note.position, tolerance).tolist():
            owner.setdefault(node, k)
    path = finder.path(start, list(owner))
    return notes[owner[path.goal]], path


def exchange_metric(weights: MetricWeights | None = None, *, limit: int = 4, tolerance: float = 0.05) -> MetricWeights:
    """The *exchange* metric: favour time jumps at ratios ``p/q`` (``q ≤ limit``) of the source length."""
    return replace(weights or MetricWeights(), ratios=low_integer_ratios(limit), ratio_tolerance=tolerance)
