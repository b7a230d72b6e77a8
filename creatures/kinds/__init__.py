"""Creature kinds, looked up by the ``kind`` key of a ``[[creature]]`` table.

Each kind lives in its own module and registers itself with :func:`register`;
:func:`load_all` imports the modules named by ``creature_music.kinds`` entry points, the
project's own (the authored creature and the pieces still written as classes) as a user's
package's (:mod:`creatures.authored.registry`); modules of shared parts register nothing.
"""

from __future__ import annotations

from typing import Callable, TypeVar

from creatures.kinds.base import CreatureKind, CreatureSpec

KINDS: dict[str, type[CreatureKind]] = {}

Kind = TypeVar("Kind", bound=type[CreatureKind])


def register(kind: str) -> Callable[[Kind], Kind]:
    """Class decorator: make a :class:`CreatureKind` available as ``kind = "<kind>"`` (the
    class itself is returned unchanged, so type checkers keep its own type)."""

    def add(cls: Kind) -> Kind:
        from creatures.authored.registry import claim

        claim(KINDS, kind, cls, "creature kind")
        return cls

    return add


def load_all() -> dict[str, type[CreatureKind]]:
    """Every kind: the ``creature_music.kinds`` entry points (the project's and any user
    package's) through the parts registry."""
    from creatures.authored.registry import load_parts

    load_parts()
    return KINDS


__all__ = ["CreatureKind", "CreatureSpec", "KINDS", "load_all", "register"]
