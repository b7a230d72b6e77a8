"""The live MIDI input's bound (``[midi] max_rate``): a flood from a broken or hostile controller
is cut to a bounded share of the creature's thread and counted, playing never loses a message,
and a note let in always gets its note-off (a dropped one would leave the note stuck)."""

from __future__ import annotations

import json

import mido

from input_fixtures import COLONY

from creatures.cli import main
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime import live
from creatures.runtime.live import LiveInputs
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.gate import BURST
from midi.ports import MemoryInput, MemoryPorts
from midi.sinks import MemorySink

CONFIG = COLONY + '[audio]\noutput = false\n[midi]\ninput_port = "keys"\n'


def on(note: int, channel: int = 0) -> mido.Message:
    return mido.Message("note_on", channel=channel, note=note, velocity=90)


def off(note: int, channel: int = 0) -> mido.Message:
    return mido.Message("note_off", channel=channel, note=note)


def colony(tmp_path, extra: str = "") -> tuple[Session, LiveInputs, MemoryInput, SimulatedClock]:
    """The colony of the input-map tests with a keyboard (an in-memory MIDI twin) on its input."""
    config = tmp_path / "live.toml"
    config.write_text(CONFIG + extra)
    inst = load_installation(config)
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(), MemorySink())
    keys = MemoryInput("keys")
    return session, LiveInputs(inst, session, clock, say=lambda m: None, ports=MemoryPorts(keys)), keys, clock


def counts(session: Session) -> dict:
    """The ``inputs`` event the session ends its log with."""
    session.close()
    return [e for e in session.log.records if e["kind"] == "inputs"][-1]


def test_a_burst_of_ten_thousand_notes_is_cut_to_the_bucket_and_counted(tmp_path):
    session, inputs, keys, clock = colony(tmp_path)
    burst = int(session.inst.settings.midi.max_rate * BURST)
    for i in range(10_000):
        keys.inject(on(24 + i % 80))
        keys.inject(off(24 + i % 80))
    clock.advance(0.02)
    assert inputs.poll(clock.now()) == burst  # heard: what the bucket held
    # a flood that goes on is taken at max_rate, not at the rate it comes
    heard = burst
    for step in range(1, 51):  # 1 s more at 5,000 note-ons a second
        for i in range(100):
            keys.inject(on(60 + i % 12, channel=1))
        clock.advance(0.02)
        heard += inputs.poll(clock.now())
    rate = session.inst.settings.midi.max_rate
    assert burst + rate - 1 <= heard <= burst + rate + 1
    said = [e for e in session.log.records if e["kind"] == "throttled"]
    assert said and "[midi] max_rate" in said[0]["why"]
    inputs.close()
    counted = counts(session)
    # every message is counted once: taken (a note-on and the note-off of one let in) or throttled
    assert counted["mapped midi"] == burst * 2 + heard - burst
    assert counted["throttled midi"] == 20_000 + 5_000 - counted["mapped midi"]
    assert counted["throttled"] == counted["throttled midi"]


def test_playing_is_never_throttled_a_fast_trill_chords_of_ten_a_mod_wheel_and_the_pedal(tmp_path):
    session, inputs, keys, clock = colony(tmp_path)
    sent = notes = 0
    for step in range(1, 501):  # 10 s at 50 polls a second, the colony's tick
        t = step * 0.02
        played: list[mido.Message] = []
        played += [on(72 + step % 2), off(73 - step % 2)]  # a trill of 50 notes a second, legato
        if step % 25 == 0:  # a chord of ten, both hands, every half second, let go just before the next
            chord = [36, 43, 48, 52, 55, 60, 64, 67, 72, 76]
            played += [off(n) for n in chord] + [on(n) for n in chord] if step > 25 else [on(n) for n in chord]
            played.append(mido.Message("control_change", control=64, value=127 * (step // 25 % 2)))  # the pedal
        played += [mido.Message("control_change", control=1, value=(step * 2 + k) % 128) for k in range(2)]  # the wheel
        for msg in played:
            keys.inject(msg)
        sent += len(played)
        notes += sum(msg.type == "note_on" for msg in played)
        clock.advance_to(t)
        assert inputs.poll(t) == sum(msg.type == "note_on" for msg in played)
    inputs.close()
    counted = counts(session)
    assert counted.get("throttled", 0) == 0
    assert counted["mapped midi"] + counted["unmapped midi"] == sent and notes == 500 + 20 * 10


def test_a_note_let_in_gets_its_note_off_even_when_a_flood_has_spent_the_budget(tmp_path):
    session, inputs, keys, clock = colony(tmp_path, '\n[[input]]\nmidi = "note_off"\nto = "sensor"\nname = "lifted"\n')
    chord = [48, 52, 55, 60, 64, 67, 72, 76, 79, 84]
    for n in chord:
        keys.inject(on(n, channel=3))
    keys.inject(on(38, channel=9))  # the snare, let in: its release is a note-on of velocity 0
    clock.advance(0.02)
    assert inputs.poll(clock.now()) == 11
    for i in range(10_000):  # a broken pad: note-ons only, and far too many
        keys.inject(on(36 + i % 12, channel=9))
    for n in chord:  # the chord is let go in the same instant: no budget has come back
        keys.inject(off(n, channel=3))
    keys.inject(mido.Message("note_on", channel=9, note=38, velocity=0))
    keys.inject(off(100, channel=3))  # a note-off of no note let in spends the budget as any message
    inputs.poll(clock.now())
    lifted = session.world.sensors["lifted"]
    assert len(lifted) == 11  # every release of a note let in reached its map
    inputs.close()
    counted = counts(session)
    assert counted["mapped midi"] == 2 * 11 + int(session.inst.settings.midi.max_rate * BURST) - 11
    assert counted["throttled midi"] == 11 + 10_000 + 11 + 1 - counted["mapped midi"]


def test_the_run_summary_and_the_inputs_event_say_what_max_rate_dropped(tmp_path, monkeypatch, capsys):
    keys = MemoryInput("keys")
    for i in range(2_000):  # waiting when the run opens the port: all read at its first look
        keys.inject(on(40 + i % 40))
        keys.inject(off(40 + i % 40))
    monkeypatch.setattr(live, "MidoInputs", lambda: MemoryPorts(keys))
    config = tmp_path / "live.toml"
    config.write_text(CONFIG + "max_rate = 200\n")
    log = tmp_path / "events.jsonl"
    assert main(["run", str(config), "--duration", "0.3", "--log", str(log)]) == 0
    taken = int(200 * BURST)
    assert f"{2 * taken} mapped, 0 unmapped, 0 malformed, {2 * (2_000 - taken)} throttled" in capsys.readouterr().out
    counted = [e for e in map(json.loads, log.read_text().splitlines()) if e["kind"] == "inputs"][-1]
    assert counted["throttled midi"] == 2 * (2_000 - taken)


def test_a_panic_all_notes_off_passes_a_spent_budget_on_a_channel_holding_notes_and_ends_them(tmp_path):
    """CC 123 (or 120, 124–127) ends every note of its channel: on a channel holding notes let in
    it passes without a token, as their note-offs would, and those notes are no longer held (their
    late note-offs spend the budget as any message); on a channel holding none it spends one."""
    session, inputs, keys, clock = colony(tmp_path, '\n[[input]]\nmidi = "cc"\ncontrol = 123\nto = "sensor"\nname = "panic"\n')
    for n in (48, 52, 55):
        keys.inject(on(n, channel=3))
    clock.advance(0.02)
    assert inputs.poll(clock.now()) == 3
    for i in range(10_000):  # a broken pad spends the budget
        keys.inject(on(36 + i % 12, channel=9))
    keys.inject(mido.Message("control_change", channel=3, control=123, value=0))  # the panic button
    keys.inject(mido.Message("control_change", channel=5, control=123, value=0))  # a channel holding nothing
    for n in (48, 52, 55):  # their note-offs after it: those notes already ended
        keys.inject(off(n, channel=3))
    inputs.poll(clock.now())
    assert len(session.world.sensors["panic"]) == 1  # channel 3's passed, channel 5's was throttled
    inputs.close()
    counted = counts(session)
    budget = int(session.inst.settings.midi.max_rate * BURST)
    assert counted["mapped midi"] == budget + 1  # 3 chord notes + 247 of the pad's, and the panic
    assert counted["throttled midi"] == 10_000 - (budget - 3) + 1 + 3
