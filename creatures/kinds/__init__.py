"""Creature kinds, looked up by the ``kind`` key of a ``[[creature]]`` table.

Each kind lives in its own module and registers itself with :func:`register`;
:func:`load_all` imports every module of this package (a new kind is just a new file;
modules of shared parts register nothing) and the modules named by ``creature_music.kinds``
entry points, so a user's package adds kinds the same way.
"""

from __future__ import annotations

import importlib
import pkgutil
from typing import Callable, TypeVar

from creatures.kinds.base import CreatureKind, CreatureSpec

KINDS: dict[str, type[CreatureKind]] = {}

Kind = TypeVar("Kind", bound=type[CreatureKind])


def register(kind: str) -> Callable[[Kind], Kind]:
    """Class decorator: make a :class:`CreatureKind` available as ``kind = "<kind>"`` (the
    class itself is returned unchanged, so type checkers keep its own type)."""

    def add(cls: Kind) -> Kind:
        KINDS[kind] = cls
        return cls

    return add


def load_all() -> dict[str, type[CreatureKind]]:
    """Every kind: this package's modules, then the ``creature_music.kinds`` entry points
    (the authored kind and any user package's kinds) through the parts registry."""
    from creatures.authored.registry import load_parts

    for module in pkgutil.iter_modules(__path__):
        importlib.import_module(f"creatures.kinds.{module.name}")
    load_parts()
    return KINDS


__all__ = ["CreatureKind", "CreatureSpec", "KINDS", "load_all", "register"]
