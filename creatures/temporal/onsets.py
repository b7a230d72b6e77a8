"""Onsets → inter-onset intervals, shared by the MIDI and audio listening paths (thesis:
"exotic duration models": the durations a rhythm-aware duration model hears are the gaps
between note onsets; "listen (installation)": creatures obtain timed note events).

Plain numpy functions in the style of ``librosa.onset``: arrays in, arrays out, keyword-only
options. MIDI note-ons and librosa's ``onset_detect(units="time")`` both give onset times in
seconds; these helpers turn either into the durations a :mod:`creatures.temporal.durations`
model learns from.
"""

from __future__ import annotations

import numpy as np


def _as_onsets(onsets: np.ndarray | list[float]) -> np.ndarray:
    x = np.asarray(onsets, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"onsets must be a flat sequence of times (got shape {x.shape})")
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        raise ValueError(f"onset {bad[0]} is not a finite time ({x[bad[0]]!r})")
    return x


def merge_onsets(onsets: np.ndarray | list[float], *, min_gap: float = 0.0) -> np.ndarray:
    """Sorted onsets with near-simultaneous ones merged into the first of each run.

    A chord's notes (or one drum hit detected twice) arrive a few milliseconds apart and
    are one rhythmic event: an onset closer than ``min_gap`` seconds to the onset before it
    joins that onset's event. A run of onsets each within ``min_gap`` of the previous one is
    a single event at the run's first time (a rolled chord).

    >>> merge_onsets([0.0, 0.004, 0.5, 1.0], min_gap=0.02)
    array([0. , 0.5, 1. ])
    """
    if not min_gap >= 0.0:
        raise ValueError(f"min_gap must be a non-negative number of seconds (got {min_gap!r})")
    x = np.sort(_as_onsets(onsets))
    if x.size == 0:
        return x
    keep = np.empty(x.size, dtype=bool)
    keep[0] = True
    np.greater(np.diff(x), min_gap, out=keep[1:])  # min_gap 0 still merges exact duplicates
    return x[keep]


def inter_onset_intervals(onsets: np.ndarray | list[float], *, min_gap: float = 0.0) -> np.ndarray:
    """Inter-onset intervals (seconds) of the merged, sorted onsets.

    Simultaneous onsets never produce a zero interval (a duration model rejects those), and
    onsets given out of order are sorted first, so a stream concatenated from several
    sources still yields positive intervals.

    >>> inter_onset_intervals([0.0, 0.6, 0.6, 0.9, 1.5])
    array([0.6, 0.3, 0.6])
    """
    return np.diff(merge_onsets(onsets, min_gap=min_gap))


def onsets_from_intervals(intervals: np.ndarray | list[float], *, start: float = 0.0) -> np.ndarray:
    """The onset times that produce ``intervals`` when the first onset is at ``start``.

    The inverse of :func:`inter_onset_intervals` for positive intervals, used to render a
    rhythm (a list of durations) as note-on times.
    """
    d = np.asarray(intervals, dtype=float)
    if d.ndim != 1 or not (np.isfinite(d).all() and (d > 0).all()):
        raise ValueError("intervals must be a flat sequence of positive, finite seconds")
    return start + np.concatenate(([0.0], np.cumsum(d)))
