"""What ``[creature.learning] groups`` grows (a percept tree split by fission, the tuples
tried on its children) and each tuple's expectation confidence last across a restart
(thesis "percept trees", "expectations about value"): before, a live run's state folder kept
neither, so every restart began the tree and the confidences again."""

from __future__ import annotations

import json
import re
import textwrap
from pathlib import Path

import numpy as np
import pytest

from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.notes import NoteEvent
from midi.sinks import MemorySink
from tests.test_authored import FISSION

TICK = 0.05

CONFIG = FISSION + """
[creature.expectations]
groups = ["main"]
"""
"""The learning of tests/test_authored.py's fission test (notes around 48 and 72 teach 'tone'
two clusters, which split it), its group keeping expectations."""


def _session(folder: Path, said: list[str] | None = None, **renames: str) -> Session:
    text = CONFIG
    for old, new in renames.items():
        text = text.replace(f'"{old}"', f'"{new}"').replace(f".{old}]", f".{new}]")
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "inst.toml").write_text(textwrap.dedent(text))
    return Session(load_installation(folder / "inst.toml"), SimulatedClock(), EventLog(), MemorySink(),
                   say=(said if said is not None else []).append)


def _run(session: Session, seconds: float, seed: int = 1) -> None:
    """``seconds`` of a visitor playing a note every 2 s, around 48 or 72."""
    rng = np.random.default_rng(seed)
    clock = session.clock
    for _ in range(round(seconds / TICK)):
        t = clock.advance(TICK)
        if round(t / TICK) % 40 == 0:
            session.world.inject(NoteEvent(t, int(rng.choice([48, 72]) + rng.integers(-1, 2)), 90, 0, 0.2))
        session.step(t, 1, None, audio=False)


def _tree(percept) -> dict:
    """A percept and what grew under it: names, split structure and models."""
    return {"name": percept.name, "model": percept.model.to_dict(), "children": [_tree(c) for c in percept.children]}


def _learnt(creature) -> dict:
    """What the creature's learning and expectations hold now, comparable across creatures."""
    group = creature.groups["main"]
    now = creature.now()
    return {"tree": _tree(creature.percepts["tone"]),
            "tuples": sorted((tp.name, tp.trigger.name, tp.action.name) for tp in group.tuples),
            "grown": group.learning.grown,
            "confidence": {tp.name: round(creature.expectations.confidence(now, tp.name), 12) for tp in group.tuples}}


def _size(percept) -> int:
    return sum(1 for _ in percept.walk())


def test_a_grown_percept_tree_its_tuples_and_confidences_are_taken_back_after_a_restart(tmp_path):
    state = tmp_path / "state"
    first = _session(tmp_path / "a")
    _run(first, 70.0)
    f = first.creatures[0]
    assert _size(f.percepts["tone"]) == 3, f.percepts["tone"].describe()  # grown: split in two
    before = _learnt(f)
    assert {"tone.1|answer", "tone.2|answer"} <= {name for name, _, _ in before["tuples"]}
    assert any(c > 0.1 for c in before["confidence"].values()), before["confidence"]
    first.save_state(state)
    said: list[str] = []
    second = _session(tmp_path / "b", said)
    assert _size(second.creatures[0].percepts["tone"]) == 1  # a fresh creature: no tree yet
    second.clock.advance_to(first.clock.now())  # the same time, so confidences compare as they were
    second.load_state(state)
    assert said == []
    assert _learnt(second.creatures[0]) == before


def test_a_restored_tree_keeps_learning_from_where_it_was(tmp_path):
    state = tmp_path / "state"
    first = _session(tmp_path / "a")
    _run(first, 70.0)
    first.save_state(state)
    grown = first.creatures[0].groups["main"].learning.grown
    second = _session(tmp_path / "b")
    second.load_state(state)
    f = second.creatures[0]
    tone = f.percepts["tone"]
    children = {c.name: c.model.buffer.copy() for c in tone.children}
    _run(second, 60.0, seed=2)
    assert {c.name for c in tone.children} == set(children)  # the same split, not made again
    assert any(not np.array_equal(c.model.buffer, children[c.name]) for c in tone.children)  # its models still learn
    assert f.groups["main"].learning.grown == grown
    assert any(c > 0 for c in (f.expectations.confidence(f.now(), n) for n in ("tone.1|answer", "tone.2|answer")))


def test_the_learning_of_a_renamed_group_is_said_once_kept_and_taken_back(tmp_path):
    state = tmp_path / "state"
    first = _session(tmp_path / "a")
    _run(first, 70.0)
    before = _learnt(first.creatures[0])
    first.save_state(state)
    saved = json.loads((state / "f.json").read_text())["state"]
    said: list[str] = []
    renamed = _session(tmp_path / "b", said, main="mainly")
    renamed.load_state(state)
    path = state / "f.json"
    assert said[0] == (f"{path}: the saved learning of action-group 'main' matches no learning group of f in "
                       "inst.toml (did you mean 'mainly'?); kept in the state file, and taken back if one of that "
                       "name returns")
    assert [line.split(" matches ")[0].split(": ", 1)[1] for line in said] == [
        "the saved learning of action-group 'main'", "the saved proximity table of action-group 'main'",
        "the saved value table of action-group 'main'", "the saved expectations of action-group 'main'"], said
    f = renamed.creatures[0]
    assert {tp.name for tp in f.groups["mainly"].tuples} == {"answer", "rest", "praised"}  # not the other's
    _run(renamed, 10.0)
    renamed.save_state(state)
    kept = json.loads(path.read_text())["state"]
    assert kept["learning"]["groups"]["main"] == saved["learning"]["groups"]["main"]  # kept as it was
    assert kept["expectations"]["main"] == saved["expectations"]["main"]
    assert {"main", "mainly"} == kept["learning"]["groups"].keys() == kept["expectations"].keys()
    said.clear()
    back = _session(tmp_path / "c", said)  # the name returns: it takes its learning back
    back.clock.advance_to(first.clock.now())
    back.load_state(state)
    b = back.creatures[0]
    assert _learnt(b)["tuples"] == before["tuples"]
    assert _learnt(b)["confidence"] == before["confidence"]
    assert [line.split(" matches ")[0].split(": ", 1)[1] for line in said if "'mainly'" in line] == [
        "the saved learning of action-group 'mainly'", "the saved proximity table of action-group 'mainly'",
        "the saved value table of action-group 'mainly'", "the saved expectations of action-group 'mainly'"], said


def _saved(tmp_path: Path) -> Path:
    state = tmp_path / "state"
    first = _session(tmp_path / "a")
    _run(first, 70.0)
    first.save_state(state)
    return state


@pytest.mark.parametrize("damage, key", [
    (lambda s: s["learning"]["trees"]["tone"]["children"][0]["model"].update(buffer=[float("1e300")] * 32),
     "learning.trees.tone.children.0.model"),
    (lambda s: s["learning"]["trees"]["tone"]["children"][1].update(name="applause"),
     "learning.trees.tone.children.1.name"),
    (lambda s: s["learning"]["groups"]["main"].update(grown=-1), "learning.groups.main.grown"),
    (lambda s: s["learning"]["groups"]["main"]["tuples"].update({"tone.1|answer": ["tone.1"]}),
     "learning.groups.main.tuples.tone.1|answer"),
    (lambda s: s["expectations"]["main"]["answer"].update(reliability=1.5), "expectations.main.answer.reliability"),
    (lambda s: s["expectations"]["main"]["answer"].update(untested=-3.0), "expectations.main.answer.untested"),
    (lambda s: s["expectations"]["main"]["answer"].update(violations=10**6), "expectations.main.answer.violations"),
    (lambda s: s["expectations"].update(gone={"answer": {"reliability": "x"}}), "expectations.gone.answer.reliability"),
])
def test_a_damaged_learnt_tree_tuple_or_confidence_is_refused_naming_its_key(tmp_path, damage, key):
    from creatures.persist import StateFileError

    state = _saved(tmp_path)
    data = json.loads((state / "f.json").read_text())
    damage(data["state"])
    (state / "f.json").write_text(json.dumps(data))
    with pytest.raises(StateFileError, match=re.escape(f"{key}:")):
        _session(tmp_path / "b").load_state(state)


def test_the_tree_of_a_renamed_percept_is_said_kept_and_grown_again_when_the_name_returns(tmp_path):
    state = _saved(tmp_path)
    saved = json.loads((state / "f.json").read_text())["state"]["learning"]
    said: list[str] = []
    renamed = _session(tmp_path / "b", said, tone="tones")
    renamed.load_state(state)
    assert said[0] == (f"{state / 'f.json'}: the saved percept tree of percept 'tone' matches no Gaussian percept "
                       "of f in inst.toml (did you mean 'tones'?); kept in the state file, and taken back if one "
                       "of that name returns"), said
    # The tree's five learnt tuples, their values and their expectations: one line each, not one a tuple
    # (sixteen lines before).
    learnt = "'tone.1|answer', 'tone.1|rest', 'tone.2|answer', 'tone.2|rest' and 'tone|rest' in action-group 'main' match"
    assert [line.split(": ", 1)[1].split(learnt)[0] for line in said[1:]] == [
        "the saved learnt tuple of trigger|actions ", "the saved value of tuples ", "the saved expectation of tuples "], said
    assert said[2].endswith(" match no tuple of f in inst.toml (did you mean 'answer' for 'tone.1|answer', 'answer' for "
                            "'tone.2|answer', 'rest' for 'tone|rest'?); kept in the state file, each taken back if one "
                            "of its name returns"), said[2]
    assert _size(renamed.creatures[0].percepts["tones"]) == 1
    renamed.save_state(state)
    kept = json.loads((state / "f.json").read_text())["state"]["learning"]
    assert kept["trees"]["tone"] == saved["trees"]["tone"] and kept["groups"]["main"]["tuples"] == saved["groups"]["main"]["tuples"]
    back = _session(tmp_path / "c")
    back.load_state(state)
    f = back.creatures[0]
    assert _tree(f.percepts["tone"])["children"] == saved["trees"]["tone"]["children"]
    assert {"tone.1|answer", "tone.2|answer"} <= {tp.name for tp in f.groups["main"].tuples}


def test_a_diff_of_two_saves_of_a_creature_that_learned_nothing_between_them_is_empty(tmp_path):
    """Seconds untested and the count of percepts grown are bookkeeping, not learning: `creatures
    state diff` of two saves a minute apart, nothing ticked between them, shows nothing."""
    from creatures.runtime.repertoire import diff

    first = _session(tmp_path / "a")
    _run(first, 70.0)
    first.save_state(tmp_path / "before")
    first.clock.advance(60.0)
    first.save_state(tmp_path / "after")
    assert [str(c) for c in diff(tmp_path / "before", tmp_path / "after")] == []


def test_a_merge_says_it_does_not_carry_the_grown_tree_nor_the_confidences(tmp_path, capsys):
    """`creatures state merge` grafts phrases and sound classes; a tree split by the source's
    experience and its confidences in its own tuples stay the target's, and the merge says so
    (it said only what parts it left)."""
    from creatures.cli import main
    from creatures.runtime import repertoire

    source = _saved(tmp_path)
    target = tmp_path / "target"
    _session(tmp_path / "t").save_state(target)
    assert repertoire.not_carried(source, "f") == ["learning.trees.tone", "expectations.main"]
    assert main(["state", "merge", str(source), "--creature", "f", str(target), "--into", "f"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == ("note: not carried: learning.trees.tone, expectations.main "
                                                         "(f keeps its own)")


def test_inspect_shows_each_tuples_expectation_as_saved(tmp_path):
    """The confidences are saved: the inspector's page shows them, with how often each
    expectation was tested and violated (it showed the trees, not these)."""
    from creatures.runtime.inspect import inspect

    state = _saved(tmp_path)
    saved = json.loads((state / "f.json").read_text())["state"]["expectations"]["main"]
    name, entry = max(saved.items(), key=lambda item: item[1]["tests"])
    assert entry["tests"] > 0
    page = inspect(state, tmp_path / "page").read_text()
    assert (f"<tr><td>main: {name}</td><td>{entry['reliability']:.3f}</td><td>{entry['tests']}</td>"
            f"<td>{entry['violations']}</td></tr>") in page


def test_a_reward_or_plasticity_edited_in_the_config_since_the_save_is_what_the_restart_takes(tmp_path):
    """Before, the saved record replaced each tuple's value whole: a reward raised from 5 to 9,
    a tuple made a reward, or a plasticity lowered in the config were silently the saved ones
    after a restart. Now the learnt number comes back and the authored rest stays the config's."""
    state = tmp_path / "state"
    first = _session(tmp_path / "a")
    _run(first, 30.0)
    first.save_state(state)
    saved = {tp.name: tp.value.to_float() for tp in first.creatures[0].groups["main"].tuples}
    assert saved["answer"] != 1.0  # it learnt something to take back
    edited = CONFIG.replace("value = { value = 5.0, plastic = false }", "value = { value = 9.0, plastic = false }")
    edited = edited.replace("value = 0.2", "value = { value = 0.2, plastic = false }")
    edited = edited.replace("action = { type = \"play_heard\", count = 1 }\nuntil = { done = true }\nvalue = 1.0",
                            "action = { type = \"play_heard\", count = 1 }\nuntil = { done = true }\n"
                            "value = { value = 1.0, plasticity = 0.25 }")
    assert edited.count("plastic") == 3
    folder = tmp_path / "b"
    folder.mkdir()
    (folder / "inst.toml").write_text(textwrap.dedent(edited))
    second = Session(load_installation(folder / "inst.toml"), SimulatedClock(), EventLog(), MemorySink())
    second.load_state(state)
    values = {tp.name: tp.value for tp in second.creatures[0].groups["main"].tuples}
    assert (values["praised"].to_float(), values["praised"].plasticity) == (9.0, 0.0)  # the raised reward
    assert (values["rest"].to_float(), values["rest"].plasticity) == (0.2, 0.0)  # a reward now
    assert (values["answer"].to_float(), values["answer"].plasticity) == (saved["answer"], 0.25)  # learnt, slower
