"""Creature kinds, looked up by the ``kind`` key of a ``[[creature]]`` table.

Each kind lives in its own module and registers itself with :func:`register`;
:func:`load_all` imports every module of this package (a new kind is just a new file;
modules of shared parts register nothing).
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
    for module in pkgutil.iter_modules(__path__):
        importlib.import_module(f"creatures.kinds.{module.name}")
    return KINDS


__all__ = ["CreatureKind", "CreatureSpec", "KINDS", "load_all", "register"]
