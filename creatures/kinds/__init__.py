"""Creature kinds, looked up by the ``kind`` key of a ``[[creature]]`` table.

Each kind lives in its own module and registers itself with :func:`register`; importing this
package imports them all so every config can name any of them.
"""

from __future__ import annotations

import importlib

from creatures.kinds.base import CreatureKind, CreatureSpec

KINDS: dict[str, type[CreatureKind]] = {}

_MODULES: tuple[str, ...] = ("exchange",)


def register(kind: str):
    """Class decorator: make a :class:`CreatureKind` available as ``kind = "<kind>"``."""

    def add(cls: type[CreatureKind]) -> type[CreatureKind]:
        KINDS[kind] = cls
        return cls

    return add


def load_all() -> dict[str, type[CreatureKind]]:
    for module in _MODULES:
        importlib.import_module(f"creatures.kinds.{module}")
    return KINDS


__all__ = ["CreatureKind", "CreatureSpec", "KINDS", "load_all", "register"]
