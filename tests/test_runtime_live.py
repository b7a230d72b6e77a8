"""Live runs without devices keep going, say which device is missing and how to list
devices, save state on exit (also on SIGTERM) and resume from it."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time

import mido
import numpy as np
import pytest

from audio.device import device_rate
from creatures.body.frames import FrameClock
from creatures.cli import main
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime import live
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.ports import MemoryInput, MemoryOutput, MemoryPorts
from midi.sinks import MemorySink

CONFIG = """
title = "live check"
tick = 0.02
[audio]
output_device = "NoSuchCard"
[midi]
output_port = "NoSuchSynth"
[[creature]]
name = "ada"
kind = "exchange"
"""


def test_absent_devices_are_named_and_the_run_goes_on(tmp_path, capsys):
    config = tmp_path / "live.toml"
    config.write_text(CONFIG)
    state = tmp_path / "state"
    assert main(["run", str(config), "--duration", "0.3", "--state", str(state)]) == 0
    out = capsys.readouterr().out
    assert "MIDI output" in out and "NoSuchSynth" in out and "creatures devices" in out
    assert "audio output NoSuchCard unavailable" in out
    assert "0 audio underruns, 0 input overruns" in out
    assert (state / "ada.json").is_file()
    assert main(["run", str(config), "--duration", "0.2", "--state", str(state)]) == 0
    assert "restored ada" in capsys.readouterr().out


def test_sigterm_stops_cleanly_and_saves_state(tmp_path):
    config = tmp_path / "live.toml"
    config.write_text(CONFIG)
    state = tmp_path / "state"
    process = subprocess.Popen(
        [sys.executable, "-m", "creatures.cli", "run", str(config), "--state", str(state)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        for line in process.stdout:  # wait until the loop is running
            if "running; Ctrl-C or SIGTERM" in line:
                break
        process.send_signal(signal.SIGTERM)
        rest = process.communicate(timeout=60)[0]
    finally:
        process.kill()
    assert process.returncode == 0, rest
    assert "stopped after" in rest
    assert (state / "ada.json").is_file()


def test_bad_state_file_is_a_clear_error(tmp_path, capsys):
    config = tmp_path / "live.toml"
    config.write_text(CONFIG)
    state = tmp_path / "state"
    state.mkdir()
    (state / "ada.json").write_text("{not json")
    assert main(["run", str(config), "--duration", "0.1", "--state", str(state)]) == 2
    assert "ada.json:1: malformed JSON" in capsys.readouterr().err


def test_live_frames_follow_their_own_clock(tmp_path, capsys):
    config = tmp_path / "live.toml"
    config.write_text(CONFIG.replace("[midi]", "[output]\nfps = 10\n[midi]"))
    pictures = tmp_path / "pictures"
    began = time.monotonic()
    assert main(["run", str(config), "--duration", "1.0", "--frames", str(pictures)]) == 0
    elapsed = time.monotonic() - began  # the frames' clock runs inside this span
    out = capsys.readouterr().out
    if "no frames:" in out:
        pytest.skip(out.split("no frames:", 1)[1].splitlines()[0])
    count = len(list((pictures / "frames").glob("frame_*.png")))
    # 10 fps of wall time, whatever the tick rate: at least the 1 s run, at most the whole call
    assert 8 <= count <= math.floor(10 * elapsed) + 1, (count, elapsed)


def test_frames_skipped_over_a_clock_gap_are_in_the_summary(tmp_path, monkeypatch, capsys):
    class Pictures:
        """Live frames whose clock leaps an hour after the first (the machine suspended)."""

        def __init__(self, output, out, clock, messages) -> None:
            self.leaping = SimulatedClock()
            self.clock = FrameClock(output.fps, self.leaping)
            self.dropped = 0

        def draw(self, creatures) -> None:
            self.clock.due()
            self.leaping.advance_to(3600.0)

        def close(self) -> None:
            pass

    monkeypatch.setattr(live, "FramesBeside", Pictures)
    config = tmp_path / "live.toml"
    config.write_text(CONFIG.replace("[midi]", "[output]\nfps = 10\n[midi]"))
    assert main(["run", str(config), "--duration", "0.2", "--frames", str(tmp_path / "pictures")]) == 0
    # the hour's 36,000 frames but the one drawn when the clock came back
    assert "35999 frames skipped over clock gaps" in capsys.readouterr().out


def test_live_midi_notes_are_heard_when_the_key_goes_down(tmp_path):
    keyboard = MemoryInput("Test Keyboard")
    config = tmp_path / "live.toml"
    deaf = '[[creature]]\nname = "bo"\nkind = "exchange"\nchannel = 1\nhears_input = false\n'
    config.write_text(CONFIG.replace('output_port = "NoSuchSynth"', 'input_port = "keyboard"') + deaf)
    inst = load_installation(config)
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(), MemorySink())
    inputs = live.LiveInputs(inst, session, clock, say=lambda message: None, ports=MemoryPorts(keyboard))
    keyboard.inject(mido.Message("note_on", note=64, velocity=90))
    keyboard.inject(mido.Message("note_on", note=64, velocity=0))  # its release: not a new note
    clock.advance(0.5)
    assert inputs.poll(clock.now()) == 1
    assert session.world.deliver(clock.now()) == 1
    heard = [e for e in session.log.records if e["kind"] == "heard"]
    assert [(e["pitch"], e["velocity"], e["time"], e["source"]) for e in heard] == [(64, 90, 0.5, "midi")]
    # A keyboard is input like a file: only creatures that hear the input take the note.
    placed = [(e["creature"], e["source"]) for e in session.log.records if e["kind"] == "placed"]
    assert placed == [("ada", "input")]


def test_audio_underruns_and_input_overruns_are_counted_logged_and_reported(tmp_path, monkeypatch, capsys):
    class Loudspeaker:
        """A device whose callback never finds the next block in time."""

        def __init__(self, sample_rate: int, channels: int, **kwargs: object) -> None:
            self.underruns = 0
            self.gaps, self.skips = 1, 0  # its start

        def describe(self) -> str:
            return "live at 22050 Hz"

        def write(self, block: object) -> None:
            self.underruns += 1

        def close(self) -> None:
            pass

    class Microphone:
        """A microphone read too slowly: a block was lost before every read."""

        def __init__(self, device: str, **kwargs: object) -> None:
            self.overruns = self.driver_overflows = 0

        def read(self) -> None:
            self.overruns += 1
            return None

        def stop(self) -> None:
            pass

    monkeypatch.setattr(live, "ResilientOutput", Loudspeaker)
    monkeypatch.setattr(live, "ResilientInput", Microphone)
    config = tmp_path / "live.toml"
    config.write_text(CONFIG.replace('output_device = "NoSuchCard"', 'input_device = "mic"'))
    log = tmp_path / "events.jsonl"
    assert main(["run", str(config), "--duration", "0.3", "--log", str(log)]) == 0
    summary = re.search(r"(\d+) ticks, .* (\d+) audio underruns, (\d+) input overruns", capsys.readouterr().out)
    ticks, underruns, overruns = map(int, summary.groups())
    # the microphone is read at every look between ticks too (its notes are heard at once:
    # creatures/runtime/microphone_notes.py), so a block is lost at least once a tick
    assert ticks >= 5 and underruns == ticks and overruns > ticks
    xruns = [e for e in map(json.loads, log.read_text().splitlines()) if e["kind"] == "xruns"]
    assert len(xruns) >= 2  # logged while running (when they change) and at the end
    assert [xruns[-1][k] for k in ("underruns", "overruns", "gaps", "skips")] == [ticks, overruns, 1, 0]


@pytest.mark.jack
def test_live_sound_reaches_a_jack_device_at_its_own_rate(tmp_path):
    rate = device_rate(None, kind="output")
    if rate is None:
        pytest.skip("no audio output device (start: jackd --no-realtime -d dummy -r 44100 -p 512)")
    config = tmp_path / "live.toml"
    config.write_text('title = "jack"\n[audio]\nsample_rate = 22050\n[[creature]]\nname = "ada"\nkind = "exchange"\n')
    summary = live.run_live(load_installation(config), duration=0.5, say=lambda message: None)
    expected = f"live at {rate} Hz" + (" (resampled from 22050 Hz)" if rate != 22050 else "")
    assert summary.sound == expected
    assert summary.ticks >= 20


# -- nothing slow on the creature's thread (issue 14) -----------------------------------------
class SlowSynthPorts:
    """A MIDI output backend whose listing takes 2 s (JACK's took ~2.5 s under load), with one
    synth port that refuses one send mid-run (the signal to look again). Records when each
    listing ran, on which thread."""

    LISTING = 2.0

    def __init__(self) -> None:
        self.listings: list[tuple[float, float, str]] = []  # (began, ended, thread) in monotonic time
        self.fail_next = 0
        self.sent: list[mido.Message] = []
        self.opened = 0

    def _send(self, msg: mido.Message) -> None:
        if self.fail_next:
            self.fail_next -= 1
            raise OSError("JACK client zombified")
        self.sent.append(msg)

    def names(self) -> list[str]:
        began = time.monotonic()
        time.sleep(self.LISTING)
        self.listings.append((began, time.monotonic(), threading.current_thread().name))
        return ["Slow Synth"]

    def open(self, name: str, *, virtual: bool = False) -> MemoryOutput:
        self.opened += 1
        synth = MemoryOutput(name)
        synth._send = self._send
        return synth


@pytest.mark.realtime  # alone: it times a live loop in real time, which a busy neighbour test delays
def test_a_port_listing_of_two_seconds_delays_its_ticks_no_more_than_the_machine_does(tmp_path, monkeypatch):
    """The stall of issue 14, with a fake backend: presence checks list the ports every second
    and a send fails mid-run, yet a 2 s listing delays its ticks no more than the machine's
    load does: the ticks whose grid time fell inside a listing are, all but two spikes (see
    below), at worst 5 ms later than the worst of the others, and nine in ten of them begin
    within 5 ms of their grid time. Wall-clock timing, as the issue demands; the loop's own
    lateness is what is measured (the run's ticks are light: one creature, audio off)."""
    ports = SlowSynthPorts()
    keyboard = MemoryInput("keys")
    monkeypatch.setattr(live, "MidoOutputs", lambda: ports)
    monkeypatch.setattr(live, "MidoInputs", lambda: MemoryPorts(keyboard))
    config = tmp_path / "live.toml"
    config.write_text(CONFIG.replace('output_device = "NoSuchCard"', "output = false")
                      .replace("NoSuchSynth", "Slow Synth").replace("[midi]", '[midi]\ninput_port = "keys"')
                      + "space.answer = 1.0\n")  # ada strikes every note she hears, at once
    inst = load_installation(config)
    grid: list[tuple[float, float]] = []  # (grid time, lateness) on the loop's own clock
    real_add = live.TickTiming.add

    def add(self, lateness: float) -> None:
        grid.append((time.monotonic(), lateness))
        real_add(self, lateness)
        if len(grid) == 60:  # a key goes down; ada's answer is the send that fails
            ports.fail_next = 1
            keyboard.inject(mido.Message("note_on", note=64, velocity=90))

    monkeypatch.setattr(live.TickTiming, "add", add)
    said: list[str] = []
    summary = live.run_live(inst, duration=6.0, say=said.append)
    assert summary.sound == "off ([audio] output = false)" and summary.underruns == 0
    # The failed send dropped the port at once; the supervisor let it go and found it again.
    assert any("'Slow Synth' lost (JACK client zombified)" in m for m in said), said
    assert any("'Slow Synth' is back" in m for m in said) and ports.opened == 2, said
    on_loop = [(a, b) for a, b, thread in ports.listings if thread != "MainThread"]
    assert len(on_loop) >= 2, ports.listings  # listings ran during the run, all off the loop's thread
    assert all(thread != "MainThread" for _, _, thread in ports.listings[1:])  # the first: before the run
    inside = [any(a <= t - lateness <= b for a, b in on_loop) for t, lateness in grid]
    during = [lateness for (_, lateness), i in zip(grid, inside) if i]
    outside = [lateness for (_, lateness), i in zip(grid, inside) if not i] or [0.0]
    assert len(during) >= 50
    # A listing on the loop's thread would make a tick ~2 s late. The machine's own load (2
    # shared cores) can wake any tick a few ms late, listing or not: so a listing may add at
    # most 5 ms to the worst the other ticks saw, and nine in ten of its ticks are within 5 ms.
    # Two ticks are let off that bound (never by a tenth of a listing): listings fill two thirds
    # of the run, so a lone spike of the machine's lands inside one two times in three (CI,
    # 2026-12-03: one tick 50 ms late inside a listing, the worst outside 0.04 ms; here, under
    # 8 spinning processes at nice -20, a 21 ms spike fell outside the listings), and on a CI
    # run sharing its two cores with a training job (2026-12-06) a second tick inside was 5.3 ms
    # late. A listing on the loop's thread would make every tick inside it late, by seconds.
    *_, third, second, worst = sorted(during)
    assert third <= max(outside) + 0.005, (third, max(outside))
    assert second <= worst < SlowSynthPorts.LISTING / 10, (worst, max(outside))
    assert np.percentile(during, 90) <= 0.005, sorted(during)[-10:]
    assert ports.sent, "the synth heard the colony"


def test_an_unreachable_peer_host_is_one_message_naming_key_and_line_before_anything_runs(tmp_path, capsys):
    config = tmp_path / "live.toml"
    text = CONFIG + '[osc]\nport = 9000\npeers = [\n  "127.0.0.1:9001",\n  "nosuchhost.invalid:9002",\n]\n'
    config.write_text(text)
    state = tmp_path / "state"
    assert main(["run", str(config), "--duration", "5", "--state", str(state)]) == 2
    captured = capsys.readouterr()
    line = text.splitlines().index("peers = [") + 1  # the line of the key (TOML arrays keep no line per item)
    (message,) = captured.err.strip().splitlines()
    assert message.startswith(f"creatures: {config}:{line}: osc.peers.1: peer host of 'nosuchhost.invalid:9002' "
                              "cannot be resolved"), message
    assert "running" not in captured.out and not state.exists()  # nothing ran
    config.write_text(CONFIG + '[osc]\nport = 9000\npeers = ["127.0.0.1:99999"]\n')
    assert main(["run", str(config), "--duration", "5"]) == 2
    assert "osc.peers.0: peer '127.0.0.1:99999' is not host:port (port 99999 is out of range" in capsys.readouterr().err


def test_osc_notes_go_out_time_tagged_with_when_they_sound(tmp_path):
    from pythonosc.osc_packet import OscPacket

    from creatures.runtime.network import Network
    from midi.notes import NoteEvent

    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("127.0.0.1", 0))
    listener.settimeout(5.0)
    config = tmp_path / "live.toml"
    config.write_text(CONFIG + f'[osc]\npeers = ["127.0.0.1:{listener.getsockname()[1]}"]\n')
    inst = load_installation(config)  # no port of its own: the network listens on any free one
    clock = SimulatedClock(100.0)
    session = Session(inst, clock, EventLog(), MemorySink())
    network = Network(inst.settings.osc, session.world, clock, lambda m: None, epoch=1_800_000_000.0)
    try:
        session.world.play(session.creatures[0], NoteEvent(100.25, 62, 90, 0, 0.5))  # sounds in 250 ms
        packet = OscPacket(listener.recv(1024))
    finally:
        network.close()
        listener.close()
    (timed,) = packet.messages
    assert timed.message.address == "/creature/ada/note" and timed.message.params[:2] == [62, 90]
    assert timed.time == pytest.approx(1_800_000_000.0 + 100.25, abs=1e-3)


class LossyKeyboard(MemoryInput):
    """A keyboard read as a polled RtMidi input is (midi/polled.py): its first poll found the
    driver's queue full and two bytes that belonged to no message."""

    full_queues = 0
    malformed_bytes = 0

    def _receive(self, block: bool = True) -> None:
        self.full_queues, self.malformed_bytes = 1, 2


def test_what_the_midi_input_lost_is_counted_logged_and_reported(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(live, "MidoInputs", lambda: MemoryPorts(LossyKeyboard("keys")))
    config = tmp_path / "live.toml"
    config.write_text(CONFIG.replace('output_device = "NoSuchCard"', "output = false")
                      .replace("[midi]", '[midi]\ninput_port = "keys"'))
    log = tmp_path / "events.jsonl"
    assert main(["run", str(config), "--duration", "0.3", "--log", str(log)]) == 0
    out = capsys.readouterr().out
    assert "2 refused midi bytes; the MIDI input's queue was full at 1 polls: messages may have been lost" in out
    counts = [e for e in map(json.loads, log.read_text().splitlines()) if e["kind"] == "inputs"][-1]
    assert counts["refused midi bytes"] == 2 and counts["full midi queue"] == 1
