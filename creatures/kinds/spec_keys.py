"""One key of a running creature's spec, read and set: the remote console's ``set`` and a room's
zones (REACT's ActionBoxes change "the agent's attributes") both go through here, so a zone
accepts exactly what the console would, with the schema's own message.

A key is dotted for a nested table (``voice.gain``). The new spec is validated as a config's
would be; from then on the creature reads it: what it reads as it runs (``gain``, which the
mixer takes each tick in a room, ``hears_input``, ``voice.gain``, …) changes at once. A key it
built parts from when it started, which nothing reads again (``vehicle``; an authored
creature's tuples, groups, drives, percepts, body…; a voice's strings but for ``voice.gain``:
the spec class's ``READ_ONCE``), is refused, not taken, and so is a table that holds one.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel

from creatures.config import ConfigError, validate

FIXED = ("name", "kind")
"""Keys no running creature may change: they are who it is."""

Spec = TypeVar("Spec", bound=BaseModel)


class SpecKeyError(ValueError):
    """A key or value a creature's spec refuses; the message says why in the schema's words."""


def keys(spec: BaseModel) -> list[str]:
    """Every settable key of ``spec``, dotted, tables descended (for the nearest name to a typo)."""
    def leaves(node: dict, prefix: str) -> list[str]:
        out = []
        for name, value in node.items():
            out.extend(leaves(value, f"{prefix}{name}.") if isinstance(value, dict) else [f"{prefix}{name}"])
        return out
    return [key for key in leaves(spec.model_dump(), "") if key.split(".")[0] not in FIXED]


def read(spec: BaseModel, key: str) -> Any:
    """The value of ``key`` in ``spec`` (KeyError when it has none)."""
    node: Any = spec.model_dump()
    for part in key.split("."):
        if not isinstance(node, dict):
            raise KeyError(key)
        node = node[part]
    return node


def has(spec: BaseModel, key: str) -> bool:
    """Whether ``spec`` has the key ``key`` (a leaf or a table)."""
    try:
        read(spec, key)
    except KeyError:
        return False
    return True


def read_once(spec: BaseModel, parts: tuple[str, ...]) -> str | None:
    """Why the key along ``parts`` cannot be set (its spec class's ``READ_ONCE``: the key, a
    table above it, or a key within it is read once), else None."""
    for entry, why in getattr(type(spec), "READ_ONCE", {}).items():
        held = tuple(entry.split("."))
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
    parts = tuple(key.split("."))
    if parts[0] in FIXED:
        raise SpecKeyError(f"{parts[0]} cannot change while the creature runs")
    once = read_once(spec, parts)
    if once is not None:
        raise SpecKeyError(f"{key}: {once}")
    # What the config set, not every default: a validator that asks which keys were given
    # (a body by figure or by files, never both) must see the spec as it was written.
    data, whole = spec.model_dump(exclude_unset=True), spec.model_dump()
    node = data
    for part in parts[:-1]:
        whole = whole.get(part) if isinstance(whole, dict) else None
        if not isinstance(whole, dict):
            raise SpecKeyError(f"{key}: {part!r} is not a table of {data.get('kind', 'the')}'s spec")
        node = node.setdefault(part, {})
    node[parts[-1]] = value
    try:
        return validate(type(spec), data, {}, Path(name), literal=literal)
    except ConfigError as exc:
        raise SpecKeyError(f"{exc.key}: {exc.message}" if exc.key else exc.message) from None
