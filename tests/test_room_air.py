"""Sound across a room (creatures/room/air.py, issue 21: "hearing attenuated and delayed by
distance"): the input and the voices reach each listening ear by the distance law, late by
distance/343 s, in a run as in the unit."""

from __future__ import annotations

import textwrap

import numpy as np

from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.room.air import RoomAir
from creatures.room.hearing import SPEED_OF_SOUND, DistanceLaw
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink

RATE = 22050
FRAMES = 441  # a 0.02 s tick


def air(delay: bool = True) -> RoomAir:
    return RoomAir(DistanceLaw("inverse", 1.0), delay=delay, sample_rate=RATE, voices=2, diagonal=15.0,
                   longest_block=FRAMES)


def late(distance: float) -> int:
    return int(round(distance / SPEED_OF_SOUND * RATE))


def test_the_input_arrives_by_the_law_and_late_by_the_distance():
    room = air()
    click = np.zeros(FRAMES, np.float32)
    click[10] = 1.0
    positions = np.array([[1.0, 0.0], [4.0, 0.0]])
    heard = []
    for block in (click, None):
        room.hear_input(block, FRAMES)
        heard.append(room.ears(np.array([0, 1]), positions, np.ones(2), np.zeros(2), np.ones(2), FRAMES, voices=False))
    heard = np.concatenate(heard, axis=1)  # (ears, two ticks)
    for ear, distance in enumerate((1.0, 4.0)):
        at = int(np.argmax(heard[ear]))
        assert at == 10 + late(distance)  # 64 and 257 samples: 2.9 and 11.7 ms
        assert heard[ear, at] == np.float32(1.0 / distance)  # inverse law, full level at 1 m
        assert np.count_nonzero(heard[ear]) == 1


def test_a_voice_reaches_the_other_ear_a_tick_late_at_its_gain_and_its_own_ear_at_once():
    room = air()
    voices = np.zeros((2, FRAMES), np.float32)
    voices[0, 0] = 1.0  # creature 0 sings a click
    positions = np.array([[0.0, 0.0], [2.0, 0.0]])
    room.hear_input(None, FRAMES)
    room.hear_voices(voices)
    heard = []
    for _ in range(2):
        room.hear_input(None, FRAMES)
        heard.append(room.ears(np.array([0, 1]), positions, np.array([0.5, 1.0]), np.zeros(2), np.zeros(2), FRAMES,
                               voices=True))
        room.hear_voices(np.zeros((2, FRAMES), np.float32))
    heard = np.concatenate(heard, axis=1)
    assert np.argmax(heard[0]) == 0 and heard[0, 0] == np.float32(0.5)  # its own mouth, at its gain
    assert np.argmax(heard[1]) == late(2.0) and heard[1, late(2.0)] == np.float32(0.25)  # 0.5 × 1/2
    assert np.count_nonzero(heard) == 2


def test_without_delay_the_input_arrives_at_once():
    room = air(delay=False)
    block = np.linspace(-1, 1, FRAMES).astype(np.float32)
    room.hear_input(block, FRAMES)
    heard = room.ears(np.array([0]), np.array([[3.0, 4.0]]), np.ones(2), np.zeros(2), np.ones(1), FRAMES, voices=False)
    np.testing.assert_allclose(heard[0], block / 5.0, rtol=1e-6)


CONFIG = """
title = "air"
seed = 1
tick = 0.02
[audio]
sample_rate = 22050
air = {air}
[output]
report = false
[room]
width = 12.0
depth = 4.0
input_at = [1.0, 2.0]
"""

LISTENER = """
[[creature]]
name = "{name}"
kind = "authored"
[creature.vehicle]
at = [{x}, 2.0]
max_speed = 0.001  # stays where it stands (to 0.4 mm over the test)
[creature.hearing]
[creature.tuples.rest]
action = "rest"
until = {{ seconds = 1.0 }}
[creature.groups.main]
tuples = ["rest"]
alpha = 0.0
"""


def test_in_a_run_each_ear_hears_the_input_by_its_distance(tmp_path):
    """Two creatures 1 m and 9 m from where the input sounds: the far one hears it 19 dB down
    and 23 ms later; a deaf creature (hears_input = false) hears none of it."""
    path = tmp_path / "air.toml"
    deaf = LISTENER.format(name="deaf", x=2.0).replace('kind = "authored"', 'kind = "authored"\nhears_input = false')
    path.write_text(textwrap.dedent(CONFIG.format(air="false")) + LISTENER.format(name="near", x=2.0)
                    + LISTENER.format(name="far", x=10.0) + deaf)
    clock = SimulatedClock()
    session = Session(load_installation(path), clock, EventLog(), MemorySink())
    heard: dict[str, list[np.ndarray]] = {c.name: [] for c in session.creatures}
    for creature in session.creatures:
        creature.aural.listen = lambda t, block, rate, name=creature.name: heard[name].append(block.copy())
    rng = np.random.default_rng(0)
    burst = np.zeros(20 * FRAMES, np.float32)
    burst[FRAMES:3 * FRAMES] = rng.normal(0, 0.1, 2 * FRAMES)  # 40 ms of noise, 20 ms in
    for k in range(20):
        session.step(clock.advance(0.02), FRAMES, burst[k * FRAMES:(k + 1) * FRAMES], audio=False)
    near, far = (np.concatenate(heard[name]) for name in ("near", "far"))
    assert not np.any(np.concatenate(heard["deaf"]))
    assert np.isclose(np.abs(far).max() / np.abs(near).max(), 1.0 / 9.0, rtol=1e-3)
    onset = lambda x: int(np.flatnonzero(np.abs(x) > 1e-6)[0])  # noqa: E731
    assert onset(near) == FRAMES + late(1.0) and onset(far) == FRAMES + late(9.0)
