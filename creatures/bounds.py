"""Bounds every number meets where it enters: config, command line, saved state.

A creature runs for weeks in a gallery; a NaN or a 1e308 let in at a door is not refused
until it has poisoned a drive, a duration or a buffer size, and then it fails far from its
cause (at the next save, or as a MemoryError). So each door checks: config models are built
on :data:`FINITE` (pydantic refuses NaN and infinity in every float field, nested lists and
tuples included) and give every number an upper bound; saved state is read back through
:func:`number`, :func:`count` and :func:`items`, whose messages name the key path so that
:class:`creatures.persist.StateFileError` can say which file and which key is damaged.
Note bounds (pitch, velocity, duration) live with the notes, in :mod:`midi.notes`.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import ConfigDict, Field

FINITE = ConfigDict(extra="forbid", allow_inf_nan=False)
"""The config of every config model: unknown keys and non-finite numbers are errors."""

LONGEST_SECONDS = 366 * 24 * 3600.0
"""A year: the longest span of time (a run, a save interval, a time constant) any door takes."""

LATEST_TIME = 1e12
"""Seconds: the latest clock time anything saved or heard may carry (some 30,000 years on
any clock a run uses), so that sums of times keep sub-millisecond resolution."""

LONGEST_OFFLINE = 7 * 24 * 3600.0
"""A week of simulated time: the longest offline run (its out.wav alone is some 50 GB)."""

Seconds = Annotated[float, Field(ge=0, le=LONGEST_SECONDS)]
"""A time of day in a script or a span (config lists such as click times): 0 to a year."""

LARGEST_RATE = 1e6
"""Largest magnitude of a rate, gain or level that has no natural bound of its own."""

Bounded = Annotated[float, Field(ge=-LARGEST_RATE, le=LARGEST_RATE)]
"""A number with no natural bound of its own (a reading, a reward, a range's end, a drive's
level), bounded all the same."""

MidiPitch = Annotated[int, Field(ge=0, le=127)]
"""A MIDI note number. A phrase to play, or a percept waiting for pitches (``played``,
``motif``), given one past 0–127 would wait for a note no one can play: silent, with nothing
said, so each is refused at its own key and line."""

LARGEST_VALUE = 1e12
"""Largest magnitude of a learned value or model sample read back (squares stay far from
overflow, and no value a creature learns comes near it)."""

LARGEST_COUNT = 2**53
"""Largest count (notes heard, ids handed out) read back: beyond it a float loses units."""


def number(value: Any, what: str, *, low: float = -LARGEST_RATE, high: float = LARGEST_RATE) -> float:
    """``value`` as a float in ``[low, high]``, or :class:`ValueError` naming ``what``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{what}: must be a number, found {_shown(value)}")
    try:
        x = float(value)
    except OverflowError:  # an integer beyond any float
        x = math.inf
    if not (math.isfinite(x) and low <= x <= high):
        raise ValueError(f"{what}: must be a finite number in [{low:g}, {high:g}], found {_shown(value)}")
    return x


def count(value: Any, what: str, *, low: int = 0, high: int = LARGEST_COUNT) -> int:
    """``value`` as an int in ``[low, high]`` (a float is no count), or :class:`ValueError`."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ValueError(f"{what}: must be a whole number in [{low}, {high}], found {_shown(value)}")
    return value


def items(value: Any, what: str, *, longest: int, shortest: int = 0) -> list[Any]:
    """``value`` as a list of ``shortest`` to ``longest`` entries, or :class:`ValueError`."""
    if not isinstance(value, list) or not shortest <= len(value) <= longest:
        size = f"{len(value)} entries" if isinstance(value, list) else _shown(value)
        raise ValueError(f"{what}: must be a list of {shortest} to {longest} entries, found {size}")
    return value


def text(value: Any, what: str) -> str:
    """``value`` as a string, or :class:`ValueError` naming ``what``."""
    if not isinstance(value, str):
        raise ValueError(f"{what}: must be text, found {_shown(value)}")
    return value


def table(value: Any, what: str) -> dict[str, Any]:
    """``value`` as a JSON object, or :class:`ValueError` naming ``what``."""
    if not isinstance(value, dict):
        raise ValueError(f"{what}: must be a table, found {_shown(value)}")
    return value


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else f"a {type(value).__name__}"
