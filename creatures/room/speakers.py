"""Where a creature's sound comes from: pan and gain by position, for a stereo pair or a
ring of loudspeakers (2-D pairwise VBAP, Pulkki 1997, "Virtual sound source positioning
using vector base amplitude panning"; the 2-D case is a 2×2 inverse per speaker pair).
spaudiopy's VBAP is 3-D only (a ring's hull is flat), loops in Python over sources and
triangles, and imports matplotlib and h5py with the package: a live tick pans every voice here
in a few numpy calls instead (README, "Creatures in a room").

A speaker layout is a list of azimuths (degrees, anticlockwise from +x as seen from the
listening point); gains are amplitude gains normalised to unit power, so a voice moving
round the ring keeps its loudness.
"""

from __future__ import annotations

import numpy as np


def ring(n: int, offset: float = 0.0) -> np.ndarray:
    """Azimuths (degrees) of ``n`` speakers evenly round a ring, the first at ``offset``."""
    if n < 2:
        raise ValueError("a ring needs at least two speakers")
    return (offset + 360.0 * np.arange(n) / n) % 360.0


STEREO = np.array([120.0, 60.0])
"""Left and right of a standard stereo pair (±30° about the listener's front, +y)."""


def vbap(azimuth: float | np.ndarray, speakers: np.ndarray) -> np.ndarray:
    """2-D pairwise VBAP gains for sources at ``azimuth`` degrees: (len(speakers),) for one,
    (N, len(speakers)) for N.

    Each source direction p is written as g₁l₁ + g₂l₂ over the adjacent pair (l₁, l₂) whose
    arc contains it (p's angle, sorted among the speakers' angles, falls between them), then
    normalised to g₁² + g₂² = 1. With two speakers (stereo) the one pair is the front arc
    between them and a source outside it goes to the nearer speaker."""
    az = np.radians(np.asarray(speakers, dtype=float))
    order = np.argsort(az)
    sorted_az = az[order]
    a = np.radians(np.atleast_1d(np.asarray(azimuth, dtype=float))) % (2 * np.pi)
    p = np.stack([np.cos(a), np.sin(a)], axis=1)
    n = len(order)
    if n == 2:  # the pair's own arc (the shorter way round), else the nearer speaker
        k = np.zeros(len(a), dtype=np.intp)
    else:
        k = (np.searchsorted(sorted_az, a, side="right") - 1) % n  # arc from sorted k to k + 1
    i, j = order[k], order[(k + 1) % n]
    unit_i = np.stack([np.cos(az[i]), np.sin(az[i])], axis=1)
    unit_j = np.stack([np.cos(az[j]), np.sin(az[j])], axis=1)
    det = unit_i[:, 0] * unit_j[:, 1] - unit_j[:, 0] * unit_i[:, 1]
    gi = (p[:, 0] * unit_j[:, 1] - unit_j[:, 0] * p[:, 1]) / det  # Cramer's rule for the 2×2 base
    gj = (unit_i[:, 0] * p[:, 1] - p[:, 0] * unit_i[:, 1]) / det
    gains = np.zeros((len(a), n))
    rows = np.arange(len(a))
    inside = (gi >= -1e-9) & (gj >= -1e-9)
    g = np.stack([np.clip(gi, 0, None), np.clip(gj, 0, None)], axis=1)
    g /= np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-12)
    gains[rows[inside], i[inside]] = g[inside, 0]
    gains[rows[inside], j[inside]] = g[inside, 1]
    outside = ~inside
    nearest = np.argmax(np.cos(az[None, :] - a[:, None]), axis=1)
    gains[rows[outside], nearest[outside]] = 1.0
    return gains[0] if np.ndim(azimuth) == 0 else gains


def stereo(azimuth: float | np.ndarray) -> np.ndarray:
    """(left, right) gains for sources at ``azimuth`` degrees: the listener's whole front
    half (0° = hard right, 180° = hard left) is spread over the pair's ±30° arc, so a room's
    width spans the stereo image; sources behind fold to the front (a pair cannot place them)."""
    a = np.radians(azimuth)
    front = np.degrees(np.arctan2(np.abs(np.sin(a)), np.cos(a)))
    return vbap(60.0 + front / 3.0, STEREO)


def azimuth(source: np.ndarray, listener: np.ndarray) -> float | np.ndarray:
    """Direction (degrees, anticlockwise from +x) of ``source`` (2,) or (N, 2) from ``listener`` (2,)."""
    d = np.asarray(source, float) - np.asarray(listener, float)
    out = np.degrees(np.arctan2(d[..., 1], d[..., 0]))
    return float(out) if np.ndim(out) == 0 else out


DOME = ((0.0, 0.0), (45.0, 0.0), (90.0, 0.0), (135.0, 0.0), (180.0, 0.0), (225.0, 0.0), (270.0, 0.0), (315.0, 0.0),
        (45.0, 45.0), (135.0, 45.0), (225.0, 45.0), (315.0, 45.0), (0.0, 90.0))
"""The default dome, (azimuth, elevation) degrees: a ring of eight at ear height, four at 45°
and one overhead (13 channels, in this order)."""


def direction(azimuth: np.ndarray, elevation: np.ndarray) -> np.ndarray:
    """Unit vectors (N, 3) of directions in degrees (azimuth anticlockwise from +x, elevation up)."""
    a, e = np.radians(azimuth), np.radians(elevation)
    return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=-1)


class Dome:
    """3-D VBAP (Pulkki 1997, triplet-wise) over a dome of speakers: the speakers' directions
    are triangulated by their convex hull, with a virtual speaker at the nadir closing the
    hull under the lowest ring (its triangles' gains on it are dropped, so a source at or below
    ear height pans over the ring alone). Each source is written as g·L over the triangle whose
    base gives no negative gain (one always does: a layout that leaves the listener outside its
    hull is refused), normalised to unit power."""

    def __init__(self, layout: tuple[tuple[float, float], ...] | list = DOME) -> None:
        from scipy.spatial import ConvexHull

        angles = np.asarray(layout, dtype=float).reshape(-1, 2)
        if len(angles) < 3:
            raise ValueError("a dome needs at least three speakers")
        self.speakers = direction(angles[:, 0], angles[:, 1])
        points = np.vstack([self.speakers, [[0.0, 0.0, -1.0]]])
        try:
            hull = ConvexHull(points)
        except (ValueError, RuntimeError) as exc:  # scipy's QhullError is a RuntimeError
            raise ValueError(f"the dome's speakers span no solid ({str(exc).splitlines()[0]})") from None
        if not np.all(hull.equations[:, 3] < -1e-9):
            # The listener must be inside the speakers' hull, or some directions lie in no
            # triangle: a dome all at ear height (or all to one side) would put the sound of
            # a creature above it nowhere, or on the wrong speaker.
            raise ValueError("the dome's speakers must surround the listener above ear height (some above it, "
                             "on every side)")
        # Each triangle's inverse base: g = p · inv(L), rows of L its three speakers (no face
        # passes through the listener, so every base inverts).
        self.triangles = hull.simplices
        self.inverse = np.linalg.inv(points[hull.simplices])  # (T, 3, 3)

    def gains(self, azimuth: np.ndarray, elevation: np.ndarray) -> np.ndarray:
        """Amplitude gains (N, speakers) of sources at ``azimuth``, ``elevation`` degrees."""
        p = direction(np.atleast_1d(azimuth), np.atleast_1d(elevation))
        g = np.einsum("ni,tij->ntj", p, self.inverse)  # (N, T, 3) every triangle's gains
        best = np.argmax(g.min(axis=2), axis=1)  # the triangle holding p: all its gains ≥ 0
        rows = np.arange(len(p))
        chosen = np.clip(g[rows, best], 0.0, None)
        out = np.zeros((len(p), len(self.speakers) + 1))
        out[rows[:, None], self.triangles[best]] = chosen
        out = out[:, :-1]  # the nadir is not a speaker
        return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
