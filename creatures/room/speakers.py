"""Where a creature's sound comes from: pan and gain by position, for a stereo pair or a
ring of loudspeakers (2-D pairwise VBAP, Pulkki 1997, "Virtual sound source positioning
using vector base amplitude panning"; no well-kept Python VBAP library exists, and the 2-D
case is a 2×2 inverse per speaker pair).

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


def vbap(azimuth: float, speakers: np.ndarray) -> np.ndarray:
    """2-D pairwise VBAP gains (len(speakers),) for a source at ``azimuth`` degrees.

    The source direction p is written as g₁l₁ + g₂l₂ over the adjacent pair (l₁, l₂) whose
    arc contains it (the pair whose inverse gives both gains ≥ 0), then normalised to
    g₁² + g₂² = 1. A source outside a stereo pair's arc goes to the nearer speaker."""
    az = np.radians(np.asarray(speakers, dtype=float))
    order = np.argsort(az)
    p = np.array([np.cos(np.radians(azimuth)), np.sin(np.radians(azimuth))])
    gains = np.zeros(len(az))
    pairs = len(order) if len(order) > 2 else 1
    for k in range(pairs):
        i, j = order[k], order[(k + 1) % len(order)]
        base = np.array([[np.cos(az[i]), np.cos(az[j])], [np.sin(az[i]), np.sin(az[j])]])
        if abs(np.linalg.det(base)) < 1e-9:
            continue
        g = np.linalg.solve(base, p)
        if (g >= -1e-9).all():
            g = np.clip(g, 0.0, None)
            gains[[i, j]] = g / np.linalg.norm(g)
            return gains
    nearest = np.argmax(np.cos(az - np.radians(azimuth)))
    gains[nearest] = 1.0
    return gains


def stereo(azimuth: float) -> np.ndarray:
    """(left, right) gains for a source at ``azimuth`` degrees: the listener's whole front
    half (0° = hard right, 180° = hard left) is spread over the pair's ±30° arc, so a room's
    width spans the stereo image; sources behind fold to the front (a pair cannot place them)."""
    front = np.degrees(np.arctan2(abs(np.sin(np.radians(azimuth))), np.cos(np.radians(azimuth))))
    return vbap(60.0 + front / 3.0, STEREO)


def azimuth(source: np.ndarray, listener: np.ndarray) -> float:
    """Direction (degrees, anticlockwise from +x) of ``source`` from ``listener``, both (2,)."""
    d = np.asarray(source, float) - np.asarray(listener, float)
    return float(np.degrees(np.arctan2(d[1], d[0])))
