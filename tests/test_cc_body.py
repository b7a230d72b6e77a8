"""``[[output.cc]]`` streams from the body (issue 14): a synth control that follows the
creature's hand — its height or its speed — in ``out.mid`` as live, and a source the
creature cannot give refused at load with its key and line."""

from __future__ import annotations

import mido
import numpy as np
import pytest

import installations
from creatures.cli import main
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog
from creatures.runtime.schema import load_installation
from creatures.runtime.score import write_score
from creatures.runtime.session import Session
from midi.sinks import MemorySink
from test_midi_out import COLONY

TICK, STEPS = 0.02, 1000  # 20 s, COLONY's tick
STREAMS = ('[output]\nwav = false\nreport = false\n'
           '[[output.cc]]\nsource = "ada.body.effector_height"\ncontroller = 20\nrange = [0.9, 1.05]\nrate = 50\n'
           '[[output.cc]]\nsource = "ada.body.speed"\ncontroller = 21\nrange = [0.0, 3.0]\nrate = 50\n')


def run(config, out_mid) -> dict[float, np.ndarray]:
    """ada's hand position at every tick of a run stepped as the offline run steps it, which
    writes its ``out.mid`` as the offline run does (``write_score`` of what the sink kept)."""
    sink, clock = MemorySink(), SimulatedClock()
    session = Session(load_installation(config), clock, EventLog(), sink)
    session.world.recording = True
    hand = {}
    for step in range(1, STEPS + 1):
        t = clock.advance_to(step * TICK)
        session.step(t, 0, None, audio=False)
        hand[t] = session.creatures[0].effector().copy()
    write_score(out_mid, session.world, sink.messages)
    return hand


def written_streams(out_mid) -> dict[int, list[tuple[float, int]]]:
    """``(time s, value)`` of each CC stream in ``out.mid`` (mido reads times through its tempo map)."""
    streams: dict[int, list[tuple[float, int]]] = {20: [], 21: []}
    t = 0.0
    for msg in mido.MidiFile(out_mid):
        t += msg.time
        if msg.type == "control_change" and msg.control in streams:
            assert msg.channel == 0  # on ada's channel
            streams[msg.control].append((t, msg.value))
    return streams


def test_out_mid_carries_cc_streams_that_follow_the_hands_height_and_speed(tmp_path):
    config = tmp_path / "daw.toml"
    config.write_text(COLONY + STREAMS)
    hand = run(config, tmp_path / "out.mid")
    times = sorted(hand)[1:]  # the speed needs a tick before
    # The features, clipped to each stream's range (what a CC can say; the hand's speed spikes
    # past 3 units/s where the body turns onto a new course).
    truth = {20: np.clip([hand[t][1] for t in times], 0.9, 1.05),
             21: np.clip([np.linalg.norm(hand[b] - hand[a]) / (b - a) for a, b in zip(sorted(hand), times)], 0.0, 3.0)}
    for controller, stream in written_streams(tmp_path / "out.mid").items():
        assert len(stream) >= 50 and len({v for _, v in stream}) >= 10, stream  # it moves, it is not a constant
        # A CC holds its value until the next: that step function against the feature at every
        # tick (out.mid's times are quantised to its ticks: a quarter behaviour tick of slack).
        at = np.searchsorted([t for t, _ in stream], np.array(times) + TICK / 4, side="right") - 1
        level = np.array([v for _, v in stream])[np.maximum(at, 0)]
        assert np.corrcoef(level, truth[controller])[0, 1] >= 0.9, controller
    # `creatures offline` writes them too.
    assert main(["offline", str(config), "--out", str(tmp_path / "out"), "--duration", "5"]) == 0
    assert all(len(stream) >= 10 for stream in written_streams(tmp_path / "out" / "out.mid").values())


@pytest.mark.parametrize("source, message", [
    ("ada.body.efector_height", "no body feature 'efector_height' (did you mean 'effector_height'?)"),
    ("ada.boddy.speed", "'boddy' is not 'body'"),
    ("ada.boredum", "ada has no drive 'boredum' (did you mean 'boredom'?)"),
])
def test_a_body_feature_or_drive_the_creature_cannot_give_is_refused_at_load_with_key_and_line(tmp_path, source,
                                                                                              message):
    config = tmp_path / "daw.toml"
    config.write_text(COLONY + f'[[output.cc]]\nsource = "{source}"\ncontroller = 20\n')
    with pytest.raises(ConfigError) as error:
        load_installation(config)
    assert "output.cc.0.source" in str(error.value) and message in str(error.value), error.value
    assert f"daw.toml:{COLONY.count(chr(10)) + 2}" in str(error.value)


def test_a_creature_without_a_body_has_no_body_features(tmp_path):
    config = tmp_path / "bodiless.toml"
    config.write_text(f'extends = "{installations.path("three_creatures")}"\n'
                      '[[output.cc]]\nsource = "left.body.effector_height"\ncontroller = 20\n')
    with pytest.raises(ConfigError, match=r"bodiless.toml:3.*output.cc.0.source.*left has no body"):
        load_installation(config)


def test_an_authored_creature_streams_its_hand_when_it_has_a_body(tmp_path):
    """``body = true`` on an authored creature gives it the features (``Authored.has_body``)."""
    config = tmp_path / "authored.toml"
    config.write_text(f'extends = "{installations.path("exchange")}"\n'
                      '[[output.cc]]\nsource = "bo.body.speed"\ncontroller = 21\nrange = [0.0, 3.0]\n')
    sink, clock = MemorySink(), SimulatedClock()
    session = Session(load_installation(config), clock, EventLog(), sink)
    for step in range(1, 301):
        session.step(clock.advance_to(step * session.inst.settings.tick), 0, None, audio=False)
    values = [m.value for _, m in sink.messages if m.type == "control_change" and m.control == 21]
    assert len(values) >= 10 and len(set(values)) >= 5, values  # the hand moves, at varying speeds
