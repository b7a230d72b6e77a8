"""Complex shaping (issue 17; thesis "learning to chase your tail"): the tutorial dog
(installations/tutorial/dog.toml) follows a training stick round a circle, is rewarded for
it, learns the movement in a gesture model inside an Ac percept whose tuple has proximity 1
to the guide, and once the core is dispatched into its motor graph as new material, a new
motor-program tuple performs the circle with no stick. The learnt gesture survives a save
and a reload of the creature's state."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from audio.cepstrum import dtw_cost
from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import WhateverPercept
from creatures.behaviour.value import ScalarValue
from creatures.clock import SimulatedClock
from creatures.events import EventLog, read_events
from creatures.kinds.parts import Body
from creatures.kinds.shaping import Circle, GestureShaping, PerformGesture
from creatures.motor.gesture import BodyMemory
from creatures.persist import StateFileError
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink
from tests.test_state_renamed_parts import _dog

DOG = Path(__file__).resolve().parents[1] / "installations" / "tutorial" / "dog.toml"
TICK = 0.05
STICK_GONE = 120.0  # creatures/dog.toml: the stick is held out for the first two minutes
SECONDS = 160.0


def _session(log: EventLog) -> tuple[Session, SimulatedClock]:
    clock = SimulatedClock()
    return Session(load_installation(DOG), clock, log, MemorySink()), clock


def _run(session: Session, clock: SimulatedClock, start: float, seconds: float) -> None:
    for step in range(1, int(round(seconds / TICK)) + 1):
        t = round(start + step * TICK, 6)
        clock.advance_to(t)
        session.step(t, 0, None, audio=False)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """The dog trained for two minutes, then left alone for 40 s; its state saved."""
    out = tmp_path_factory.mktemp("dog")
    log = EventLog(out / "events.jsonl")
    session, clock = _session(log)
    _run(session, clock, 0.0, SECONDS)
    session.save_state(out / "state")
    log.close()
    return session, read_events(out / "events.jsonl"), out / "state"


def _activations(events: list[dict]) -> list[tuple[str, float, float]]:
    """(tuple, start, stop) of every finished activation."""
    started: dict[str, float] = {}
    done = []
    for e in events:
        if e["kind"] == "selection":
            started[e["tuple"]] = e["t"]
        elif e["kind"] == "stop" and e["tuple"] in started:
            done.append((e["tuple"], started.pop(e["tuple"]), e["t"]))
    return done


def _hand(events: list[dict], start: float, stop: float) -> np.ndarray:
    """The effector's path between two times, from the creature's motor reports (ten a second)."""
    return np.array([[e["position"][k] for k in "xyz"] for e in events
                     if e["kind"] == "motor" and start <= e["t"] < stop])


def dtw_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Time-warped distance between two trajectories: the best path's cost per step."""
    cost, length = dtw_cost(a, b)
    return cost / length


def _random_walk(seed: int, seconds: float) -> np.ndarray:
    """The hand of a body walking its motor graph at random (a random neighbour at each
    arrival), sampled ten times a second: what a creature that learnt nothing would trace."""
    rng = np.random.default_rng(seed)
    body = Body(rng)
    path, t = [], 0.0
    while t < seconds:
        if body.motor.arrived(t):
            node = body.motor.position(t).node
            adjacency = body.graph.adjacency
            near = adjacency.indices[adjacency.indptr[node]:adjacency.indptr[node + 1]]
            body.motor.set_course(t, body.motor.course(t, [int(rng.choice(near))]))
        body.update(t)
        path.append(body.hand().copy())
        t += 0.1
    return np.array(path)


def _winding(path: np.ndarray) -> float:
    """Degrees the path turns about the stick circle's centre, in the circle's plane."""
    circle = Circle.in_reach(Body(np.random.default_rng(0)).reach(), 1.0)
    q = path - circle.center
    angle = np.unwrap(np.arctan2(q @ circle.v, q @ circle.u))
    return float(np.degrees(abs(angle[-1] - angle[0])))


def test_a_circle_taught_under_a_guide_is_reproduced_without_it(trained):
    _, events, _ = trained
    gesture = [e for e in events if e["kind"] == "gesture"]
    assert len(gesture) == 1 and gesture[0]["tuple"] == "chase tail" and gesture[0]["replaces"] == "chase"
    dispatched = gesture[0]["t"]
    activations = _activations(events)
    trials = [a for a in activations if a[0] == "follow" and a[2] <= dispatched]
    assert 5 <= len(trials) <= 20  # five rewarded runs taught it (dispatch_after = 5)
    taught = _hand(events, *trials[-1][1:])
    assert _winding(taught) >= 300.0  # the hand went round the stick's circle
    alone = [a for a in activations if a[0] == "chase tail" and a[1] >= STICK_GONE]
    assert len(alone) >= 3  # with no stick, the new tuple is what the dog does
    walks = [dtw_distance(_random_walk(seed, 6.5), taught) for seed in range(5)]
    ratios = [dtw_distance(_hand(events, *a[1:]), taught) / float(np.mean(walks)) for a in alone]
    print(f"trials {len(trials)}; DTW ratio to a random walk's: median {np.median(ratios):.3f}, "
          f"worst {max(ratios):.3f}")
    assert max(ratios) <= 0.25
    assert min(_winding(_hand(events, *a[1:])) for a in alone) >= 300.0  # round the circle, with no stick


def test_the_guide_credit_reached_the_shaping_tuple_at_proximity_one(trained):
    session, events, _ = trained
    dog = session.creatures[0]
    group = dog.groups["main"]
    assert group.proximities.between(group.find("follow").action, group.find("chase tail").action) == 0.0
    assert ("follow", "chase") in group.proximities.fixed and group.proximities.table[("follow", "chase")] == 1.0
    credit = [e for e in events if e["kind"] == "credit" and e["last"] == "follow" and e["new"] == "treat"]
    assert credit and all(e["blended"]["chase"] == pytest.approx(0.3) for e in credit[:3])
    values = [e for e in events if e["kind"] == "values" and "chase" in e.get("values", {})]
    assert values[-1]["values"]["chase"] > 1.5  # from 0.5, toward 0.8 × the treat's 10


def test_the_new_motor_program_survives_save_and_reload(trained, tmp_path):
    session, events, state = trained
    before = session.creatures[0]
    saved = json.loads((state / "dog.json").read_text())["state"]
    assert saved["gestures"][0]["program"].startswith("chase tail: getTo ")
    log = EventLog(tmp_path / "events.jsonl")
    fresh, clock = _session(log)
    assert fresh.load_state(state) == ["dog"]
    dog = fresh.creatures[0]
    group = dog.groups["main"]
    chase = group.find("chase tail")
    assert isinstance(chase.action, PerformGesture) and "chase" not in [tp.name for tp in group.tuples]
    assert chase.action.gesture.program.statements == before.groups["main"].find("chase tail").action.gesture.program.statements
    assert chase.value.to_float() == pytest.approx(before.groups["main"].find("chase tail").value.to_float())
    assert len(dog.body.graph) == len(before.body.graph) > len(Body(np.random.default_rng(0)).graph)
    # performed after the reload, without the stick: the same circle
    start = 1000.0  # long after the stick: only the learnt gesture and idling compete
    clock.advance_to(start)
    _run(fresh, clock, start, 30.0)
    log.close()
    after = read_events(tmp_path / "events.jsonl")
    runs = [a for a in _activations(after) if a[0] == "chase tail"]
    assert runs
    taught = _hand(events, *[a for a in _activations(events) if a[0] == "follow"][-1][1:])
    walk = np.mean([dtw_distance(_random_walk(seed, 6.5), taught) for seed in range(5)])
    assert dtw_distance(_hand(after, *runs[0][1:]), taught) / walk <= 0.25
    # the gesture model came back too: the trainer's eye still sees the circle
    assert any(e["kind"] == "credit" and e["last"] == "chase tail" and e["new"] == "praise" for e in after)
    assert [e["restored"] for e in after if e["kind"] == "gesture"] == [True]


def test_a_gesture_saved_over_another_body_is_refused(trained, tmp_path):
    _, _, state = trained
    data = json.loads((state / "dog.json").read_text())
    data["state"]["gestures"][0]["program"] = "chase tail: getTo 3; wait; end"
    (tmp_path / "dog.json").write_text(json.dumps(data))
    fresh, _ = _session(EventLog())
    with pytest.raises(StateFileError, match=r"gestures\.0\.program"):
        fresh.load_state(tmp_path)


def test_the_shaping_model_learns_only_from_rewarded_runs(trained):
    session, events, _ = trained
    shaping = [e for e in events if e["kind"] == "gesture"][0]
    credited = [e for e in events if e["kind"] == "credit" and e["last"] in ("follow", "chase")
                and e["new"] in ("treat", "praise") and e["t"] <= shaping["t"]]
    assert len(credited) == 5  # the fifth reward dispatched it; unrewarded runs taught nothing
    assert not any(isinstance(tp.action, GestureShaping) for tp in session.creatures[0].groups["main"].tuples)


@pytest.mark.parametrize("guide, treat, lessons", [
    ("follow", 10.0, 1),   # proximity 1 to the guide, and the guide was rewarded: learnt
    (None, 10.0, 0),       # no proximity to the guide: its credit does not reach the model
    ("follow", 0.5, 0),    # what followed the guide was worth less than it: no reward
])
def test_the_gesture_model_learns_a_guided_run_only_through_proximity_and_reward(rng, guide, treat, lessons):
    memory = BodyMemory()
    for k, node in enumerate([4, 9, 2, 7, 5]):
        memory.record(node, 0.5 + k)
    shaping = GestureShaping("chase", None, memory, dispatch_after=100, gesture="chase tail", guide=guide)
    tuples = [ActionTuple("follow", WhateverPercept(), Action("follow"), DoUntil(100.0), 1.0),
              ActionTuple("chase", WhateverPercept(), shaping, DoUntil(100.0), 0.5),
              ActionTuple("treat", WhateverPercept(), Action("treat"), DoUntil(1.0), ScalarValue(treat, plasticity=0.0))]
    group = ActionGroup("dog", tuples, rng=rng, alpha=0.3, discount=0.8)
    shaping.attach(group)
    group.force("follow", 0.0)
    group.force("treat", 5.0)
    assert shaping.lessons == lessons
    if lessons:
        assert [shaping.model.states[s].node for s in shaping.model.core()] == [4, 9, 2, 7, 5]
        assert shaping.match(list(memory)) == 1.0  # as a percept model: the taught run is certain
        assert shaping.match(list(memory)[::-1]) == 0.0  # the same poses backwards were never seen
        assert group.find("chase").value.to_float() == pytest.approx(0.7 * 0.5 + 0.3 * 8.0)


def test_without_the_stick_the_trainer_praises_the_movement_itself(trained):
    _, events, _ = trained
    praised = [e for e in events if e["kind"] == "credit" and e["last"] == "chase tail" and e["new"] == "praise"
               and e["t"] >= STICK_GONE]
    assert praised  # the 'shaped' percept saw the circle in the body's memory
    later = [e["values"]["chase tail"] for e in events if e["kind"] == "values" and e["t"] >= STICK_GONE]
    assert later[-1] > 6.0  # toward 0.8 × the praise's 10


@pytest.mark.parametrize("damage, named", [
    (lambda s: s["gestures"][0].update(core=[-1, 2]), "gestures.0.core"),
    (lambda s: s["gestures"][0].update(dwell=[0.1]), "gestures.0.dwell"),
    (lambda s: s["gestures"][0].update(shaping="idle"), "gestures.0.shaping"),
    (lambda s: s["gestures"].append(dict(s["gestures"][0])), "already has material"),
    (lambda s: s["shaping"]["chase"]["model"]["states"][0].update(node=10**9), "shaping.chase.model.states.0.node"),
    (lambda s: s["proximity"]["main"]["table"].append(["a", "b", 2.0]), "proximity.main.table"),
])
def test_a_damaged_shaping_state_is_refused_naming_the_key(trained, tmp_path, damage, named):
    _, _, state = trained
    data = json.loads((state / "dog.json").read_text())
    damage(data["state"])
    (tmp_path / "dog.json").write_text(json.dumps(data))
    fresh, _ = _session(EventLog())
    with pytest.raises(StateFileError, match=named.replace(".", r"\.")):
        fresh.load_state(tmp_path)


def test_a_merged_gesture_is_performed_by_a_dog_that_was_never_taught(trained, tmp_path):
    """``creatures state merge``: the trained dog's dispatched gesture (motor material) into an
    untaught dog's state; restored, the untaught dog has the new nodes and the 'chase tail'
    tuple, and performs it without a stick."""
    from creatures.cli import main

    _, _, state = trained
    pupil = tmp_path / "pupil"
    session, clock = _session(EventLog())
    _run(session, clock, 0.0, 5.0)
    session.save_state(pupil)
    assert "gestures" not in json.loads((pupil / "dog.json").read_text())["state"]
    assert main(["state", "merge", str(state), "--creature", "dog", str(pupil), "--into", "dog"]) == 0
    log = EventLog(tmp_path / "events.jsonl")
    fresh, clock = _session(log)
    assert fresh.load_state(pupil) == ["dog"]
    dog = fresh.creatures[0]
    assert isinstance(dog.groups["main"].find("chase tail").action, PerformGesture)
    assert len(dog.body.graph) > len(Body(np.random.default_rng(0)).graph)
    clock.advance_to(1000.0)
    _run(fresh, clock, 1000.0, 60.0)
    log.close()
    assert [a for a in _activations(read_events(tmp_path / "events.jsonl")) if a[0] == "chase tail"]


def test_merged_gestures_are_renumbered_after_the_targets_own():
    from creatures.runtime import repertoire

    def gesture(shaping: str, first: int, count: int) -> dict:
        program = f"{shaping}: " + "; ".join(f"getTo {first + k}; wait" for k in range(count)) + "; end"
        return {"shaping": shaping, "name": shaping, "core": list(range(count)), "dwell": [0.1] * count,
                "program": program}

    src = {"gestures": [gesture("spin", 100, 3), gesture("bow", 103, 4)], "shaping": {"spin": {}, "bow": {}}}
    dst = {"gestures": [gesture("bow", 100, 5)], "shaping": {"spin": {}, "bow": {}}}
    added = repertoire._merge_gestures(src, dst)
    assert [g["shaping"] for g in dst["gestures"]] == ["bow", "spin"]
    assert dst["gestures"][1]["program"] == "spin: getTo 105; wait; getTo 106; wait; getTo 107; wait; end"
    assert "not added: gesture bow (the target dispatched its own from 'bow')" in added
    other = {"gestures": [gesture("bow", 90, 5)], "shaping": {"spin": {}}}
    with pytest.raises(StateFileError, match="different bodies"):
        repertoire._merge_gestures(src, other)


def test_a_gesture_of_a_renamed_shaping_tuple_is_kept_not_refused(trained, tmp_path):
    """The shaping tuple renamed in the config ('chase' to 'chaser') after the dog had learnt its
    gesture: the whole state file was refused ("gestures.0.shaping: no shape_gesture tuple named
    'chase'"), so the dog could not start with that config. Now the gesture's nodes are
    dispatched again (a later gesture's nodes follow them), it is kept in every save, said with
    its shaping, and left behind in its tuple's place when the name returns."""
    session, _, saved = trained
    state = tmp_path / "state"
    shutil.copytree(saved, state)
    said: list[str] = []
    renamed = _dog(tmp_path, said, chase="chaser")
    assert renamed.load_state(state) == ["dog"]
    assert any("the saved shaping of tuple 'chase' matches no shape_gesture tuple" in line for line in said), said
    assert len(renamed.creatures[0].body.graph) == len(session.creatures[0].body.graph)
    renamed.save_state(state)
    assert [g["shaping"] for g in json.loads((state / "dog.json").read_text())["state"]["gestures"]] == ["chase"]
    back = _dog(tmp_path, [])  # the name returns: the gesture is performed in the shaping tuple's place again
    back.load_state(state)
    assert isinstance(back.creatures[0].groups["main"].find("chase tail").action, PerformGesture)
