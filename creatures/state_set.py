"""A colony's state files saved as one set: all of a save, or none of it (DESIGN.md, "State
that lasts").

Each creature's file was written atomically, but the set was not: a power cut between two
creatures' files left one creature's state from one save beside another's from the save before,
each whole and loadable, and the colony's pulse from either. A save is now written into a hidden
journal folder (:data:`JOURNAL`) beside the files, then the list of its files (:data:`LISTED`),
and only then renamed into place. :func:`settle`, run holding the state folder's lock (a live
run's start, a save, ``state rollback`` and ``merge``), finishes a save whose list was written
(every file of it is whole) and drops one whose list was not (the files in place are still the
last whole set). What reads the folder without its lock (``inspect``, ``state diff``,
``export-motion``; a live start on a read-only folder, which cannot finish the save) reads it
through :func:`files`: the last whole save, whether or not its renames were finished.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from pathlib import Path

from creatures.persist import StateFileError, fsync_directory, write_json_text

JOURNAL = ".saving"
"""The hidden folder a set is written into before it is renamed into place."""

LISTED = ".files"
"""The journal's list of the files of its save, written last: a journal holding it is whole."""


def write_set(directory: Path, saved: list[tuple[str, str]]) -> None:
    """Write ``saved`` (name, JSON text) into ``directory`` as one set. On an error (a full
    disk) before the list is written, the journal is removed and the files in place are kept."""
    directory.mkdir(parents=True, exist_ok=True)
    settle(directory)
    journal = directory / JOURNAL
    journal.mkdir()
    try:
        for name, text in saved:
            write_json_text(journal / name, text)
        write_json_text(journal / LISTED, json.dumps([name for name, _ in saved]))
    except BaseException:
        shutil.rmtree(journal, ignore_errors=True)
        raise
    _roll_forward(directory, journal)


def settle(directory: Path) -> None:
    """Finish a save a crash interrupted after its list was written, or drop one interrupted
    before; nothing to do when no save was under way. Run it holding the folder's lock: a
    journal is never another live process's save in progress then."""
    journal = directory / JOURNAL
    if journal.is_symlink() or journal.exists() and not journal.is_dir():
        raise StateFileError(f"{journal}: not a folder this program wrote (it writes a save there first); "
                             "move it away")
    if not journal.is_dir():
        return
    if (journal / LISTED).is_file():
        _roll_forward(directory, journal)
    else:
        shutil.rmtree(journal)


def files(directory: Path) -> dict[str, Path]:
    """The state files of ``directory`` by name (``NAME.json``, the colony's), as its last whole
    save left them: those of a listed journal where a crash cut its renames short, the folder's
    own otherwise. For a reader that does not hold the folder's lock."""
    found = {p.name: p for p in directory.glob("[!.]*.json")}
    journal = directory / JOURNAL
    if (journal / LISTED).is_file() and not journal.is_symlink():
        found.update({name: journal / name for name in _listed(journal) if (journal / name).is_file()})
    return dict(sorted(found.items()))


def _listed(journal: Path) -> list[str]:
    """The names a journal's list holds; :class:`StateFileError` naming it when damaged."""
    listed = journal / LISTED
    try:
        names = json.loads(listed.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise StateFileError(f"{listed}: unreadable list of a save ({exc}); remove {journal} to keep the "
                             "files in place") from None
    if not (isinstance(names, list) and all(isinstance(n, str) and n and "/" not in n and not n.startswith(".")
                                            for n in names)):
        raise StateFileError(f"{listed}: not a list of state files; remove {journal} to keep the files in place")
    return names


def _roll_forward(directory: Path, journal: Path) -> None:
    """Rename every listed file of ``journal`` into ``directory``, then remove the journal."""
    names = _listed(journal)
    for name in names:
        with contextlib.suppress(FileNotFoundError):  # renamed before a crash cut the roll forward short
            os.replace(journal / name, directory / name)
    fsync_directory(directory)
    shutil.rmtree(journal)
