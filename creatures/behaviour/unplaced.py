"""Learned parts a state file saved under a name the config no longer has (README, "What a
restart keeps").

A creature's state keeps much of what it learned by name: a drive's level, an action-group's
proximity table, a percept's grown tree, an Ac percept's adverb model, a shaping tuple's model,
a tuple's expectation confidence, a part's own state. A name renamed between runs (a typo
corrected, ``boredum`` to ``boredom``) or removed matched nothing at the next load, and what
had been learned under it was forgotten without a word and gone at the next save. :class:`Unplaced` sorts a saved table by the config's names: the entries
a name takes go to their parts; the others are kept, carried into every save, and taken back
when a part of that name returns; and the run says each once at load, with the nearest name
(:meth:`Unplaced.said`, creatures/runtime/session.py). The names one section keeps are said in
one line: a renamed percept whose tree grew five learnt tuples took sixteen lines to say, one
per tuple for its tuple, its value and its expectation; it takes four.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Collection, Iterator, Mapping

from creatures import bounds


@dataclass(frozen=True)
class Unmatched:
    """The saved entries of one section no part takes, as the run says them: ``the saved
    {what} of {of} {names}{within} match no {no} …``, the nearest of ``among`` (the config's
    names of its kind) named."""

    what: str
    of: str
    names: tuple[str, ...]
    within: str
    no: str
    among: tuple[str, ...]


@dataclass(frozen=True)
class _Section:
    what: str
    of: str
    within: str
    no: str
    among: tuple[str, ...]


class Unplaced:
    """The saved entries, section by section (``proximity``, ``levels``, …), that no name of
    the config took at the last :meth:`place`: kept as saved until a part of that name returns."""

    def __init__(self) -> None:
        self.kept: dict[str, dict[str, Any]] = {}
        """Section → name → the entry as saved (checked by the ``check`` given to :meth:`place`)."""
        self._sections: dict[str, _Section] = {}

    def place(self, section: str, saved: Any, names: Collection[str], *, what: str, of: str, no: str | None = None,
              within: str = "", check: Callable[[Any, str], object] | None = None) -> dict[str, Any]:
        """The entries of ``saved`` (a table; :class:`ValueError` naming ``section`` if not)
        whose name is one of ``names``; the others replace what ``section`` kept, each given to
        ``check(entry, key)`` first, so a damaged one is refused naming its key as one a part
        takes is. ``what``, ``of``, ``within`` and ``no`` (``of`` when not given) say them (:class:`Unmatched`)."""
        placed: dict[str, Any] = {}
        kept: dict[str, Any] = {}
        for name, entry in bounds.table(saved, section).items():
            if name in names:
                placed[name] = entry
            else:
                if check is not None:
                    check(entry, f"{section}.{name}")
                kept[name] = entry
        self.kept.pop(section, None)
        if kept:
            self.kept[section] = kept
            self._sections[section] = _Section(what, of, within, no or of, tuple(sorted(names)))
        return placed

    def carry(self, section: str, current: Mapping[str, Any]) -> dict[str, Any]:
        """``current`` (the parts' own state by name) with the entries ``section`` keeps
        beside it, to be saved: a part's own entry wins over a kept one of its name."""
        return {**self.kept.get(section, {}), **current}

    def said(self) -> Iterator[Unmatched]:
        """Each section's kept entries once (sections that say the same, a drive's ``levels``
        and ``inputs``, once for both), in the order their sections were placed."""
        seen: set[Unmatched] = set()
        for section, kept in self.kept.items():
            how = self._sections[section]
            unmatched = Unmatched(how.what, how.of, tuple(sorted(kept)), how.within, how.no, how.among)
            if unmatched not in seen:
                seen.add(unmatched)
                yield unmatched
