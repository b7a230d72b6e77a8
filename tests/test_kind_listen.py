"""listen: a population of gesture models of heard notes converges to a repeated phrase, and
the body's dance repeats with the phrase's period. The creature is authored
(installations/creatures/listen.toml); what it models is read from its ``percepts`` events,
what the inspector shows."""

from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

import installations
from creatures.authored.migrate import keep_originals
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog
from creatures.kinds import KINDS, load_all
from creatures.kinds.model_population import ModelPopulation
from creatures.motor.gesture import Observation
from creatures.persist import StateFileError
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from creatures.runtime.world import World
from midi.notes import NoteEvent
from midi.scheduler import NoteScheduler
from midi.sinks import MemorySink

PHRASE = [60, 64, 67, 72, 71, 67, 62, 65]
OTHER = [74, 69, 76, 57, 59, 79, 53, 81]
GAP = 0.35
TICK = 0.02


def listen_spec(**keys):
    """The shipped listen creature named lis, ``keys`` set on its model population."""
    lines = ['title = "t"', "[[creature]]", 'name = "lis"', 'kind = "listen"']
    lines += [f"percepts.heard.{k} = {v!r}" for k, v in keys.items()]
    with tempfile.TemporaryDirectory() as folder:
        config = Path(folder) / "listen.toml"
        config.write_text("\n".join(lines) + "\n")
        return load_installation(config).specs[0]


def colony(seed: int = 3, **keys):
    clock = SimulatedClock()
    world = World(clock, EventLog(None), NoteScheduler(MemorySink(), clock))
    load_all()
    creature = KINDS["authored"](listen_spec(**keys), world, np.random.default_rng(seed))
    world.add(creature)
    return world, creature


def modelled(world: World) -> dict:
    """The creature's last ``percepts`` record: its models, the best one's core, the match."""
    return [e for e in world.log.records if e["kind"] == "percepts"][-1]


def feed(world: World, phrase: list[int], repeats: int, start: float) -> float:
    """Inject ``phrase`` ``repeats`` times from ``start``; returns when it ends."""
    for r in range(repeats):
        for i, pitch in enumerate(phrase):
            world.inject(NoteEvent(round(start + GAP * (len(phrase) * r + i), 6), pitch, 90, 0, 0.3))
    return start + GAP * len(phrase) * repeats


def run(world: World, creature, until: float, start: float = 0.0) -> np.ndarray:
    """Tick the colony to ``until``; the hand's trajectory, one row per tick."""
    hands = []
    for step in range(int(round(start / TICK)) + 1, int(round(until / TICK)) + 1):
        t = step * TICK
        world.clock.advance_to(t)
        world.deliver(t)
        creature.tick(t)
        world.scheduler.pump()
        hands.append(creature.body.hand().copy())
    return np.array(hands)


def core_pitches(world: World) -> list[int]:
    return modelled(world)["core"]


def restored_at_zero(population: dict) -> dict:
    """A saved population as a run whose clock starts at 0 saves it again: the same models,
    as old as they were (their births count back from the new run's start)."""
    shift = population["time"]
    return {**population, "time": 0.0, "members": [{**m, "born": m["born"] - shift} for m in population["members"]]}


def is_rotation(a: list[int], b: list[int]) -> bool:
    return len(a) == len(b) and any(a == b[k:] + b[:k] for k in range(len(b)))


@pytest.fixture(scope="module")
def danced():
    world, creature = colony()
    end = feed(world, PHRASE, 14, 1.0)
    return world, creature, run(world, creature, end), end


def test_best_model_converges_to_the_repeated_phrase(danced):
    world, _, _, _ = danced
    assert modelled(world)["sizes"]["models"] == 1
    assert is_rotation(core_pitches(world), PHRASE)


def test_dance_repeats_with_the_phrase_period(danced):
    _, _, hands, end = danced
    period = GAP * len(PHRASE)
    steady = hands[int(10.0 / TICK):]  # after the model has converged
    x = steady - steady.mean(axis=0)
    lags = np.arange(int(0.3 * period / TICK), int(1.5 * period / TICK))  # the fundamental, not its multiples
    ac = np.array([(x[:-k] * x[k:]).sum() / np.sqrt((x[:-k] ** 2).sum() * (x[k:] ** 2).sum()) for k in lags])
    peak = lags[int(np.argmax(ac))] * TICK
    assert abs(peak - period) <= 0.05 * period, f"autocorrelation peaks at {peak:.2f} s, phrase period {period:.2f} s"
    assert ac.max() > 0.8
    half = ac[np.searchsorted(lags, int(round(0.5 * period / TICK)))]
    assert ac.max() - half > 0.3, "the dance does not tell the phrase from half of it"


def test_silence_after_the_phrase_is_filled_quietly_with_its_prediction(danced):
    world, creature, _, end = danced
    run(world, creature, end + 8.0, start=end)
    played = [e for e in world.log.records if e["kind"] == "note" and e["time"] > end]
    assert 1 <= len(played) <= creature.spec.percepts["heard"].params()["continuation"]
    pitches = [e["pitch"] for e in played]
    k = PHRASE.index(pitches[0])
    assert pitches == (PHRASE[k:] + PHRASE[:k])[: len(pitches)], "continuation does not follow the phrase"
    assert all(e["velocity"] < 90 for e in played)
    assert {"anticipate", "dance"} <= {e["tuple"] for e in world.log.records if e["kind"] == "selection"}


def test_new_material_spawns_a_model_and_the_best_match_follows_the_music():
    world, creature = colony(seed=5)
    t = feed(world, PHRASE, 5, 1.0)
    t = feed(world, OTHER, 5, t)
    run(world, creature, t)
    assert modelled(world)["sizes"]["models"] == 2
    assert is_rotation(core_pitches(world), OTHER)
    t2 = feed(world, PHRASE, 3, t + 0.5)
    run(world, creature, t2, start=t)
    assert is_rotation(core_pitches(world), PHRASE)
    spawned = [e for e in world.log.records if e["kind"] == "model" and e["action"] == "spawn"]
    assert len(spawned) == 2


def test_a_repeated_phrase_makes_the_match_confident_and_new_material_surprises():
    world, creature = colony(seed=5)
    t = feed(world, PHRASE, 6, 1.0)
    t2 = feed(world, OTHER, 4, t)
    run(world, creature, t2)
    seen = [e for e in world.log.records if e["kind"] == "percepts"]
    steady = [e for e in seen if 8.0 <= e["t"] < t]  # the phrase, once its model has formed
    change = [e for e in seen if t <= e["t"] < t + 3.0]
    assert all(e["surprise"] == 0.0 for e in steady)
    assert steady[-1]["expected_match"] > -0.1 and steady[-1]["confidence"] > 0.9
    assert max(e["surprise"] for e in change) > 0.5
    assert min(e["expected_match"] for e in change) < -2.0
    assert min(e["confidence"] for e in change) < steady[-1]["confidence"] - 0.03
    assert seen[-1]["confidence"] > min(e["confidence"] for e in change)  # the new phrase is learnt in turn


def test_population_stays_bounded_under_ever_new_material(rng):
    world, creature = colony(seed=7, max_models=3, forget=5.0)
    t = 1.0
    for _ in range(8):  # eight unrelated phrases, each repeated twice
        t = feed(world, [int(p) for p in rng.choice(np.arange(40, 90), 8, replace=False)], 2, t)
    run(world, creature, t)
    assert max(e["sizes"]["models"] for e in world.log.records if e["kind"] == "percepts") <= 3
    retired = [e for e in world.log.records if e["kind"] == "model" and e["action"] == "retire"]
    assert len(retired) >= 5


def test_overgrown_model_is_distilled_to_its_core():
    world, creature = colony(seed=9, max_states=8)
    t = feed(world, PHRASE, 6, 1.0)
    noisy = [p + d for p, d in zip(PHRASE, [0, 1, 0, -1, 0, 2, 0, 1])]  # the phrase, smudged
    t = feed(world, noisy, 1, t)
    t = feed(world, PHRASE, 3, t)
    run(world, creature, t)
    assert any(e["kind"] == "model" and e["action"] == "distil" for e in world.log.records)
    memory = creature.spec.percepts["heard"].params()["memory"]
    assert all(e["sizes"]["states of best"] <= 8 + memory for e in world.log.records if e["kind"] == "percepts")
    assert is_rotation(core_pitches(world), PHRASE)


def test_a_model_whose_core_is_all_of_it_is_distilled_within_max_states():
    """A long path, each step repeated, is a core as long as the model: distilling it to that
    core kept every state, and the population passed its bound (the soak saw 19 of 16)."""
    population = ModelPopulation(known=0.2, evidence=4, max_models=2, max_states=8, forget=120.0)
    member = population.learn(0.0, [], [Observation(node, float(i)) for i, node in enumerate(list(range(12)) * 3)])
    assert len(member.model.core()) == len(member.model.states) > 8
    population.maintain(1.0)
    assert [len(m.model.states) for m in population.members] == [8]


def test_state_round_trips_through_json(danced):
    world, creature, _, end = danced
    state = json.loads(json.dumps(creature.state()))
    other, fresh = colony(seed=11)
    fresh.restore(state)
    again = json.loads(json.dumps(fresh.state()))["parts"]["percepts"]["heard"]
    saved = state["parts"]["percepts"]["heard"]
    assert again["poses"] == saved["poses"]
    assert again["population"] == restored_at_zero(saved["population"])
    assert again["expected match"] == saved["expected match"]
    run(other, fresh, TICK)
    assert modelled(other)["core"] == core_pitches(world)
    assert modelled(other)["models"] == modelled(world)["models"]
    # The expectation's confidence fades with the new run's time (its clock is this world's).
    confident = modelled(other)["confidence"]
    run(other, fresh, 600.0, start=TICK)
    assert modelled(other)["confidence"] < 0.5 * confident



def test_a_restored_population_matches_as_well_as_it_did_when_saved(danced):
    """The ``population`` percept says how well its best model explains what was heard
    (exp of the match). Saved without that match, a restored creature kept its best model but
    read 0.0 (the match −inf: "match": null in its percepts) until two new notes were analysed;
    the danced creature read 1.0 when saved."""
    world, creature, _, end = danced
    heard = creature.percepts["heard"]
    other, fresh = colony(seed=11)
    fresh.restore(json.loads(json.dumps(creature.state())))
    run(other, fresh, TICK)
    assert heard.evaluate(end) > 0.5
    assert fresh.percepts["heard"].evaluate(TICK) == heard.evaluate(end)
    assert modelled(other)["match"] == modelled(world)["match"]

def test_bad_config_is_rejected_with_the_key():
    with pytest.raises(ConfigError, match="memory"):
        listen_spec(memory=1)
    with pytest.raises(ConfigError, match="context .* must be smaller than memory"):
        listen_spec(memory=8, context=8)


# -- a state folder saved by the class-based listen (tests/data/retired/listen, a real one) ---
RETIRED = Path(__file__).parent / "data" / "retired" / "listen"


def _session(config: Path | None = None) -> Session:
    inst = load_installation(config or installations.path("listen"))
    return Session(inst, SimulatedClock(), EventLog(), MemorySink())


def test_a_state_saved_by_the_class_based_listen_loads_into_the_authored_one(tmp_path):
    saved = json.loads((RETIRED / "lis.json").read_text())
    assert saved["kind"] == "listen" and "population" in saved["state"]  # the class's own format
    session = _session()
    assert session.load_state(RETIRED) == ["ada", "lis", "bo"]
    lis = next(c for c in session.creatures if c.name == "lis")
    parts = lis.state()["parts"]["percepts"]["heard"]
    assert parts["poses"] == saved["state"]["poses"]
    assert parts["population"] == restored_at_zero(saved["state"]["population"])
    assert parts["expected match"] == saved["state"]["expected match"]
    assert lis.state()["motivation"]["levels"] == saved["state"]["motivation"]["levels"]
    lis.tick(0.0)
    members = [m["id"] for m in saved["state"]["population"]["members"]]
    assert modelled(session.world)["models"] == members and modelled(session.world)["core"]
    session.save_state(tmp_path)  # and it saves as the authored creature it now is
    assert json.loads((tmp_path / "lis.json").read_text())["kind"] == "authored"


def test_a_class_listen_state_is_refused_where_nothing_can_take_it(tmp_path):
    config = tmp_path / "c.toml"
    config.write_text('title = "t"\n[[creature]]\nname = "lis"\nkind = "exchange"\n')
    with pytest.raises(StateFileError, match=r"lis.json: cannot take .* no 'population' percept.*move lis.json out"):
        _session(config).load_state(RETIRED)
    state = tmp_path / "state"
    state.mkdir()
    saved = json.loads((RETIRED / "lis.json").read_text())
    saved["state"]["population"] = {"members": "many"}
    (state / "lis.json").write_text(json.dumps(saved))
    with pytest.raises(StateFileError, match="lis.json: malformed authored state"):
        _session().load_state(state)


def test_a_live_run_taking_in_a_class_listen_state_keeps_its_original_beside_it(tmp_path):
    """A live run loads its state folder and saves into it: the class-based original was
    overwritten by the authored state at the first save, and with it the way back."""
    from creatures.runtime import live

    state = tmp_path / "state"
    shutil.copytree(RETIRED, state)
    inst = load_installation(installations.path("listen"))
    inst.settings.midi.input_port = inst.settings.midi.output_port = None
    said: list[str] = []
    assert live.run_live(inst, duration=0.2, state=state, say=said.append).restored == ["ada", "lis", "bo"]
    assert json.loads((state / "lis.json").read_text())["kind"] == "authored"
    assert (state / "lis.json.listen").read_bytes() == (RETIRED / "lis.json").read_bytes()
    assert any("lis.json" in line and "kept as lis.json.listen" in line for line in said)
    session = _session()
    assert session.load_state(state) == ["ada", "lis", "bo"] and session.migrated == []  # the copy is no one's state
    shutil.copy(RETIRED / "lis.json", state)  # the same original put back: kept once, not twice
    session.load_state(state)
    keep_originals(session.migrated, said.append)
    assert sorted(p.name for p in state.glob("lis.json*")) == ["lis.json", "lis.json.listen"]


def test_a_restored_population_forgets_at_its_rate_from_the_new_runs_clock(danced):
    """A live run's clock starts again at 0. The population's clock and its models' births
    were taken back as the last run left them, so for as long as that run had lasted nothing
    decayed and nothing was old enough to retire (after ten minutes of a phrase, a model the
    music had then left kept its usefulness, 62.5, where the run that went on let it fall to
    1.5 in 140 s). Restored, each model keeps its age and usefulness and forgets from now."""
    _, creature, _, _ = danced
    saved = json.loads(json.dumps(creature.state()))
    population = saved["parts"]["percepts"]["heard"]["population"]
    other, fresh = colony(seed=11)
    fresh.restore(saved)
    run(other, fresh, 30.0)  # silence: the models are not used
    [member] = fresh.percepts["heard"].population.members
    [was] = population["members"]
    assert member.born == pytest.approx(was["born"] - population["time"])  # as old as it was, now
    assert member.usefulness == pytest.approx(was["usefulness"] * np.exp(-30.0 / 120.0), rel=0.02)
    resaved = json.loads(json.dumps(fresh.state()))
    _, reloaded = colony(seed=11)
    reloaded.restore(resaved)  # born before this run's start, it loads back
    [again] = restored_at_zero(resaved["parts"]["percepts"]["heard"]["population"])["members"]
    assert reloaded.percepts["heard"].population.members[0].born == again["born"]


def test_a_burst_of_notes_sets_the_dancing_body_off_once():
    """Every note heard since the last step moves the dance on, but only the last sets the
    body's course: each note set off its own A* course, each replaced within the same tick,
    so 10,000 notes arriving at once (a MIDI flood) held the shipped listen's tick for 8 s
    of CPU. The dance still steps through every note of the burst."""
    world, creature = colony(seed=5)
    t = feed(world, PHRASE, 6, 1.0)
    burst = [PHRASE[i % len(PHRASE)] for i in range(400)]
    for pitch in burst:
        world.inject(NoteEvent(t, pitch, 90, 0, 0.3))
    run(world, creature, t - TICK)
    heard = creature.percepts["heard"]
    assert heard.dancing
    expected = heard.dance.state
    for pitch in burst:  # where stepping through the burst note by note leaves the dance
        heard.dance.state = heard.dance.locate(heard.poses.node(pitch))
    expected, heard.dance.state = heard.dance.state, expected
    motor, courses = creature.body.motor, []
    set_course = motor.set_course
    motor.set_course = lambda *args, **keys: courses.append(args[0]) or set_course(*args, **keys)
    run(world, creature, t + TICK, start=t - TICK)
    assert len(courses) == 1 and heard.dance.state == expected
