"""The shipped installations: one TOML config each (see README, "Installations").

This folder is a package only so the configs install with the code; ``path(name)`` finds one.
"""

from __future__ import annotations

import difflib
from pathlib import Path

HERE = Path(__file__).resolve().parent


def names() -> list[str]:
    """Names of the shipped installations (config files without ``.toml``)."""
    return sorted(p.stem for p in HERE.glob("*.toml") if not p.stem.startswith("_"))


CREATURES = HERE / "creatures"
"""Shipped creature documents: ``kind = "exchange"`` starts a ``[[creature]]`` table from
``creatures/exchange.toml`` (creatures/authored/include.py, :func:`expand_kinds`)."""


def creature_names() -> list[str]:
    """Names of the shipped creature documents (usable as ``kind``)."""
    return sorted(p.stem for p in CREATURES.glob("*.toml"))


TUTORIAL = "tutorial"
"""The folder of the tutorial's steps, run by name too: ``creatures demo tutorial/heron-1``."""


def nearest(name: str) -> str | None:
    """The shipped installation (or tutorial step) whose name is nearest ``name``, if one is near."""
    steps = [f"{TUTORIAL}/{p.stem}" for p in (HERE / TUTORIAL).glob("*.toml")]
    close = difflib.get_close_matches(name, [*names(), *steps], n=1)
    return close[0] if close else None


def path(name: str) -> Path:
    """The config file of a shipped installation, or a clear error naming the nearest one and
    listing the choices."""
    candidate = HERE / f"{name}.toml"
    if not candidate.is_file():
        close = nearest(name)
        hint = f" (did you mean {close!r}?)" if close else ""
        raise FileNotFoundError(f"no shipped installation {name!r}{hint}; choose from {names()} "
                                f"or a step of {TUTORIAL}/")
    return candidate


SEEN_NOT_HEARD = {("sandstone", "ozymandias"): "the statue: the rocks' presence moves it; the rocks sing",
                  ("void", "eddie"): "a diner character: visitors make him dance; the score plays for him",
                  ("void", "elliot"): "a diner character", ("void", "earl"): "a diner character"}
"""Creatures whose part in a piece is to be seen: they act by moving, not by sounding."""

CUTTING = {("void", "camera"): "the camera creature: its acts are its cuts, which the score's balance follows"}
"""Creatures whose acts are choices others perceive: each selection of a tuple is an act."""

UNHEARD = {**SEEN_NOT_HEARD, **CUTTING}
"""Creatures whose acts make no sound: a silence of theirs is no silence of the piece."""
