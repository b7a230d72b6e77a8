"""listen: a population of gesture models of heard notes converges to a repeated phrase, and
the body's dance repeats with the phrase's period."""

from __future__ import annotations

import json

import numpy as np
import pytest

from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.kinds import load_all
from creatures.runtime.world import World
from midi.notes import NoteEvent
from midi.scheduler import NoteScheduler
from midi.sinks import MemorySink

PHRASE = [60, 64, 67, 72, 71, 67, 62, 65]
OTHER = [74, 69, 76, 57, 59, 79, 53, 81]
GAP = 0.35
TICK = 0.02


def colony(seed: int = 3, **keys):
    clock = SimulatedClock()
    world = World(clock, EventLog(None), NoteScheduler(MemorySink(), clock))
    kind = load_all()["listen"]
    creature = kind(kind.Spec(name="lis", kind="listen", **keys), world, np.random.default_rng(seed))
    world.add(creature)
    return world, creature


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


def core_pitches(creature) -> list[int]:
    return [creature.poses.pitch(n) for n in creature.population.best.model.core_nodes()]


def is_rotation(a: list[int], b: list[int]) -> bool:
    return len(a) == len(b) and any(a == b[k:] + b[:k] for k in range(len(b)))


@pytest.fixture(scope="module")
def danced():
    world, creature = colony()
    end = feed(world, PHRASE, 14, 1.0)
    return world, creature, run(world, creature, end), end


def test_best_model_converges_to_the_repeated_phrase(danced):
    _, creature, _, _ = danced
    assert len(creature.population.members) == 1
    assert is_rotation(core_pitches(creature), PHRASE)


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
    assert 1 <= len(played) <= creature.spec.continuation
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
    assert len(creature.population.members) == 2
    assert is_rotation(core_pitches(creature), OTHER)
    t2 = feed(world, PHRASE, 3, t + 0.5)
    run(world, creature, t2, start=t)
    assert is_rotation(core_pitches(creature), PHRASE)
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
    assert len(creature.population.members) <= 3
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
    assert all(len(m.model.states) <= 8 + creature.spec.memory for m in creature.population.members)
    assert is_rotation(core_pitches(creature), PHRASE)


def test_state_round_trips_through_json(danced):
    _, creature, _, _ = danced
    state = json.loads(json.dumps(creature.state()))
    world, fresh = colony(seed=11)
    fresh.restore(state)
    assert fresh.poses.nodes == creature.poses.nodes
    assert core_pitches(fresh) == core_pitches(creature)
    assert [m.id for m in fresh.population.members] == [m.id for m in creature.population.members]
    assert fresh.expected_match.to_dict() == creature.expected_match.to_dict()
    assert fresh.expected_match.clock is world.clock  # confidence fades with the new run's time


def test_bad_config_is_rejected_with_the_key():
    kind = load_all()["listen"]
    with pytest.raises(ValueError, match="memory"):
        kind.Spec(name="x", kind="listen", memory=1)
    with pytest.raises(ValueError, match="context .* must be smaller than memory"):
        kind.Spec(name="x", kind="listen", memory=8, context=8)
