"""One key of a running creature's spec, read and set: the remote console's ``set`` and a room's
zones (REACT's ActionBoxes change "the agent's attributes") both go through here, so a zone
accepts exactly what the console would, with the schema's own message.

A key is dotted for a nested table (``voice.gain``); a name that holds a dot itself is quoted,
as TOML quotes it (``notes."roll.over"``: the trick ``roll.over`` of the table ``notes``). The
new spec is validated as a config's would be; from then on the creature reads it: what it reads
as it runs (``gain``, which the mixer takes each tick in a room, ``hears_input``,
``voice.gain``, …) changes at once. A key it built parts from when it started, which nothing
reads again (``vehicle``; an authored creature's tuples, groups, drives, percepts, body…; a
voice's strings but for ``voice.gain``: the spec class's ``READ_ONCE``), is refused, not taken,
and so is a table that holds one.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel

from creatures.config import ConfigError, validate

FIXED = ("name", "kind")
"""Keys no running creature may change: they are who it is."""

Spec = TypeVar("Spec", bound=BaseModel)


class SpecKeyError(ValueError):
    """A key or value a creature's spec refuses; the message says why in the schema's words."""


NAME = r'"[^"]+"|[^".]+'
"""One name of a key: as written, or quoted whole when it holds a dot."""
KEY = re.compile(rf"(?:{NAME})(?:\.(?:{NAME}))*")


def path(key: str) -> tuple[str, ...]:
    """The names along ``key``: split at its dots but within double quotes (``notes."roll.over"``
    is ``("notes", "roll.over")``); :class:`SpecKeyError` for an empty name or a stray quote."""
    if not KEY.fullmatch(key):
        raise SpecKeyError(f'{key}: a key is names joined by dots, a name that holds a dot quoted whole '
                           '(notes."roll.over")')
    return tuple(name.strip('"') for name in re.findall(NAME, key))


def dotted(parts: tuple[str, ...]) -> str:
    """``parts`` as a key :func:`path` reads back: a name that holds a dot quoted."""
    return ".".join(f'"{part}"' if "." in part else part for part in parts)


def keys(spec: BaseModel) -> list[str]:
    """Every settable key of ``spec``, dotted, tables descended (for the nearest name to a typo)."""
    def leaves(node: dict, prefix: tuple[str, ...]) -> list[tuple[str, ...]]:
        out = []
        for name, value in node.items():
            out.extend(leaves(value, (*prefix, name)) if isinstance(value, dict) else [(*prefix, name)])
        return out
    return [dotted(parts) for parts in leaves(spec.model_dump(), ()) if parts[0] not in FIXED]


def read(spec: BaseModel, key: str) -> Any:
    """The value of ``key`` in ``spec`` (KeyError when it has none)."""
    node: Any = spec.model_dump()
    for part in path(key):
        if not isinstance(node, dict):
            raise KeyError(key)
        node = node[part]
    return node


def has(spec: BaseModel, key: str) -> bool:
    """Whether ``spec`` has the key ``key`` (a leaf or a table)."""
    try:
        read(spec, key)
    except (KeyError, SpecKeyError):
        return False
    return True


def read_once(spec: BaseModel, parts: tuple[str, ...]) -> str | None:
    """Why the key along ``parts`` cannot be set (its spec class's ``READ_ONCE``: the key, a
    table above it, or a key within it is read once), else None."""
    for entry, why in getattr(type(spec), "READ_ONCE", {}).items():
        held = path(entry)
        if parts[:len(held)] == held or held[:len(parts)] == parts:
            return why
    return None


def with_key(spec: Spec, key: str, value: Any, name: str, *, literal: bool = True) -> Spec:
    """A copy of ``spec`` with ``key`` set to ``value``, validated by its own schema as a
    config would be (:class:`SpecKeyError` with the schema's message; ``name`` is the
    creature's, for the message's file). ``literal=False`` reads 0/1 as a truth value and
    text as a number, as pydantic's lax mode does: an OSC controller (a Max or Pd toggle)
    has no truth values and sends what it has. Lax mode's other truth values ("yes", "on",
    "t" …) are refused still, as a config refuses them."""
    parts = path(key)
    if parts[0] in FIXED:
        raise SpecKeyError(f"{parts[0]} cannot change while the creature runs")
    once = read_once(spec, parts)
    if once is not None:
        raise SpecKeyError(f"{key}: {once}")
    # What the config set, not every default: a validator that asks which keys were given
    # (a body by figure or by files, never both) must see the spec as it was written.
    data, whole = spec.model_dump(exclude_unset=True), spec.model_dump()
    node = data
    for at, part in enumerate(parts[:-1]):
        table, whole = whole, whole.get(part) if isinstance(whole, dict) else None
        if not isinstance(whole, dict):
            named = ".".join(parts[at:])
            quoted = (f" (a name with a dot is quoted: {dotted((*parts[:at], named))})"
                      if isinstance(table, dict) and named in table else "")
            raise SpecKeyError(f"{key}: {part!r} is not a table of {data.get('kind', 'the')}'s spec{quoted}")
        node = node.setdefault(part, {})
    node[parts[-1]] = value
    try:
        return validate(type(spec), data, {}, Path(name), literal=literal)
    except ConfigError as exc:
        raise SpecKeyError(f"{exc.key}: {exc.message}" if exc.key else exc.message) from None
