"""MIDI out that a DAW or synth can use as it is: each creature's channel set up at start,
control streams from drives, and an ``out.mid`` with the input, named creature tracks (their
programs and pan) and the tempo the colony heard."""

from __future__ import annotations

import mido
import numpy as np
import pytest

from creatures.cli import main
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.channel_setup import CcStream, channel_setup, midi_pan
from midi.files import TICKS_PER_BEAT, read_notes
from midi.notes import NoteEvent, is_note_off
from midi.sinks import MemorySink

COLONY = """
title = "daw"
seed = 3
tick = 0.02
[midi]
program = 19
volume = 100
[[creature]]
name = "ada"
kind = "exchange"
channel = 0
pan = -0.7
program = 48
bank = 130
space.answer = 1.0
[[creature]]
name = "bo"
kind = "exchange"
channel = 1
pan = 0.5
bend_range = 2.5
"""


def _cc(msg: mido.Message) -> tuple[int, int]:
    return msg.control, msg.value


def test_channel_setup_puts_bank_before_program_and_closes_the_rpn():
    setup = channel_setup(3, pan=1.0, program=5, bank=300, volume=90, bend_range=12.25)
    assert [m.channel for m in setup] == [3] * len(setup)
    assert [m.type for m in setup[:3]] == ["control_change", "control_change", "program_change"]
    assert _cc(setup[0]) == (0, 300 >> 7) and _cc(setup[1]) == (32, 300 & 0x7F) and setup[2].program == 5
    assert [_cc(m) for m in setup[3:]] == [(7, 90), (10, 127), (101, 0), (100, 0), (6, 12), (38, 25),
                                          (101, 127), (100, 127)]
    assert [m.type for m in channel_setup(0, pan=0.0)] == ["control_change"]  # pan only: the synth keeps the rest
    assert (midi_pan(-1.0), midi_pan(0.0), midi_pan(1.0)) == (0, 64, 127)


def test_each_creature_channel_is_set_up_before_its_first_note(tmp_path):
    config = tmp_path / "daw.toml"
    config.write_text(COLONY)
    sink = MemorySink()
    clock = SimulatedClock()
    Session(load_installation(config), clock, EventLog(), sink).scheduler.pump()
    by_channel = {c: [m for _, m in sink.messages if m.channel == c] for c in (0, 1)}
    ada, bo = by_channel[0], by_channel[1]
    assert [m.program for m in ada if m.type == "program_change"] == [48]  # its own over [midi]'s
    assert [_cc(m) for m in ada if m.type == "control_change"] == [(0, 1), (32, 2), (7, 100), (10, midi_pan(-0.7))]
    assert [m.program for m in bo if m.type == "program_change"] == [19]  # [midi]'s default
    controls = [_cc(m) for m in bo if m.type == "control_change"]
    assert (6, 2) in controls and (38, 50) in controls  # its pitch-bend range, 2.5 semitones


def test_a_program_volume_or_pan_set_while_the_run_goes_is_sent_to_the_synth_that_tick(tmp_path):
    """The console's ``set ada program 40`` (and a zone's spec) replace the creature's spec: the
    setup was sent once, at the start, and the synth kept the old instrument. A set that changes
    no setting of the channel (its gain) sends nothing."""
    from creatures.kinds.spec_keys import with_key

    config = tmp_path / "daw.toml"
    config.write_text(COLONY)
    sink, clock = MemorySink(), SimulatedClock()
    session = Session(load_installation(config), clock, EventLog(), sink)
    ada = session.creatures[0]
    session.step(clock.advance(0.02), 0, None, audio=False)
    started = len(sink.messages)
    ada.spec = with_key(ada.spec, "gain", 0.5, "ada")
    session.step(clock.advance(0.02), 0, None, audio=False)
    assert not [m for _, m in sink.messages[started:] if m.type in ("program_change", "control_change")]
    ada.spec = with_key(ada.spec, "program", 40, "ada")
    ada.spec = with_key(ada.spec, "pan", 0.0, "ada")
    t = clock.advance(0.02)
    session.step(t, 0, None, audio=False)
    sent = [(when, m) for when, m in sink.messages[started:] if m.type in ("program_change", "control_change")]
    assert [m.program for _, m in sent if m.type == "program_change"] == [40]
    assert (10, 64) in [_cc(m) for _, m in sent if m.type == "control_change"]  # the centre
    assert {m.channel for _, m in sent} == {0} and {when for when, _ in sent} == {t}
    session.step(clock.advance(0.02), 0, None, audio=False)
    assert len([m for _, m in sink.messages if m.type == "program_change" and m.channel == 0]) == 2  # once each


def test_a_zone_that_sets_a_program_changes_the_instrument_while_a_creature_stands_in_it(tmp_path):
    config = tmp_path / "room.toml"
    config.write_text(COLONY + "[creature.vehicle]\nat = [1.0, 1.0]\nmax_speed = 1.0\n"  # bo's
                      'steer = [{ behaviour = "seek", target = [9.0, 1.0] }]\n'
                      "[room]\nwidth = 10.0\ndepth = 2.0\n"
                      '[[room.zones]]\nname = "organ"\nlow = [4.0, 0.0]\nhigh = [6.0, 2.0]\nspec = { program = 20 }\n')
    sink, clock = MemorySink(), SimulatedClock()
    session = Session(load_installation(config), clock, EventLog(), sink)
    programs = []
    for _ in range(600):  # 12 s: bo walks from x = 1 through the zone (4–6 m) and on
        t = clock.advance(0.02)
        session.step(t, 0, None, audio=False)
        x = float(session.stage.v.pos[1, 0])
        programs += [(round(x, 1), m.program) for when, m in sink.messages if when == t and m.channel == 1
                     and m.type == "program_change"]
    assert [p for _, p in programs] == [20, 19]  # into the zone the organ, out of it [midi]'s program again
    assert 4.0 <= programs[0][0] <= 4.3 and 6.0 <= programs[1][0] <= 6.3


def test_a_cc_stream_follows_a_drive_at_its_rate_and_only_when_it_changes(tmp_path):
    config = tmp_path / "daw.toml"
    config.write_text(COLONY + '[[output.cc]]\nsource = "bo.boredom"\ncontroller = 74\nrange = [0.0, 2.0]\nrate = 5\n')
    sink, clock = MemorySink(), SimulatedClock()
    session = Session(load_installation(config), clock, EventLog(), sink)
    bo = session.creatures[1]
    boredom = {}
    for step in range(1, 501):  # 10 s; bo hears nothing and grows bored
        t = clock.advance_to(step * 0.02)
        session.step(t, 0, None, audio=False)
        boredom[t] = bo.motivation.level("boredom", t)
    stream = [(t, m) for t, m in sink.messages if m.type == "control_change" and m.control == 74]
    assert len(stream) >= 10 and all(b - a >= 0.2 - 1e-9 for (a, _), (b, _) in zip(stream, stream[1:]))
    assert all(m.channel == 1 for _, m in stream)  # on bo's channel
    assert all(m.value != n.value for (_, m), (_, n) in zip(stream, stream[1:]))  # sent only when it changed
    scale = CcStream(1, 74, 0.0, 2.0, 5)
    assert [m.value for _, m in stream] == [scale.value(boredom[t]) for t, _ in stream]
    assert stream[-1][1].value > stream[0][1].value  # bo grew bored


def test_a_cc_stream_of_a_drive_the_creature_lacks_names_the_key_and_line(tmp_path):
    config = tmp_path / "daw.toml"
    config.write_text(COLONY + '[[output.cc]]\nsource = "bo.boredum"\ncontroller = 74\n')
    with pytest.raises(ConfigError) as error:
        Session(load_installation(config), SimulatedClock(), EventLog(), MemorySink())
    assert "output.cc.0.source" in str(error.value) and "boredom" in str(error.value)
    assert f"daw.toml:{COLONY.count(chr(10)) + 2}" in str(error.value)
    config.write_text(COLONY + '[[output.cc]]\nsource = "bob.boredom"\ncontroller = 74\n')
    with pytest.raises(ConfigError, match=r"no creature named 'bob' \(did you mean 'bo'\?\)"):
        load_installation(config)


def test_out_mid_opens_in_mido_and_music21_with_input_named_tracks_programs_pan_and_heard_tempo(tmp_path):
    music21 = pytest.importorskip("music21")
    config = tmp_path / "daw.toml"
    config.write_text(COLONY)
    out = tmp_path / "out"
    assert main(["offline", str(config), "--out", str(out), "--duration", "20"]) == 0
    events = [line for line in (out / "events.jsonl").read_text().splitlines() if '"kind":"tempo"' in line]
    assert events, "the colony heard a pulse in the generated phrases"

    midi = mido.MidiFile(out / "out.mid")
    names = [track.name for track in midi.tracks]
    assert names == ["tempo", "input", "ada", "bo"]
    tracks = dict(zip(names, midi.tracks))
    tempos = [m.tempo for m in tracks["tempo"] if m.type == "set_tempo"]
    assert len(tempos) >= 2 and tempos[0] == 500_000 and tempos[-1] != 500_000  # 120 bpm until it heard one
    heard = [m for m in tracks["input"] if m.type == "note_on" and m.velocity > 0]
    heard_log = [line for line in (out / "events.jsonl").read_text().splitlines() if '"kind":"heard"' in line]
    assert len(heard) == len(heard_log) > 0
    for name, program, pan in (("ada", 48, midi_pan(-0.7)), ("bo", 19, midi_pan(0.5))):
        messages = list(tracks[name])
        assert [m.program for m in messages if m.type == "program_change"] == [program]
        assert [m.value for m in messages if m.type == "control_change" and m.control == 10] == [pan]
    assert any(m.type == "note_on" for m in tracks["ada"])  # ada answers what she hears

    score = music21.converter.parse(str(out / "out.mid"))
    parts = {part.partName: part for part in score.parts}
    assert {"input", "ada", "bo"} <= set(parts)
    assert len(parts["input"].recurse().notes) > 0
    programs = {name: [i.midiProgram for i in parts[name].recurse().getElementsByClass("Instrument")]
                for name in ("ada", "bo")}
    assert 48 in programs["ada"] and 19 in programs["bo"]
    marks = [round(m.number, 1) for m in score.recurse().getElementsByClass("MetronomeMark")]
    assert round(mido.tempo2bpm(tempos[-1]), 1) in marks, marks


def test_a_run_says_how_many_notes_re_struck_a_sounding_key(tmp_path):
    """Two creatures on one channel playing one pitch at once share MIDI's one key: the
    re-strike that keeps the later note whole is counted in the log and said at the end."""
    config = tmp_path / "daw.toml"
    config.write_text(COLONY.replace("channel = 1", "channel = 0"))
    said: list[str] = []
    clock = SimulatedClock()
    log = EventLog()
    session = Session(load_installation(config), clock, log, MemorySink(), say=said.append)
    ada, bo = session.creatures
    session.world.play(ada, NoteEvent(0.0, 60, 100, 0, 2.0))
    session.world.play(bo, NoteEvent(1.0, 60, 90, 0, 2.0))
    clock.advance_to(4.0)
    session.scheduler.pump()
    session.close()
    assert [e["notes"] for e in log.records if e["kind"] == "restruck"] == [1]
    assert any(message.startswith("1 note started on a key (channel and pitch) still sounding") for message in said)


def test_out_mid_input_track_re_strikes_a_key_played_again_before_its_note_ended(tmp_path):
    """An input that strikes a key again while it sounds (on, on, off, off: two controllers,
    a sequencer) was written to out.mid's input track the same way, which a synth plays as the
    second note cut short at the first note-off. The track ends the first note at the re-strike
    (off, then on, at one tick) and sounds the key to the later end; read back, the onsets and
    pitches are those heard and the first note is shortened to the re-strike."""
    config = tmp_path / "daw.toml"
    config.write_text(COLONY)
    played = mido.MidiFile(type=0, ticks_per_beat=480)  # 120 bpm: 960 ticks a second
    played.tracks.append(mido.MidiTrack([
        mido.Message("note_on", channel=5, note=70, velocity=100, time=480),   # 0.5 s
        mido.Message("note_on", channel=5, note=70, velocity=80, time=960),    # 1.5 s, the key still down
        mido.Message("note_off", channel=5, note=70, time=960),                # 2.5 s
        mido.Message("note_off", channel=5, note=70, time=480)]))              # 3.0 s
    played.save(tmp_path / "again.mid")
    out = tmp_path / "out"
    assert main(["offline", str(config), "--midi", str(tmp_path / "again.mid"), "--out", str(out),
                 "--duration", "6"]) == 0

    midi = mido.MidiFile(out / "out.mid")
    track = next(t for t in midi.tracks if t.name == "input")
    ticks = np.cumsum([m.time for m in track]).tolist()
    notes = [(tick / (2 * midi.ticks_per_beat), "off" if is_note_off(m) else "on", m.note)
             for tick, m in zip(ticks, track) if m.type in ("note_on", "note_off")]
    assert midi.ticks_per_beat == TICKS_PER_BEAT and notes == [(0.5, "on", 70), (1.5, "off", 70), (1.5, "on", 70),
                                                               (3.0, "off", 70)]  # 120 bpm: no pulse heard in two
    heard = [(n.time, n.pitch, n.velocity, n.duration) for n in read_notes(out / "out.mid") if n.channel == 5]
    assert heard == [(0.5, 70, 100, 1.0), (1.5, 70, 80, 1.5)]
