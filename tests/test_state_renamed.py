"""A tuple renamed in the config (or removed) while a state folder holds its learned value: the
value is neither lost nor silently dropped. The run says which saved values match no tuple, keeps
them in the state it saves, and a tuple given that name again takes its value back."""

from __future__ import annotations

import json

import pytest

import installations
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.persist import StateFileError
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink

LEARNT = {"kind": "scalar", "plasticity": 1.0, "value": 2.5}


def _session(said: list[str]) -> Session:
    return Session(load_installation(installations.path("exchange")), SimulatedClock(), EventLog(), MemorySink(),
                   say=said.append)


def _values(path) -> dict:
    return json.loads(path.read_text())["state"]["values"]


def _rename(path, old: str, new: str, value: dict) -> None:
    data = json.loads(path.read_text())
    main = data["state"]["values"]["main"]
    del main[old]
    main[new] = value
    path.write_text(json.dumps(data))


def test_a_saved_value_no_tuple_takes_is_reported_and_kept(tmp_path):
    _session([]).save_state(tmp_path)
    # The state was saved when the tuple was called "stroll"; the config now calls it "wander".
    _rename(tmp_path / "ada.json", "wander", "stroll", LEARNT)
    said: list[str] = []
    session = _session(said)
    assert session.load_state(tmp_path) == ["ada", "bo", "cy"]
    assert said == [f"{tmp_path / 'ada.json'}: the saved value of tuple 'stroll' in action-group 'main' matches no "
                    "tuple of ada in exchange.toml (tuples: rest, retrograde, seek note, swap, wander); kept in the "
                    "state file, and taken back if one of that name returns"], said
    ada = session.world.creatures[0]
    assert [tp.value.to_dict() for tp in ada.groups["main"].tuples if tp.name == "wander"] != [LEARNT]
    session.save_state(tmp_path)
    assert _values(tmp_path / "ada.json")["main"]["stroll"] == LEARNT  # kept, not lost
    assert "wander" in _values(tmp_path / "ada.json")["main"]
    # Named back (as if the config called it "stroll" again): the kept value is taken back.
    _rename(tmp_path / "ada.json", "wander", "wander", _values(tmp_path / "ada.json")["main"]["stroll"])
    data = json.loads((tmp_path / "ada.json").read_text())
    del data["state"]["values"]["main"]["stroll"]
    (tmp_path / "ada.json").write_text(json.dumps(data))
    said.clear()
    again = _session(said)
    again.load_state(tmp_path)
    assert said == []
    wander = [tp for tp in again.world.creatures[0].groups["main"].tuples if tp.name == "wander"]
    assert wander[0].value.to_dict() == LEARNT


def test_a_group_no_longer_in_the_config_is_kept_too(tmp_path):
    _session([]).save_state(tmp_path)
    data = json.loads((tmp_path / "bo.json").read_text())
    data["state"]["values"]["dance"] = {"spin": LEARNT}
    (tmp_path / "bo.json").write_text(json.dumps(data))
    said: list[str] = []
    session = _session(said)
    session.load_state(tmp_path)
    assert said == [f"{tmp_path / 'bo.json'}: the saved value table of action-group 'dance' matches no action-group "
                    "of bo in exchange.toml (action-groups: main, manner); kept in the state file, and taken back if "
                    "one of that name returns"], said
    session.save_state(tmp_path)
    assert _values(tmp_path / "bo.json")["dance"] == {"spin": LEARNT}


def test_a_saved_creature_no_creature_takes_is_reported_and_left_as_it_is(tmp_path):
    """ada renamed ann in the config: the run said "restored bo, cy" and nothing of ada.json.
    Now it names the file's creature, and the file is left for a creature of that name."""
    _session([]).save_state(tmp_path)
    (tmp_path / "ada.json").rename(tmp_path / "ann.json")
    before = (tmp_path / "ann.json").read_bytes()
    said: list[str] = []
    assert _session(said).load_state(tmp_path) == ["bo", "cy"]
    assert len(said) == 1 and "saved state of ann matches no creature in exchange.toml" in said[0], said
    assert (tmp_path / "ann.json").read_bytes() == before


def _motivation(path) -> dict:
    return json.loads(path.read_text())["state"]["motivation"]


def test_a_saved_drive_level_no_drive_takes_is_reported_with_the_nearest_and_kept(tmp_path):
    """A drive renamed in the config (``boredum`` corrected to ``boredom``) lost the level the
    creature had reached without a word: restore forgot it, and the next save wrote the file
    without it. Now it is said, with the nearest drive, kept in every save, and a drive given
    that name again takes it back."""
    _session([]).save_state(tmp_path)
    data = json.loads((tmp_path / "ada.json").read_text())
    motivation = data["state"]["motivation"]
    for table in ("levels", "inputs"):  # saved when the config called it "boredum"
        motivation[table]["boredum"] = motivation[table].pop("boredom")
    motivation["levels"]["boredum"] = 0.7
    (tmp_path / "ada.json").write_text(json.dumps(data))
    said: list[str] = []
    session = _session(said)
    session.load_state(tmp_path)
    assert said == [f"{tmp_path / 'ada.json'}: the saved level of drive 'boredum' matches no drive of ada in "
                    "exchange.toml (did you mean 'boredom'?); kept in the state file, and taken back if one of that "
                    "name returns"]
    session.save_state(tmp_path)
    assert _motivation(tmp_path / "ada.json")["unplaced"]["levels"] == {"boredum": 0.7}  # kept, not lost
    # Saved while the config had no "boredom" (kept aside at 0.4), loaded by one that has it again.
    data = json.loads((tmp_path / "ada.json").read_text())
    motivation = data["state"]["motivation"]
    motivation["unplaced"] = {table: {"boredom": motivation[table].pop("boredom")} for table in ("levels", "inputs")}
    motivation["unplaced"]["levels"]["boredom"] = 0.4
    (tmp_path / "ada.json").write_text(json.dumps(data))
    said.clear()
    again = _session(said)
    again.load_state(tmp_path)
    ada = again.world.creatures[0].motivation
    assert said == [] and ada.levels[ada.index("boredom")] == 0.4 and not ada.unplaced.kept
    again.save_state(tmp_path)
    assert "unplaced" not in _motivation(tmp_path / "ada.json")


def test_a_damaged_value_kept_under_an_old_name_is_refused_at_load_naming_its_key(tmp_path):
    """A value no tuple takes is kept as saved: a damaged one was carried through every save and
    refused only when a tuple of its name returned, runs later. Now it is refused at once, as a
    damaged value of a tuple the config has is, naming its key."""
    import pytest

    from creatures.persist import StateFileError

    _session([]).save_state(tmp_path)
    _rename(tmp_path / "ada.json", "wander", "stroll", {**LEARNT, "value": "x"})
    with pytest.raises(StateFileError, match=r"values\.main\.stroll: value: must be a number, found 'x'"):
        _session([]).load_state(tmp_path)
    data = json.loads((tmp_path / "bo.json").read_text())
    data["state"]["values"]["dance"] = {"spin": {**LEARNT, "plasticity": -1.0}}
    (tmp_path / "bo.json").write_text(json.dumps(data))
    _rename(tmp_path / "ada.json", "stroll", "stroll", LEARNT)
    with pytest.raises(StateFileError, match=r"values\.dance\.spin: plasticity"):
        _session([]).load_state(tmp_path)


def test_a_state_file_linked_elsewhere_is_read_said_and_left_as_it_is_by_a_save(tmp_path):
    """A state file may be a link to a shared one (a pre-trained creature): it is read through
    the link, the run says a save will put a file of its own there (a state folder is saved as
    one set, renamed into place), and the file linked to is never written."""
    shared, folder = tmp_path / "shared", tmp_path / "state"
    _session([]).save_state(shared)
    _session([]).save_state(folder)
    _rename(shared / "ada.json", "wander", "wander", LEARNT)
    before = (shared / "ada.json").read_bytes()
    (folder / "ada.json").unlink()
    (folder / "ada.json").symlink_to(shared / "ada.json")
    said: list[str] = []
    session = _session(said)
    session.load_state(folder)
    assert said == [f"{folder / 'ada.json'}: read through its link to {shared / 'ada.json'}; a save writes ada.json "
                    "here as a file of the state folder's set and leaves that file as it is"], said
    ada = session.world.creatures[0]
    assert [tp.value.to_dict()["value"] for tp in ada.groups["main"].tuples if tp.name == "wander"] == [2.5]
    session.save_state(folder)
    assert (shared / "ada.json").read_bytes() == before
    assert not (folder / "ada.json").is_symlink() and _values(folder / "ada.json")["main"]["wander"]["value"] == 2.5


def test_a_state_file_linked_to_nothing_says_where_it_points(tmp_path):
    """A link whose target is gone (a drive not mounted) was "state file not found", though the
    file was there, as a link."""
    _session([]).save_state(tmp_path)
    (tmp_path / "ada.json").unlink()
    (tmp_path / "ada.json").symlink_to("/nonexistent/ada.json")
    with pytest.raises(StateFileError, match=r"ada\.json: state file is a link to /nonexistent/ada\.json, which "
                                             "does not exist"):
        _session([]).load_state(tmp_path)
