"""Registries of the parts an authored creature is made of: actions, percepts, models (Du and
V) and whole kinds, bound to code by name (STYLE.md: "Pieces are data"; after pytest's and
mido's plugins).

A part is a small documented class: ``name`` (what a config writes), ``thesis`` (the heading it
implements), ``Params`` (a pydantic model of its keys, validated at load) and ``build``. Parts
join a registry with its ``register`` decorator. The built-in parts live in modules named by
this project's own entry points (``[project.entry-points."creature_music.actions"]`` …); a
user's pip package adds modules the same way, and a ``plugins`` file next to a config is
imported by path. :func:`load_parts` imports all of them once; a module that fails to import
is a :class:`PluginError` naming it.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any, ClassVar, Generic, Iterator, TypeVar

from pydantic import BaseModel

from creatures.bounds import FINITE
from creatures.config import nearest

GROUPS = ("actions", "percepts", "models", "kinds")
"""Entry point groups are ``creature_music.<group>``; each entry names a module to import."""

BUILTIN = {
    "actions": ("creatures.authored.actions", "creatures.score.action"),
    "percepts": ("creatures.authored.percepts",),
    "models": ("creatures.authored.models",),
    # The authored creature, then the pieces still written as whole kinds (extension API: a
    # kind as a small documented class; docs/authoring.md, "The shipped pieces, by behaviour").
    "kinds": ("creatures.authored.creature", "creatures.kinds.curve", "creatures.kinds.duncan",
              "creatures.kinds.ozymandias", "creatures.kinds.three_creatures"),
}
"""The project's own entry points (pyproject.toml lists the same; a test keeps them equal).
Imported directly as well, so a source checkout whose installed metadata is older still has
its built-in parts."""


class PluginError(Exception):
    """A plugin (entry point or ``plugins`` file) could not be imported or registered."""


class Params(BaseModel):
    """The keys of a part (subclassed by each part with its own fields): unknown keys and
    non-finite numbers are errors, as everywhere in a config (creatures/bounds.py)."""

    model_config = FINITE


class Part:
    """What every registered part declares (subclasses: actions, percepts, models)."""

    name: ClassVar[str]
    thesis: ClassVar[str] = ""
    Params: ClassVar[type[BaseModel]] = Params
    needs: ClassVar[str | None] = None
    """What of the creature the part uses beyond its ear and drives: "body" (``body = true``)
    or "space" (a ``[creature.space]`` table as well); checked at load."""
    refs: ClassVar[dict[str, str]] = {}
    """Params keys that name other things: key → "percepts", "drives" or "tuples" (a name or
    a list of names), or "utterances" / "populations" / "adverb models" (a percept of type
    'utterance' / 'population' / 'adverb_model'), checked at load and
    followed for reference cycles."""

    @classmethod
    def references(cls, params: BaseModel) -> list[tuple[str, str, str]]:
        """``(key, namespace, name)`` of every name ``params`` refers to."""
        out = []
        for key, namespace in cls.refs.items():
            given = getattr(params, key, None)
            for name in [given] if isinstance(given, str) else (given or []):
                out.append((key, namespace, name))
        return out

    @classmethod
    def summary(cls) -> str:
        return " ".join((cls.__doc__ or "").strip().split("\n\n")[0].split())


P = TypeVar("P", bound=type[Part])


def claim(parts: dict[str, Any], name: str, cls: type, what: str) -> None:
    """Enter ``cls`` as ``parts[name]``, or :class:`PluginError` when another class has that
    name: a plugin's ``echo`` silently took the built-in's place for every creature, and a
    config written for the built-in then failed on keys the plugin's part lacked. The same
    class again (a module imported twice) is no clash."""
    taken = parts.get(name)
    if taken is not None and (taken.__module__, taken.__qualname__) != (cls.__module__, cls.__qualname__):
        source = getattr(sys.modules.get(taken.__module__), "__file__", None) or taken.__module__
        raise PluginError(f"{cls.__qualname__}: the {what} name {name!r} is taken by {taken.__qualname__} of "
                          f"{source}; give this one a name of its own")
    parts[name] = cls


class Registry(Generic[P]):
    """Parts of one kind by name; ``lookup`` suggests the nearest name for a typo."""

    def __init__(self, what: str) -> None:
        self.what = what
        self._parts: dict[str, P] = {}

    def register(self, cls: P) -> P:
        """Class decorator: make ``cls`` available as ``type = cls.name``."""
        name = getattr(cls, "name", None)
        if not isinstance(name, str) or not name:
            raise PluginError(f"{cls.__qualname__}: a {self.what} needs a class attribute 'name'")
        claim(self._parts, name, cls, self.what)
        return cls

    def names(self) -> list[str]:
        return sorted(self._parts)

    def get(self, name: str) -> P | None:
        return self._parts.get(name)

    def unknown(self, name: object) -> str:
        """The message for a name that is not registered, with the nearest valid one."""
        return f"unknown {self.what} {name!r}{nearest(name, self.names(), 'choose from')}"

    def __iter__(self) -> Iterator[P]:
        return iter(self._parts[n] for n in self.names())

    def __contains__(self, name: object) -> bool:
        return name in self._parts


ACTIONS: Registry[Any] = Registry("action")
PERCEPTS: Registry[Any] = Registry("percept")
MODELS: Registry[Any] = Registry("model")

_loaded: set[str] = set()

FOREIGN_FAILURES = (Exception, SystemExit)
"""What importing a plugin may raise that is the plugin's failure: a script reused as one, its
``argparse`` or ``sys.exit()`` run at import, ended the program with its own usage line and
no word of the config or the plugin."""


def _import(module: str, origin: str) -> None:
    if module in _loaded:
        return
    try:
        importlib.import_module(module)
    except FOREIGN_FAILURES as exc:  # any failure of foreign code is that plugin's error, named
        raise PluginError(f"{origin}: cannot import {module!r} ({type(exc).__name__}: {exc})") from None
    _loaded.add(module)


_scanned_path: tuple[str, ...] | None = None


def load_parts() -> None:
    """Import the built-in parts and every installed package's ``creature_music.*`` entry points.

    Scanning the installed packages' metadata costs ~15 ms a group, and every authored
    creature asks (twice: its check and its build), so 200 creatures spent 12 s starting; the
    scan is done again only when ``sys.path`` has changed (a package put on it since)."""
    global _scanned_path
    if _scanned_path == tuple(sys.path):
        return
    for group in GROUPS:
        for module in BUILTIN[group]:
            _import(module, f"built-in {group}")
        for ep in entry_points(group=f"creature_music.{group}"):
            _import(ep.value.split(":")[0], f"entry point {ep.name!r} of creature_music.{group}")
    _scanned_path = tuple(sys.path)


def load_plugin_file(path: Path) -> None:
    """Import a ``plugins`` file by path (once); its ``register`` decorators add its parts."""
    path = path.resolve()
    key = f"creature_music_plugin_{abs(hash(str(path)))}"
    if key in _loaded:
        return
    if not path.is_file():
        raise PluginError(f"plugin file not found: {path}")
    spec = importlib.util.spec_from_file_location(key, path)
    if spec is None or spec.loader is None:
        raise PluginError(f"{path}: not a Python module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[key] = module
    try:
        spec.loader.exec_module(module)
    except FOREIGN_FAILURES as exc:  # the plugin's own bug, reported as such
        del sys.modules[key]
        raise PluginError(f"{path}: plugin failed to import ({type(exc).__name__}: {exc})") from None
    _loaded.add(key)
