"""No silent decay (issue 15): credit assignment with nothing to ground it is refused, and the
shipped pieces keep their authored values (and keep selecting) over hours."""

from __future__ import annotations

import json
import shutil
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import pytest

import installations
from creatures.behaviour.action_group import ActionGroup, group_tuple
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import WhateverPercept
from creatures.behaviour.value import ScalarValue
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog, read_events
from creatures.runtime.session import Session
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from midi.sinks import MemorySink

HOURS = 2.0
RETIRED = Path(__file__).parent / "data" / "retired"


def _tuples(plasticity: float = 1.0) -> list[ActionTuple]:
    root = WhateverPercept()
    return [ActionTuple("dance", root, Action("dance"), DoUntil(1.0), 3.0),
            ActionTuple("rest", root, Action("rest"), DoUntil(1.0), ScalarValue(0.3, plasticity=plasticity))]


def test_a_group_that_assigns_credit_with_nothing_grounding_it_is_refused():
    with pytest.raises(ValueError, match="non-plastic value.*shrinking geometrically"):
        ActionGroup("lis", _tuples(), rng=np.random.default_rng(0))


def test_a_group_built_empty_is_refused_when_it_first_ticks():
    group = ActionGroup("lis", rng=np.random.default_rng(0))
    for tuple_ in _tuples():
        group.add(tuple_)
    with pytest.raises(ValueError, match="assigns credit"):
        group.tick(0.0)


@pytest.mark.parametrize("kwargs", [{"alpha": 0.0}, {"discount": 1.0}, {"grounded_by": "a trainer's clicks"}])
def test_groups_without_decay_or_with_a_named_ground_are_accepted(kwargs):
    ActionGroup("lis", _tuples(), rng=np.random.default_rng(0), **kwargs).tick(0.0)


def test_a_reward_inside_a_group_it_holds_grounds_the_outer_group():
    """Credit reaches leaves only (hierarchical groups): the outer group blends its leaves toward
    the value of the leaf that ran inside a group tuple, so a non-plastic leaf there grounds it.
    docs/authoring.md's songs-after-a-wait, with its songs as the rewards, was refused."""
    root = WhateverPercept()
    songs = ActionGroup("songs", [ActionTuple("low", root, Action("low"), DoUntil(1.0), ScalarValue(2.0, plasticity=0.0))],
                        rng=np.random.default_rng(0))
    wait = ActionTuple("wait", root, Action("wait"), DoUntil(1.0), 1.0)
    main = ActionGroup("main", [wait, group_tuple(songs, root, 3.0)], rng=np.random.default_rng(0), alpha=0.2)
    for k in range(5_000):
        main.tick(k * 1.0)
    assert wait.value.to_float() > 0.5  # held up by the song's 2.0 (toward 0.8 × 2.0), not decayed to 0
    with pytest.raises(ValueError, match="non-plastic value"):  # no ground at any depth: refused as before
        ActionGroup("main", [ActionTuple("wait", root, Action("wait"), DoUntil(1.0), 1.0),
                             group_tuple(ActionGroup("songs", _tuples()[:1], rng=np.random.default_rng(0)), root, 3.0)],
                    rng=np.random.default_rng(0), alpha=0.2)


def test_an_authored_group_grounded_by_a_reward_in_a_group_it_holds_loads(tmp_path):
    config = tmp_path / "songs.toml"
    tables = "".join(f'[creature.tuples.{name}]\naction = "rest"\nuntil = {{ seconds = 1.0 }}\nvalue = {value}\n'
                     for name, value in (("wait", "1.0"), ("low", "{ value = 2.0, plastic = false }"), ("high", "1.0")))
    groups = ('[creature.groups.main]\ntuples = ["wait", "songs"]\nalpha = 0.2\n'
              '[creature.groups.songs]\ntuples = ["low", "high"]\nalpha = 0.0\nvalue = 3.0\n')
    config.write_text('title = "t"\n[[creature]]\nname = "ada"\nkind = "authored"\n' + tables + groups)
    session = Session(load_installation(config), SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())
    assert [c.name for c in session.creatures] == ["ada"]
    config.write_text(config.read_text().replace("{ value = 2.0, plastic = false }", "2.0"))
    with pytest.raises(ConfigError, match="groups.main.alpha: group 'main' assigns credit"):
        load_installation(config)


def test_a_non_plastic_reward_grounds_the_values_over_many_selections():
    group = ActionGroup("lis", _tuples(plasticity=0.0), rng=np.random.default_rng(0), alpha=0.1)
    for k in range(20_000):  # about 5.5 simulated hours of one-second tuples
        group.tick(k * 1.0)
    values = {tp.name: tp.value.to_float() for tp in group.tuples}
    assert values["rest"] == 0.3 and values["dance"] > 0.1  # blended toward 0.8 × 0.3 at worst, not to 0


def _long_run(name: str, out: Path):
    inst = load_installation(installations.path(name))
    s = inst.settings
    s.tick = 0.5  # the coarsest legal tick: hours in seconds
    s.output.wav = s.output.midi = s.output.report = s.output.frames = False
    run_offline(inst, out, duration=HOURS * 3600.0, progress=False)
    return inst, read_events(out / "events.jsonl")


@pytest.mark.slow
@pytest.mark.parametrize("name", ["curve", "listen"])
def test_shipped_values_and_their_ratios_hold_for_hours_and_every_creature_selects(name, tmp_path):
    inst, events = _long_run(name, tmp_path)
    values: dict[str, list[dict[str, float]]] = defaultdict(list)
    last_hour = defaultdict(int)
    for e in events:
        if e["kind"] == "values":
            values[e["creature"]].append(e["values"])
        elif e["kind"] == "selection" and e["t"] > (HOURS - 1) * 3600.0:
            last_hour[e["creature"]] += 1
    for spec in inst.specs:
        first, last = {}, {}  # per tuple: a creature with several groups logs each group's values
        for snapshot in values[spec.name]:
            first.update({k: v for k, v in snapshot.items() if k not in first})
            last.update(snapshot)
        assert last == first, (spec.name, first, last)
        assert last_hour[spec.name] >= 20, (spec.name, last_hour)


def test_a_state_saved_while_values_decayed_does_not_bring_the_decay_back(tmp_path):
    """A state folder the class-based listen saved while credit assignment decayed its values
    (tests/data/retired: a real one, its values set to what an hour made of them) loads into
    the authored listen with its values as authored."""
    state = tmp_path / "state"
    shutil.copytree(RETIRED / "listen", state)
    saved = json.loads((state / "lis.json").read_text())
    assert saved["kind"] == "listen"
    saved["state"]["values"] = {name: {**v, "value": 7e-8} for name, v in saved["state"]["values"].items()}
    (state / "lis.json").write_text(json.dumps(saved))
    inst = load_installation(installations.path("listen"))
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(), MemorySink())
    lis = next(c for c in session.creatures if c.name == "lis")
    authored = lis.group.value_state()
    assert "lis" in session.load_state(state)
    assert lis.group.value_state() == authored


@pytest.mark.slow
def test_a_grounded_learning_creature_keeps_what_it_learnt_for_hours(tmp_path):
    """The heron learns (alpha 0.2) from a non-plastic praise: over six simulated hours its
    values neither leak away nor run off, the praised phrase stays ahead, and it still selects."""
    inst = load_installation(Path(installations.__file__).parent / "tutorial" / "heron-4.toml")
    inst.settings.tick = 0.5
    run_offline(inst, tmp_path, duration=6 * 3600.0, progress=False)
    events = read_events(tmp_path / "events.jsonl")
    late = [e["values"] for e in events if e["kind"] == "values" and e["t"] > 5 * 3600.0]
    assert late
    for values in late:
        assert values["praised"] == 4.0
        assert all(0.5 < v < 4.0 for k, v in values.items() if k != "praised"), values
        assert values["phrase 3"] > max(values["phrase 1"], values["phrase 2"])
    last_hour = Counter(e["tuple"] for e in events if e["kind"] == "selection" and e["t"] > 5 * 3600.0)
    assert last_hour["phrase 3"] > max(last_hour["phrase 1"], last_hour["phrase 2"]) >= 20, last_hour
