"""A learned part of a creature saved under a name the config no longer has (an action-group,
a percept or a tuple renamed between runs, or removed): its proximity table, its adverb
model, its shaping data, a part's own kept state. Each was dropped without a word and gone at
the next save; now, as a renamed tuple's value and a renamed drive's level are, each is said
once at load with the nearest name, kept in every save, and taken back when the name returns."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path
from typing import Callable

import installations
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink

TUTORIAL = Path(__file__).resolve().parents[1] / "installations" / "tutorial"
LIFT = """
[creature.percepts.lift]
type = "adverb_model"
prior_mean = 0.1
"""
"""An Ac percept the tutorial dog is given, so that it has an adverb model to keep."""


def _dog(tmp_path: Path, said: list[str], **renames: str) -> Session:
    """The tutorial dog (with :data:`LIFT`), each name of ``renames`` renamed in its config."""
    folder = tmp_path / "config"
    shutil.rmtree(folder, ignore_errors=True)
    (folder / "creatures").mkdir(parents=True)
    shutil.copy(TUTORIAL / "dog.toml", folder / "dog.toml")
    text = (TUTORIAL / "creatures" / "dog.toml").read_text() + LIFT
    for old, new in renames.items():
        text = re.sub(rf"\b{old}\b", new, text)
    (folder / "creatures" / "dog.toml").write_text(text)
    return Session(load_installation(folder / "dog.toml"), SimulatedClock(), EventLog(), MemorySink(),
                   say=said.append)


def _shipped(name: str, said: list[str]) -> Session:
    return Session(load_installation(installations.path(name)), SimulatedClock(), EventLog(), MemorySink(),
                   say=said.append)


def _saved_renamed(folder: Path, installation: str, creature: str, rename: Callable[[dict], None]) -> list[str]:
    """Save ``installation``'s state into ``folder``, ``rename`` a name in ``creature``'s file
    (as if saved by a config that called it otherwise), load it again; what the run said."""
    _shipped(installation, []).save_state(folder)
    data = json.loads((folder / f"{creature}.json").read_text())
    rename(data["state"])
    (folder / f"{creature}.json").write_text(json.dumps(data))
    said: list[str] = []
    session = _shipped(installation, said)
    session.load_state(folder)
    session.save_state(folder)
    return said


def _state(path: Path) -> dict:
    return json.loads(path.read_text())["state"]


def _learnt(state: Path) -> dict:
    """Save the dog, then give its saved parts values no fresh dog has (as if it had learnt)."""
    _dog(state.parent, []).save_state(state)
    data = json.loads((state / "dog.json").read_text())
    data["state"]["proximity"]["main"]["table"].append(["follow", "idle", 0.42])
    data["state"]["adverb_models"]["lift"]["buffer"] = [0.77] * len(data["state"]["adverb_models"]["lift"]["buffer"])
    data["state"]["shaping"]["chase"]["lessons"] = 7
    (state / "dog.json").write_text(json.dumps(data))
    return data["state"]


def test_the_parts_of_a_renamed_group_percept_and_tuple_are_said_kept_and_taken_back(tmp_path):
    state = tmp_path / "state"
    learnt = _learnt(state)
    said: list[str] = []
    renamed = _dog(tmp_path, said, main="mainly", lift="lifted", chase="chaser")
    renamed.load_state(state)
    path = state / "dog.json"
    assert said == [
        f"{path}: the saved shaping of tuple 'chase' matches no shape_gesture tuple of dog in dog.toml "
        "(did you mean 'chaser'?); kept in the state file, and taken back if one of that name returns",
        f"{path}: the saved proximity table of action-group 'main' matches no action-group of dog in dog.toml "
        "(did you mean 'mainly'?); kept in the state file, and taken back if one of that name returns",
        f"{path}: the saved value table of action-group 'main' matches no action-group of dog in dog.toml "
        "(did you mean 'mainly'?); kept in the state file, and taken back if one of that name returns",
        f"{path}: the saved adverb model of percept 'lift' matches no adverb_model percept of dog in dog.toml "
        "(did you mean 'lifted'?); kept in the state file, and taken back if one of that name returns",
    ], said
    renamed.save_state(state)
    kept = _state(path)
    assert kept["proximity"]["main"] == learnt["proximity"]["main"]  # kept, not lost
    assert kept["adverb_models"]["lift"] == learnt["adverb_models"]["lift"]
    assert kept["shaping"]["chase"] == learnt["shaping"]["chase"]
    assert {"mainly", "main"} <= kept["proximity"].keys() and "lifted" in kept["adverb_models"]
    said.clear()
    back = _dog(tmp_path, said)  # the config's names back as they were: each takes its part back
    back.load_state(state)
    # what the renamed run learnt under its names is, in turn, said and kept
    assert [line.split(" matches ")[0].split(": ")[1] for line in said] == [
        "the saved shaping of tuple 'chaser'", "the saved proximity table of action-group 'mainly'",
        "the saved value table of action-group 'mainly'", "the saved adverb model of percept 'lifted'"], said
    dog = back.world.creatures[0]
    assert dog.groups["main"].proximities.table[("follow", "idle")] == 0.42
    assert dog.percepts["lift"].model.buffer.tolist() == learnt["adverb_models"]["lift"]["buffer"]
    assert dog.tuples["chase"].action.lessons == 7
    back.save_state(state)
    assert {"main", "mainly"} == _state(path)["proximity"].keys() and {"lift", "lifted"} == _state(path)["adverb_models"].keys()


def test_a_damaged_part_kept_for_a_renamed_name_is_refused_naming_its_key(tmp_path):
    state = tmp_path / "state"
    _learnt(state)
    data = json.loads((state / "dog.json").read_text())
    data["state"]["adverb_models"]["lift"]["buffer"][0] = "high"
    (state / "dog.json").write_text(json.dumps(data))
    try:
        _dog(tmp_path, [], lift="lifted").load_state(state)
    except Exception as exc:  # noqa: BLE001 - the message is what is checked
        assert "dog.json" in str(exc) and "adverb_models.lift" in str(exc), exc
    else:
        raise AssertionError("a damaged kept adverb model loaded")


def test_a_kept_part_of_a_renamed_percept_is_said_kept_and_taken_back(tmp_path):
    """listen's 'heard' population percept keeps its state as parts.percepts.heard."""
    parts: dict = {}

    def rename(state: dict) -> None:  # saved when the config called it "herd"
        parts.update(state["parts"]["percepts"])
        state["parts"]["percepts"]["herd"] = state["parts"]["percepts"].pop("heard")
    said = _saved_renamed(tmp_path, "listen", "lis", rename)
    assert said == [f"{tmp_path / 'lis.json'}: the saved state of percept 'herd' matches no percept of lis in "
                    "listen.toml (did you mean 'heard'?); kept in the state file, and taken back if one of that "
                    "name returns"], said
    assert _state(tmp_path / "lis.json")["parts"]["percepts"]["herd"] == parts["heard"]


def test_a_duncan_value_of_a_trick_the_config_no_longer_has_is_said_kept_and_taken_back(tmp_path):
    """A trick's learnt value saved when the dog's tricks named it "sat" (the body's label since
    renamed "sit"): the value of ``quiet|sat`` was dropped without a word (gone at the next save)."""
    def rename(state: dict) -> None:
        state["values"]["quiet|sat"] = {**state["values"].pop("quiet|sit"), "value": 3.5}
    said = _saved_renamed(tmp_path, "duncan", "duncan", rename)
    assert said == [f"{tmp_path / 'duncan.json'}: the saved value of tuple 'quiet|sat' matches no tuple of "
                    "duncan in duncan.toml (did you mean 'quiet|sit'?); kept in the state file, and taken "
                    "back if one of that name returns"], said
    assert _state(tmp_path / "duncan.json")["values"]["quiet|sat"]["value"] == 3.5


def test_the_aural_tuples_of_a_renamed_group_are_said_and_kept_not_refused(tmp_path):
    """A soundcreature's learnt aural tuples are saved by group. Saved when its group was
    called "mian" (since corrected to "main"), the whole file was refused (exit 2: "saved tuples
    name an unknown group"), and the creature could not start with that config at all."""
    def rename(state: dict) -> None:
        for table in (state["aural"]["tuples"], state["aural"]["refined"]):
            table["mian"] = table.pop("main")
    said = _saved_renamed(tmp_path, "soundcreatures", "parrot", rename)
    assert said == [f"{tmp_path / 'parrot.json'}: the saved aural learning of action-group 'mian' matches no "
                    "action-group of parrot in soundcreatures.toml (did you mean 'main'?); kept in the state file, "
                    "and taken back if one of that name returns"], said
    aural = _state(tmp_path / "parrot.json")["aural"]
    assert {"main", "mian"} == aural["tuples"].keys() == aural["refined"].keys()


def test_a_tuple_value_saved_under_a_misspelt_name_is_said_with_the_nearest_tuple(tmp_path):
    """"saved values of main.wandr match no tuple in exchange.toml (renamed or removed?)": the
    one kept part whose line did not name the tuple the saved name was nearest."""
    def rename(state: dict) -> None:
        state["values"]["main"]["wandr"] = state["values"]["main"].pop("wander")
    said = _saved_renamed(tmp_path, "exchange", "ada", rename)
    assert said == [f"{tmp_path / 'ada.json'}: the saved value of tuple 'wandr' in action-group 'main' matches no "
                    "tuple of ada in exchange.toml (did you mean 'wander'?); kept in the state file, and taken back "
                    "if one of that name returns"], said
    assert "wandr" in _state(tmp_path / "ada.json")["values"]["main"]
