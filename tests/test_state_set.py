"""A colony's state saved as one set (creatures/state_set.py): after a crash at any point of a
save, the state folder loads as all of one save, never creatures from two."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from creatures.persist import StateFileError
from creatures.state_set import JOURNAL, LISTED, files, settle, write_set
from test_faults import _colony_session, colony  # noqa: F401 (a fixture)

OLD = [("ada.json", '{"save": 1}'), ("bo.json", '{"save": 1}'), ("colony.state.json", '{"save": 1}')]
NEW = [(name, '{"save": 2}') for name, _ in OLD]


def _saves(directory: Path) -> dict[str, int]:
    return {p.name: json.loads(p.read_text())["save"] for p in sorted(directory.glob("*.json"))}


class Crash(Exception):
    """A power cut, as far as the files on disk can tell."""


def _crash_at_rename(monkeypatch, after: int) -> None:
    """The process dies as the ``after + 1``-th rename of a file into place is made."""
    real, made = os.replace, []

    def replace(src, dst, *args, **kwargs):
        if Path(src).parent.name == JOURNAL and Path(dst).parent.name != JOURNAL:
            if len(made) == after:
                raise Crash
            made.append(dst)
        return real(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "replace", replace)


@pytest.mark.parametrize("after", [0, 1, 2])
def test_a_save_cut_short_while_renaming_is_finished_by_the_next_start(tmp_path, monkeypatch, after):
    """Each file alone was atomic, the set was not: a crash between two renames left one
    creature from each save. The list of the save was written before the renames, so the
    next start finishes it."""
    write_set(tmp_path, OLD)
    _crash_at_rename(monkeypatch, after)
    with pytest.raises(Crash):
        write_set(tmp_path, NEW)
    monkeypatch.undo()
    assert sorted(_saves(tmp_path).values()) == sorted([2] * after + [1] * (3 - after))  # two saves mixed
    settle(tmp_path)
    assert _saves(tmp_path) == {name: 2 for name, _ in NEW} and not (tmp_path / JOURNAL).exists()


def test_a_save_cut_short_before_its_list_leaves_the_last_whole_set(tmp_path):
    write_set(tmp_path, OLD)
    journal = tmp_path / JOURNAL
    journal.mkdir()
    (journal / "ada.json").write_text('{"save": 2}')  # the crash came before the list
    settle(tmp_path)
    assert _saves(tmp_path) == {name: 1 for name, _ in OLD} and not journal.exists()


def test_a_full_disk_during_a_save_keeps_the_last_set_and_no_journal(tmp_path, monkeypatch):
    write_set(tmp_path, OLD)
    written = []

    def write(path: Path, text: str) -> None:
        if written:
            raise OSError(28, "No space left on device", str(path))
        written.append(path)
        path.write_text(text)

    monkeypatch.setattr("creatures.state_set.write_json_text", write)
    with pytest.raises(OSError):
        write_set(tmp_path, NEW)
    assert len(written) == 1  # one file of the save was written, and went with its journal
    assert _saves(tmp_path) == {name: 1 for name, _ in OLD} and not (tmp_path / JOURNAL).exists()


def test_a_damaged_list_is_refused_naming_it_and_nothing_moves(tmp_path):
    write_set(tmp_path, OLD)
    journal = tmp_path / JOURNAL
    journal.mkdir()
    (journal / "ada.json").write_text('{"save": 2}')
    for damaged in ('{"ada.json"', '["../../etc/passwd"]'):
        (journal / LISTED).write_text(damaged)
        with pytest.raises(StateFileError, match=f"{LISTED}: "):
            settle(tmp_path)
        assert _saves(tmp_path) == {name: 1 for name, _ in OLD}


def test_a_live_start_loads_the_finished_save(colony, tmp_path, monkeypatch):  # noqa: F811
    """The session's own save and load: a crash mid-save, then a restart, gives every creature
    and the colony's pulse from the one save."""
    state = tmp_path / "state"
    session = _colony_session(colony, 1.0)
    session.save_state(state)
    first = _saves_bytes(state)
    later = _colony_session(colony, 3.0)
    _crash_at_rename(monkeypatch, 1)
    with pytest.raises(Crash):
        later.save_state(state)
    monkeypatch.undo()
    assert _saves_bytes(state) != first
    assert _colony_session(colony, 0.02).load_state(state) == ["ada", "bo"]
    assert _saves_bytes(state) == {name: text.encode() for name, text in later.snapshot()}


def _saves_bytes(directory: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(directory.glob("*.json"))}


def _cut_after_listing(directory: Path, saved: list[tuple[str, str]]) -> None:
    """A save whose list was written and none of whose renames were made (a power cut)."""
    journal = directory / JOURNAL
    journal.mkdir()
    for name, text in saved:
        (journal / name).write_text(text)
    (journal / LISTED).write_text(json.dumps([name for name, _ in saved]))


def test_a_reader_without_the_lock_reads_the_last_whole_save(tmp_path):
    """``inspect``, ``state diff`` and ``export-motion`` read a folder a run may hold, so they
    cannot finish its save; they read it as the last whole save left it."""
    write_set(tmp_path, OLD)
    _cut_after_listing(tmp_path, NEW[:2])  # a save of two files
    assert {name: json.loads(path.read_text())["save"] for name, path in files(tmp_path).items()} == {
        "ada.json": 2, "bo.json": 2, "colony.state.json": 1}


def test_a_merge_after_a_crash_merges_into_the_last_whole_save(tmp_path):
    """The merge read its target before finishing the interrupted save, then wrote the merge
    of the older file over the newer: what the newer save learnt was lost (a review)."""
    from creatures.runtime import repertoire
    from test_state_history import FIRST, SECOND, live_for

    one, two = tmp_path / "one", tmp_path / "two"
    live_for(None, 10, FIRST)[0].save_state(two)
    newer = live_for(two, 10, SECOND)[0].snapshot()
    _cut_after_listing(two, newer)
    live_for(None, 10, (61, 63, 66))[0].save_state(one)
    repertoire.merge(one, "heron", two, "heron")
    assert not (two / JOURNAL).exists()
    merged = json.loads((two / "heron.json").read_text())["state"]
    assert len(merged["phrases"]) > len(json.loads(dict(newer)["heron.json"])["state"]["phrases"])


def test_a_read_only_folder_starts_from_the_save_it_cannot_finish(colony, tmp_path, monkeypatch):  # noqa: F811
    """A run may start on a read-only state folder (lock.hold lets it); one holding a listed
    journal could not finish it (EROFS) and the run did not start at all."""
    import errno

    state = tmp_path / "state"
    first = _colony_session(colony, 1.0)
    first.save_state(state)
    later = _colony_session(colony, 3.0)
    assert later.world.pulse.heard != first.world.pulse.heard
    _cut_after_listing(state, later.snapshot())
    real = os.replace

    def read_only(src, dst, *args, **kwargs):
        if Path(dst).parent == state:
            raise OSError(errno.EROFS, os.strerror(errno.EROFS))
        return real(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "replace", read_only)
    said: list[str] = []
    fresh = _colony_session(colony, 0.02)
    fresh.say = said.append
    assert fresh.load_state(state) == ["ada", "bo"]
    assert len(said) == 1 and "could not finish the save a crash interrupted" in said[0]
    assert fresh.world.pulse.heard == later.world.pulse.heard  # the colony's file of the later save
