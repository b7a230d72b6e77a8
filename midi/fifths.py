"""The circle of fifths as a distance between pitches and between what is sung.

Thesis, "sand:stone (installation)": the creatures' "perceptual abilities – based on a
'circle of fifths' distance metric" decide whether the music a creature hears is correlated
with its own. Pitch class ``pc`` sits at position ``7·pc mod 12`` on the circle (C=0, G=1,
D=2, … F=11), and two pitch classes are as far apart as the shorter way round: C–G and C–F
are 1, C–D 2, C–F# 6 (the most distant, the tritone).

A *passage* (a phrase, or what was heard lately) is placed on the same circle by the
direction of the sum of its notes' unit vectors (:func:`fifths_vector`, weighted e.g. by
duration): a diatonic scale points at the middle of its seven neighbouring fifths, so
passages in neighbouring keys are one fifth apart (C major – G major = 1) and passages a
tritone apart are 6 (:func:`circular_distance`). Summing vectors rather than picking a key
means a passage needs no key-finding step and can be accumulated note by note.
"""

from __future__ import annotations

import math

import numpy as np

STEPS = 12
"""Positions on the circle of fifths."""


def fifths_position(pitch: int | np.ndarray) -> int | np.ndarray:
    """Position on the circle of fifths (0..11) of a MIDI pitch or pitch class (C=0, G=1, …)."""
    return (pitch * 7) % STEPS


def fifths_vector(pitches: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Sum of unit vectors at the pitches' circle positions (weighted): ``(2,)``.

    Vectors add, so a passage heard note by note can be accumulated (and decayed) as one
    2-vector instead of kept as a list of notes.
    """
    angle = fifths_position(np.asarray(pitches, dtype=np.int64)) * (2.0 * np.pi / STEPS)
    w = np.ones(len(angle)) if weights is None else np.asarray(weights, dtype=float)
    return np.array([w @ np.cos(angle), w @ np.sin(angle)])


def circular_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Fifths (0..6, continuous) between the directions of two :func:`fifths_vector`'s;
    6 if either is zero (nothing heard has no key, so it cannot be correlated)."""
    ax, ay, bx, by = float(a[0]), float(a[1]), float(b[0]), float(b[1])
    na, nb = math.hypot(ax, ay), math.hypot(bx, by)
    if na == 0.0 or nb == 0.0:
        return STEPS / 2
    cosine = min(1.0, max(-1.0, (ax * bx + ay * by) / (na * nb)))
    return math.acos(cosine) * STEPS / (2.0 * math.pi)
