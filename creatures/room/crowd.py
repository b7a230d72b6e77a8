"""Crowds from one table: ``count = N`` on a ``[[creature]]`` table makes N creatures named
``NAME-0`` … ``NAME-(N-1)``, each with its own draw from the table's ``vary`` ranges (REACT's
agents share a knowledge file and differ in radius, mass and speed; IViHumans' clones start at
random offsets).

``vary`` maps a dotted key of the table to a range: ``vary = {"vehicle.max_speed" = [0.8, 1.2],
"channel" = [0, 3]}`` draws each clone's value uniformly from it (integers when both ends
are). Draws come from the installation's seed, so a crowd is the same crowd every run.
``cycle`` maps a dotted key to a list the clones take in turn (clone k gets item k mod its
length): ``cycle = { channel = [0, 1, 2] }`` spreads a crowd over MIDI channels evenly, where
random draws could put two on one channel.
"""

from __future__ import annotations

import copy
import difflib
from typing import Any

import numpy as np

LARGEST_CROWD = 10_000
"""Most creatures one table may make."""


class CrowdError(ValueError):
    """A ``count`` or ``vary`` that cannot make a crowd; ``key`` is where, under the table."""

    def __init__(self, key: tuple[str, ...], message: str) -> None:
        super().__init__(message)
        self.key = key
        self.index = 0  # which [[creature]] table


def _draw(rng: np.random.Generator, span: Any, key: str) -> float | int:
    if (not isinstance(span, list) or len(span) != 2
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in span)):
        raise CrowdError(("vary", key), f"vary[{key!r}] must be a range [low, high] of two numbers, got {span!r}")
    low, high = span
    if not (np.isfinite(low) and np.isfinite(high) and low <= high):
        raise CrowdError(("vary", key), f"vary[{key!r}] = {span!r} is not a range (low ≤ high, finite)")
    if isinstance(low, int) and isinstance(high, int):
        return int(rng.integers(low, high + 1))
    return float(rng.uniform(low, high))


def _set(table: dict, dotted: str, value: Any, section: str = "vary") -> None:
    *parents, last = dotted.split(".")
    for n, part in enumerate(parents):
        if part not in table and table:  # a slip for a written table ("tuples.chrip") would make a new one
            close = difflib.get_close_matches(part, [str(k) for k in table], n=1)
            if close:
                under = f" under {'.'.join(parents[:n])!r}" if n else ""
                raise CrowdError((section, dotted), f"no {part!r}{under} in the table (did you mean {close[0]!r}?)")
        nested = table.setdefault(part, {})
        if not isinstance(nested, dict):
            raise CrowdError((section, dotted), f"{section}[{dotted!r}]: {part!r} is not a table")
        table = nested
    table[last] = value


def created(table: dict) -> list[tuple[tuple[str, ...], str, str]]:
    """What the ``vary`` and ``cycle`` keys of one table write that the table itself does not:
    for each such key, the first part of its path not written (a key path under the table), its
    section ("vary" or "cycle") and its dotted key. A clone's error at or under that path is the
    key's own slip, said at its line rather than at the table around what it made."""
    out = []
    for section in ("vary", "cycle"):
        keys = table.get(section)
        for dotted in keys if isinstance(keys, dict) else ():
            at: Any = table
            parts = tuple(str(dotted).split("."))
            for n, part in enumerate(parts):
                if not isinstance(at, dict) or part not in at:
                    out.append((parts[:n + 1], section, dotted))
                    break
                at = at[part]
    return out


def expand(tables: list[dict], seed: int) -> tuple[list[dict], list[int]]:
    """The creature tables with every ``count`` table replaced by its clones, and for each
    resulting table the index of the table it came from (errors in a clone name the line of
    the table it came from)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 21]))
    out: list[dict] = []
    origin: list[int] = []
    for i, table in enumerate(tables):
        try:
            clones = _clones(table, rng) if "count" in table else [table]
        except CrowdError as exc:
            exc.index = i
            raise
        out.extend(clones)
        origin.extend([i] * len(clones))
    return out, origin


def _clones(table: dict, rng: np.random.Generator) -> list[dict]:
    """The ``count`` creatures of one table, each with its draws from ``vary``."""
    count, vary, cycle = table["count"], table.get("vary", {}), table.get("cycle", {})
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= LARGEST_CROWD:
        raise CrowdError(("count",), f"count must be a whole number from 1 to {LARGEST_CROWD}, got {count!r}")
    if not isinstance(vary, dict):
        raise CrowdError(("vary",), f"vary must be a table of ranges, got {vary!r}")
    if not isinstance(cycle, dict) or not all(isinstance(v, list) and 0 < len(v) <= LARGEST_CROWD
                                              for v in cycle.values()):
        raise CrowdError(("cycle",), f"cycle must be a table of non-empty lists, got {cycle!r}")
    base = {k: v for k, v in table.items() if k not in ("count", "vary", "cycle")}
    clones = []
    for k in range(count):
        clone = copy.deepcopy(base)
        clone["name"] = f"{base.get('name', 'creature')}-{k}"
        for key in sorted(cycle):
            _set(clone, key, copy.deepcopy(cycle[key][k % len(cycle[key])]), "cycle")
        for key in sorted(vary):
            _set(clone, key, _draw(rng, vary[key], key))
        clones.append(clone)
    return clones
