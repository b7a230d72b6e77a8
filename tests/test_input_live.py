"""The input map on the live path: foreign OSC senders (python-osc's client in another
process, liblo's ``oscsend``) reaching ``creatures run`` on loopback; a rehearsal file offline
giving the same events as the same messages sent live; and a fuzz of random OSC packets and
MIDI bytes that never crashes the loop and leaves nothing uncounted."""

from __future__ import annotations

import json
import re
import shutil
import socket
import subprocess
import sys
import textwrap

import mido
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message_builder import OscMessageBuilder
from pythonosc.osc_packet import OscPacket
from pythonosc.udp_client import SimpleUDPClient

from input_fixtures import COLONY, all_read, live_run

from creatures.cli import main
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.input_sources import RETRY
from creatures.runtime.live import LiveInputs
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.osc import MAX_PACKET, check_wire
from midi.ports import MemoryInput, MemoryPorts
from midi.sinks import MemorySink

CREATURES = COLONY + '[audio]\noutput_device = "NoSuchCard"\n'

MAPS = """
[[input.map]]
osc = "/note"
to = "note"
velocity = {arg = 1, default = 100}
duration = {arg = 2, default = 0.25}

[[input.map]]
osc = "/reward"
to = "reward"
creatures = {arg = 0}
amount = {arg = 1, default = 1.0}

[[input.map]]
osc = "/light/*"
to = "sensor"
name = "light"

[[input.map]]
osc = "/bored"
to = "drive"
drive = "boredom"
set = {arg = 0}

[[input.map]]
midi = "cc"
to = "sensor"
name = "knob"
range = [0.0, 1.0]
"""


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def records(path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


SENDER = """
import sys
from pythonosc.udp_client import SimpleUDPClient
client = SimpleUDPClient("127.0.0.1", int(sys.argv[1]))
client.send_message("/note", [60.0, 90.0, 0.5])            # floats, as TouchDesigner sends them
client.send_message("/note", [61, 80])                    # ints, two arguments
client.send_message("/creature/visitor/note", [62.0, 100.0, 0.25])  # the shipped space, floats
client.send_message("/reward", ["bo", 1.0])
client.send_message("/light/left", [0.75])
client.send_message("/no/such/map", [1, "x", True])
client.send_message("/creature/visitor/note", [60.5, 100, 0.25])  # no such pitch: refused by the listener
"""


@pytest.mark.skipif(shutil.which("oscsend") is None, reason="liblo-tools (oscsend) is not installed")
def test_foreign_osc_senders_reach_a_live_run(tmp_path):
    port = free_port()
    config = tmp_path / "live.toml"
    config.write_text(CREATURES + f"[osc]\nport = {port}\n" + MAPS.replace("[[input.map]]", "[[input]]"))
    log = tmp_path / "events.jsonl"

    def send() -> None:
        subprocess.run([sys.executable, "-c", SENDER, str(port)], check=True, timeout=60)
        for args in (["/note", "iif", "64", "100", "0.3"], ["/reward", "sf", "deaf", "0.5"], ["/bored", "f", "1.5"]):
            subprocess.run(["oscsend", "127.0.0.1", str(port), *args], check=True, timeout=30)

    lines, out = live_run(config, log, port, send)
    events = records(log)
    heard = sorted((e["pitch"], e["velocity"], e["duration"], e["source"]) for e in events if e["kind"] == "heard")
    assert heard == [(60, 90, 0.5, "osc"), (61, 80, 0.25, "osc"), (62, 100, 0.25, "visitor"),
                     (64, 100, pytest.approx(0.3), "osc")]  # the shipped space's notes keep the sender's name
    placed = {e["creature"] for e in events if e["kind"] == "placed" and e["source"] == "input"}
    assert placed == {"bo"}  # hears_input = false holds for OSC notes too, the shipped space's included
    assert [(e["creature"], e["amount"]) for e in events if e["kind"] == "reward"] == [("bo", 1.0), ("deaf", 0.5)]
    assert [e["value"] for e in events if e["kind"] == "sensor"] == [0.75]
    assert [(e["creature"], e["level"]) for e in events if e["kind"] == "drive"] == [("bo", 1.5), ("deaf", 1.5)]
    counts = [e for e in events if e["kind"] == "inputs"][-1]
    assert counts["unmapped osc"] == 2 and counts["mapped osc"] == 7 and "malformed" not in counts
    assert counts["refused osc"] == 1
    assert "outside input: 7 mapped, 2 unmapped, 0 malformed, 0 throttled, 1 refused osc" in out
    assert any("/no/such/map" in line and "unmapped" in line for line in lines + out.splitlines())


@pytest.mark.skipif(shutil.which("oscsend") is None, reason="liblo-tools (oscsend) is not installed")
def test_two_thousand_distinct_unmapped_addresses_make_at_most_two_lines_and_are_all_counted(tmp_path):
    """2,000 packets ``/probe/<i>`` made 1,023 lines in under a second (one per address, up to
    1,024): unmapped is one cause, logged at most every 10 s with a count and a few addresses."""
    port = free_port()
    config = tmp_path / "live.toml"
    config.write_text(CREATURES + f"[osc]\nport = {port}\n" + MAPS.replace("[[input.map]]", "[[input]]"))
    log = tmp_path / "events.jsonl"

    def send() -> None:
        client = SimpleUDPClient("127.0.0.1", port)
        for i in range(2000):
            client.send_message(f"/probe/{i}", [i])
            if i % 250 == 249:  # no more than a receive buffer holds at once: none dropped
                all_read(port)

    lines, out = live_run(config, log, port, send)
    printed = [line for line in lines + out.splitlines() if "unmapped" in line and "outside input:" not in line]
    assert len(printed) <= 2, printed
    counts = [e for e in records(log) if e["kind"] == "inputs"][-1]
    assert counts["unmapped osc"] == 2001  # and /done
    assert "outside input: 0 mapped, 2001 unmapped" in out
    assert len([e for e in records(log) if e["kind"] == "unmapped"]) <= 2


# -- rehearsal: the same events offline and live ------------------------------------------------
REHEARSAL = """\
time,address,args
0.5,/note,60,90,0.5
1.0,/light/a,0.2
1.5,/reward,bo,2.0
2.0,/note,C5
2.5,/bored,1.0
3.0,/light/b,0.9
3.5,/reward,deaf
4.0,/unknown,1
4.5,midi,176,7,127
"""

COMPARED = ("heard", "sensor", "reward", "drive", "unmapped", "placed", "selection")


def rounded(v):
    """OSC carries 32-bit floats (0.2 arrives as 0.2000000029…): compare to 6 digits."""
    if isinstance(v, float):
        return round(v, 6)
    if isinstance(v, dict):
        return {k: rounded(x) for k, x in v.items()}
    return [rounded(x) for x in v] if isinstance(v, list) else v


def same(events: list[dict]) -> list[tuple]:
    """The events the input map causes (and the creatures' answers), without the source's name or place."""
    return [(e["kind"], round(e["t"], 6), *sorted((k, json.dumps(rounded(v))) for k, v in e.items()
                                                   if k not in ("t", "kind", "via", "source", "time", "at")))
            for e in events if e["kind"] in COMPARED]


def test_a_rehearsal_offline_gives_the_events_of_the_same_messages_live(tmp_path):
    (tmp_path / "rehearsal.csv").write_text(REHEARSAL)
    base = CREATURES + '[output]\nwav = false\nmidi = false\nreport = false\n[input]\ngenerate = "none"\n' + MAPS
    offline = tmp_path / "offline.toml"
    offline.write_text(base + '[[input.map]]\nfile = "rehearsal.csv"\n')
    run_offline(load_installation(offline), tmp_path / "out", duration=5.0)
    rehearsed = records(tmp_path / "out" / "events.jsonl")

    port = free_port()
    live = tmp_path / "live.toml"
    live.write_text(base.replace("[input]", f"[osc]\nport = {port}\n[input]") + '[midi]\ninput_port = "knobs"\n')
    inst = load_installation(live)
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(), MemorySink())
    knobs = MemoryInput("knobs")
    inputs = LiveInputs(inst, session, clock, say=lambda m: None, ports=MemoryPorts(knobs))
    client = SimpleUDPClient("127.0.0.1", port)
    rows = [line.split(",") for line in REHEARSAL.splitlines()[1:]]
    from creatures.runtime.input_sources import value_of

    try:
        tick, sr = inst.settings.tick, inst.settings.audio.sample_rate
        for step in range(1, int(round(5.0 / tick)) + 1):
            t = step * tick
            clock.advance_to(t)
            while rows and float(rows[0][0]) <= t + 1e-9:  # sent live when the rehearsal plays it
                _, address, *args = rows.pop(0)
                if address == "midi":
                    knobs.inject(mido.Message.from_bytes([int(a) for a in args]))
                else:
                    client.send_message(address, [value_of(a) for a in args])
                    assert inputs.network.listener.wait(10.0)
            inputs.poll(t)
            session.step(t, int(round(t * sr)) - int(round((t - tick) * sr)), None, audio=False)
    finally:
        session.close()
        inputs.close()
    assert same(session.log.records) == same(rehearsed)
    kinds = {e["kind"] for e in rehearsed}
    assert {"heard", "sensor", "reward", "drive", "unmapped"} <= kinds
    assert [e["value"] for e in rehearsed if e["kind"] == "sensor"] == [0.2, 0.9, 1.0]  # the knob: cc 127


def test_rehearsal_rows_past_an_offline_run_are_said_not_dropped_in_silence(tmp_path):
    (tmp_path / "long.csv").write_text("time,address,args\n" + "".join(f"{t},/light/x,0.5\n" for t in (0.5, 1.0, 3.0, 9.5)))
    config = tmp_path / "c.toml"
    config.write_text(CREATURES + '[output]\nwav = false\nmidi = false\nreport = false\n[input]\ngenerate = "none"\n'
                      + MAPS + '[[input.map]]\nfile = "long.csv"\n')
    summary = run_offline(load_installation(config), tmp_path / "out", duration=1.0, progress=False)
    assert [e["value"] for e in records(tmp_path / "out" / "events.jsonl") if e["kind"] == "sensor"] == [0.5, 0.5]
    assert any("long.csv: 2 of its 4 rows fall past the run's 1 s (the last at 9.5 s)" in m for m in summary.messages)


@pytest.mark.parametrize("text", ["", "time,address,args\n", "# exported 2026-12-07\n\n"])
def test_a_rehearsal_file_of_no_rows_is_said_at_its_key(tmp_path, text):
    """An export that wrote only its header (or nothing) played nothing, and nothing said so."""
    (tmp_path / "walk.csv").write_text(text)
    config = tmp_path / "c.toml"
    config.write_text(CREATURES + '[output]\nwav = false\nmidi = false\nreport = false\n[input]\ngenerate = "none"\n'
                      + MAPS + '[[input.map]]\nfile = "walk.csv"\n')
    inst = load_installation(config)
    said = [note for note in inst.notes if "walk.csv holds no rows" in note]
    assert len(said) == 1 and re.match(rf"{re.escape(str(config))}:\d+: input\.map\.\d+\.file: ", said[0]), inst.notes


def test_a_rehearsal_row_no_map_can_read_is_said_at_its_line(tmp_path):
    """A tracker's export with a lost reading (``nan``), a decimal comma or a slip of an address
    plays on, each row counted; what was said named the address and why, not where: in a file
    of a hundred ``/light/x`` rows the author hunted for the one."""
    rows = ["0.1,/light/x,0.5", "0.2,/light/x,nan", "0.3,/light/x,0.6", "0.4,/ligth/x,0.5", "0.5,midi,300"]
    (tmp_path / "walk.csv").write_text("time,address,args\n" + "".join(f"{row}\n" for row in rows))
    config = tmp_path / "c.toml"
    config.write_text(CREATURES + '[output]\nwav = false\nmidi = false\nreport = false\n[input]\ngenerate = "none"\n'
                      + MAPS + '[[input.map]]\nfile = "walk.csv"\n')
    summary = run_offline(load_installation(config), tmp_path / "out", duration=1.0, progress=False)
    assert [e["value"] for e in records(tmp_path / "out" / "events.jsonl") if e["kind"] == "sensor"] == [0.5, 0.6]
    said = "\n".join(summary.messages)
    assert "'/light/x' malformed (value: nan is not a finite number within ±1e+06, at walk.csv:3)" in said
    assert "'/ligth/x' unmapped (no [[input]] map takes it, at walk.csv:5)" in said
    assert "e.g. 'midi' (last: not one MIDI message (invalid status byte 300), at walk.csv:6)" in said


def test_rehearsal_rows_a_live_run_never_reached_are_counted_when_it_stops(tmp_path, capsys):
    (tmp_path / "long.csv").write_text("time,address,args\n" + "".join(f"{t},/light/x,0.5\n" for t in (0.05, 0.2, 30, 95.5)))
    config = tmp_path / "c.toml"
    config.write_text(CREATURES + MAPS + '[[input.map]]\nfile = "long.csv"\n')
    log = tmp_path / "events.jsonl"
    assert main(["run", str(config), "--duration", "0.3", "--log", str(log)]) == 0
    said = re.search(r"long\.csv: 2 of its 4 rows were not played: the run stopped ([\d.]+) s into them, before "
                     r"the row at 30\.0 s \(the last at 95\.5 s\)", capsys.readouterr().out)
    assert said and 0.3 <= float(said.group(1)) < 30
    events = records(log)
    assert [e["value"] for e in events if e["kind"] == "sensor"] == [0.5, 0.5]
    assert [(e["file"], e["rows"], e["of"]) for e in events if e["kind"] == "unplayed"] == [("long.csv", 2, 4)]


# -- fuzz ---------------------------------------------------------------------------------------
ADDRESSES = ["/note", "/reward", "/light/x", "/bored", "/creature/x/note", "/creature/x/hello", "/creature/bo/state",
             "/other", "/light"]
ARGS = st.lists(st.one_of(st.integers(-2**31, 2**31 - 1), st.floats(allow_nan=True, allow_infinity=True, width=32),
                          st.text(st.characters(blacklist_characters="\x00"), max_size=12), st.booleans(), st.binary(min_size=1, max_size=8)), max_size=5)


@st.composite
def osc_packets(draw) -> bytes:
    def message():
        address = draw(st.one_of(st.sampled_from(ADDRESSES), st.text(st.characters(min_codepoint=33, max_codepoint=126), min_size=1,
                                                                      max_size=20).map(lambda s: "/" + s)))
        builder = OscMessageBuilder(address)
        for arg in draw(ARGS):
            builder.add_arg(arg)
        return builder.build()

    kind = draw(st.sampled_from(["message", "bundle", "bytes", "mangled"]))
    if kind == "bytes":
        return draw(st.binary(max_size=MAX_PACKET + 40))
    if kind == "bundle":
        bundle = OscBundleBuilder(IMMEDIATELY)
        for _ in range(draw(st.integers(1, 4))):
            bundle.add_content(message())
        return bundle.build().dgram
    data = message().dgram
    if kind == "mangled":  # a real message cut or flipped somewhere
        cut = draw(st.integers(0, len(data)))
        data = data[:cut] + draw(st.binary(max_size=8))
    return data


def expected(packet: bytes) -> int:
    """How many counts a packet must add: one per message, or one for the packet itself (too
    large, not OSC, or refused whole at the door by :func:`midi.osc.check_wire`)."""
    if len(packet) > MAX_PACKET:
        return 1
    try:
        check_wire(packet, elsewhere=True)
        return len(OscPacket(packet).messages)
    except Exception:
        return 1


@pytest.fixture(scope="module")
def fuzzed(tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzz") / "fuzz.toml"
    path.write_text(CREATURES + f"[osc]\nport = {free_port()}\n[midi]\ninput_port = \"fuzz\"\n"
                    + MAPS.replace("[[input.map]]", "[[input]]") + textwrap.dedent("""
                        [[input]]
                        midi = "note"
                        note = 36
                        to = "reward"
                        [[input]]
                        midi = "pitchbend"
                        to = "drive"
                        drive = "hunger"
                        amount = {arg = 0}
                        """))
    inst = load_installation(path)
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(keep_in_memory=100), MemorySink())
    keyboard = MemoryInput("fuzz")
    inputs = LiveInputs(inst, session, clock, say=lambda m: None, ports=MemoryPorts(keyboard))
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    yield session, inputs, keyboard, sender, clock
    sender.close()
    inputs.close()


def counted(session: Session, inputs: LiveInputs) -> int:
    ear, counts = inputs.network.listener, session.inputs.counts
    return (ear.received + ear.malformed + ear.oversize
            + sum(counts[f"{what} {via}"] for what in ("mapped", "unmapped", "malformed", "throttled")
                  for via in ("osc", "midi")))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(packets=st.lists(osc_packets(), max_size=6), midi=st.binary(max_size=48), chunk=st.binary(max_size=4))
def test_fuzz_random_osc_and_midi_never_crash_the_loop_and_all_is_counted(fuzzed, packets, midi, chunk):
    session, inputs, keyboard, sender, clock = fuzzed
    before = counted(session, inputs)
    for packet in packets:
        sender.sendto(packet, ("127.0.0.1", inputs.network.listener.port))
    parser = mido.Parser()
    parser.feed(midi)
    messages = list(parser)
    for msg in messages:
        keyboard.inject(msg)
    if packets:
        assert inputs.network.listener.wait(10.0)
    t = clock.now() + 0.02
    clock.advance_to(t)
    inputs.poll(t)
    session.inputs.midi_bytes(chunk, t, "midi")  # raw bytes: one message, or malformed
    session.step(t, 441, None, audio=False)  # the creatures take whatever it became
    assert counted(session, inputs) - before == sum(expected(p) for p in packets) + len(messages) + 1


def test_numbers_beyond_their_bounds_sent_live_are_counted_and_the_colony_still_saves(tmp_path):
    """``/reward bo 1e308`` over UDP once crashed ``creatures run`` (a traceback, exit 1):
    through the live listener, each number beyond its bound is counted malformed, and the
    creatures still tick and save."""
    path = tmp_path / "live.toml"
    path.write_text(CREATURES + f"[osc]\nport = {free_port()}\n" + MAPS.replace("[[input.map]]", "[[input]]"))
    inst = load_installation(path)
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(), MemorySink())
    inputs = LiveInputs(inst, session, clock, say=lambda m: None)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for address, args in (("/reward", ["bo", 1e308]), ("/light/a", [1e308]), ("/bored", [-1e308]),
                              ("/reward", ["bo", 1.0])):
            message = OscMessageBuilder(address)
            for arg in args:  # 64-bit doubles ('d', as `oscsend ... sd bo 1e308` sends them)
                message.add_arg(arg, "s" if isinstance(arg, str) else "d")
            sender.sendto(message.build().dgram, ("127.0.0.1", inputs.network.listener.port))
        assert inputs.network.listener.wait(10.0)
        ticks = session.ticks
        for step in range(1, 101):
            t = step * 0.02
            clock.advance_to(t)
            inputs.poll(t)
            session.step(t, 441, None, audio=False)
        counts = session.inputs.counts
        assert counts["malformed osc"] == 3 and counts["mapped osc"] == 1, counts
        assert session.ticks > ticks
        session.save_state(tmp_path / "state")
        assert (tmp_path / "state" / "bo.json").is_file()
    finally:
        sender.close()
        inputs.close()


def test_maps_no_port_can_reach_are_reported_at_start(tmp_path):
    config = tmp_path / "c.toml"
    config.write_text(CREATURES + MAPS)
    inst = load_installation(config)
    clock = SimulatedClock()
    said: list[str] = []
    LiveInputs(inst, Session(inst, clock, EventLog(), MemorySink()), clock, said.append).close()
    assert said == ["[[input]] maps OSC messages but [osc] port is not set: nothing will reach them",
                    "[[input]] maps MIDI messages but [midi] input_port is not set: nothing will reach them"]


def test_a_serial_device_missing_and_back_is_in_the_events_log(tmp_path):
    """As the MIDI port's going and coming are (``device`` events): a weekend's log said when
    the synth went, but of the sensors' Arduino only the terminal knew."""
    import os
    import pty

    master, slave = pty.openpty()
    device = tmp_path / "ttyUSB0"
    config = tmp_path / "c.toml"
    config.write_text(CREATURES + MAPS + f'\n[[input.map]]\nserial = "{device}"\n')
    inst = load_installation(config)
    clock = SimulatedClock()
    said: list[str] = []
    session = Session(inst, clock, EventLog(), MemorySink())
    inputs = LiveInputs(inst, session, clock, said.append)
    try:
        inputs.poll(0.0)
        device.symlink_to(os.ttyname(slave))  # plugged in
        clock.advance_to(RETRY)
        inputs.poll(RETRY)
    finally:
        inputs.close()
        os.close(master)
        os.close(slave)
    logged = [e["message"] for e in session.log.records if e["kind"] == "device"]
    assert len(logged) == 2 and "unavailable" in logged[0] and "connected" in logged[1]
    assert logged == said[-2:]
