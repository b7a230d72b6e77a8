"""Fault injection into running colonies: one test per fault a gallery meets in weeks of
unattended running. Each injects a counted number of faults, checks the counters agree, and
checks that nothing the creatures know was lost (often: the run is identical to one without
the fault)."""

from __future__ import annotations

import errno
import hashlib
import io
import json
import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import mido
import numpy as np
import pytest
from pythonosc.osc_message_builder import OscMessageBuilder

from audio.output import WavOutput
from audio.sources import LiveInput
from creatures.clock import SimulatedClock
from creatures.cli import main
from creatures.events import EventLog, read_events
from creatures.persist import load_json, save_json
from creatures.runtime import live
from creatures.runtime.inputs import phrase_notes, render_notes
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.session import STATE_KIND, Session
from midi.osc import MAX_PACKET, OscSender
from midi.notes import NoteEvent
from midi.ports import ResilientPort
from midi.sinks import MemorySink, PortSink
from test_midi_ports import FakeBackend

COLONY = """
title = "faults"
seed = 5
tick = 0.02
[audio]
sample_rate = 22050
[output]
report = false
[midi]
input_port = "Fake Keys"
output_port = "Fake Synth"
[[creature]]
name = "ada"
kind = "exchange"
[[creature]]
name = "bo"
kind = "exchange"
channel = 1
"""


@pytest.fixture
def colony(tmp_path):
    path = tmp_path / "colony.toml"
    path.write_text(COLONY)
    return load_installation(path)


def _heard(log: EventLog, source: str) -> list[tuple[float, int]]:
    return [(e["time"], e["pitch"]) for e in log.records if e["kind"] == "heard" and e["source"] == source]


class CountingPortSink(PortSink):
    """A port sink that also counts what the scheduler handed it."""

    def __init__(self, port: ResilientPort) -> None:
        super().__init__(port)
        self.sends = 0

    def send(self, time: float, msg: mido.Message) -> None:
        self.sends += 1
        super().send(time, msg)


# -- MIDI devices ----------------------------------------------------------------------------
def _midi_run(inst, monkeypatch, *, unplug: bool):
    """15 simulated s: a keyboard plays a note every 0.5 s except 5–11 s; with ``unplug`` both
    the keyboard and the synth vanish at 5 s and return at 10 s."""
    keys, synth = FakeBackend("Fake Keys 20:0"), FakeBackend("Fake Synth 21:0")
    monkeypatch.setattr(live, "MidoInputs", lambda: keys)
    clock, log, reports = SimulatedClock(), EventLog(), []
    sink = CountingPortSink(ResilientPort(inst.settings.midi.output_port, synth, clock, report=reports.append))
    session = Session(inst, clock, log, sink)
    inputs = live.LiveInputs(inst, session, clock, reports.append)
    played, at_return = [], None
    for step in range(1, 751):
        t = round(step * 0.02, 6)
        clock.advance_to(t)
        if unplug and t in (5.0, 10.0):
            keys.present = synth.present = t == 10.0
            at_return = len(synth.sent)
        if not 5.0 <= t < 11.0 and step % 25 == 5:  # on at x.1 and x.6 s
            played.append(48 + step % 24)
            keys.queued.append(mido.Message("note_on", note=played[-1], velocity=80))
        elif not 5.0 <= t < 11.0 and step % 25 == 15:  # off 0.2 s later
            keys.queued.append(mido.Message("note_off", note=played[-1]))
        inputs.poll(t)
        session.step(t, 0, None, audio=False)
    return session, log, inputs.midi, sink, synth.sent[at_return:] if at_return is not None else [], played, reports


def test_midi_devices_vanish_and_return_inside_a_running_session(colony, monkeypatch):
    session, log, keys_port, sink, after_return, played, reports = _midi_run(colony, monkeypatch, unplug=True)
    out_port = sink.port

    assert session.ticks == 750  # the loop never stopped
    assert (keys_port.faults, keys_port.reopened) == (1, 1)
    assert (out_port.faults, out_port.reopened) == (1, 1)
    assert sum("lost" in r for r in reports) == 2 and sum("is back" in r for r in reports) == 2
    # The keyboard's loss and return are in the events log too, when they happened (a weekend's log shows them).
    device = [(e["t"], e["message"]) for e in log.records if e["kind"] == "device"]
    assert [t for t, _ in device] == [5.0, 10.0] and "lost" in device[0][1] and "is back" in device[1][1]
    # Every message the colony sent either reached the synth or was dropped and counted.
    assert out_port.dropped > 0
    assert sink.port.factory.opened == 2 and len(sink.port.factory.sent) + out_port.dropped == sink.sends
    assert any(m.type == "note_on" for m in after_return)  # the synth plays again once it is back
    # Every note played on the keyboard before and after the gap was heard, in order.
    heard = _heard(log, "midi")
    assert [p for _, p in heard] == played
    assert sum(t > 11.0 for t, _ in heard) == 8

    # Nothing the creatures know was lost: the run is event for event the one without faults
    # (but for the device events that say there was one).
    clean, clean_log, *_ = _midi_run(colony, monkeypatch, unplug=False)
    assert [e for e in log.records if e["kind"] != "device"] == clean_log.records
    assert [c.state() for c in session.creatures] == [c.state() for c in clean.creatures]


# -- audio input -----------------------------------------------------------------------------
def test_nan_silence_and_clipping_from_the_microphone_into_a_running_creature(tmp_path):
    inst = load_installation(Path(__file__).parents[1] / "installations" / "soundcreatures.toml")
    sr, tick = inst.settings.audio.sample_rate, inst.settings.tick
    clock, log = SimulatedClock(), EventLog()
    session = Session(inst, clock, log, MemorySink())
    microphone = LiveInput(samplerate=sr, buffer_seconds=1.0)
    microphone.prepare(sr)  # a device at the analysis rate: no resampling, exact counts
    speech = render_notes(phrase_notes(start=0.2, gap=2.0), sr, 10.0)
    nan = clipped = 0
    frames_per_tick = int(round(tick * sr))
    for step in range(1, 501):
        t = round(step * tick, 6)
        clock.advance_to(t)
        block = speech[(step - 1) * frames_per_tick:step * frames_per_tick].copy()
        if 2.0 < t <= 3.0:  # a driver delivering garbage
            block[::2] = np.nan
            block[1::7] = np.inf
            nan += int((~np.isfinite(block)).sum())
        elif 3.0 < t <= 4.0:  # the cable pulled: digital silence
            block[:] = 0.0
        elif 4.0 < t <= 5.0:  # the gain knob turned up: hard clipping
            block = np.clip(block * 200.0, -1.0, 1.0).astype(np.float32)
            clipped += int(np.count_nonzero(np.abs(block) >= 0.999))
        microphone.callback(block[:, None], len(block), None, None)
        heard = microphone.read()
        assert np.isfinite(heard).all()
        mix = session.step(t, len(heard), heard)
        assert np.isfinite(mix).all() and np.abs(mix).max() < 10.0
    assert microphone.bad_samples == nan > 0
    assert microphone.clipped == clipped > 0
    assert microphone.overruns == 0 and session.ticks == 500
    assert any(e["kind"] == "sound" and e["t"] > 5.0 for e in log.records)  # still hearing after
    session.save_state(tmp_path)  # save_json refuses NaN: no garbage reached what it learnt
    session.load_state(tmp_path)


# -- OSC flood -------------------------------------------------------------------------------
def test_osc_flood_of_malformed_packets_at_a_running_listener(colony, rng):
    colony.settings.osc.port = 0  # any free port (configs must name one ≥ 1024)
    colony.settings.osc.max_rate = 1_000_000  # every packet read, so each is counted by cause
    # (at the default rate a burst this fast is partly left to the kernel: tests/test_osc_flood.py)
    colony.settings.midi.input_port = None
    clock, log = SimulatedClock(), EventLog()
    session = Session(colony, clock, log, MemorySink())
    inputs = live.LiveInputs(colony, session, clock, print)
    listener = inputs.network.listener
    assert listener.socket.getsockname()[0] == "127.0.0.1"  # loopback unless configured
    visitor = OscSender("visitor", peers={"colony": ("127.0.0.1", listener.port)})
    flood = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    target = ("127.0.0.1", listener.port)

    def bad(kind: str) -> bytes:
        if kind == "garbage":
            return b"\xff" + rng.bytes(int(rng.integers(1, 200)))
        if kind == "truncated":
            return b"/creature/x/note\x00\x00\x00\x00,iif\x00\x00\x00\x00\x00\x3c"
        builder = OscMessageBuilder("/creature/x/note" if kind == "bad args" else "/somewhere/else")
        builder.add_arg("sixty")
        return builder.build().dgram

    sent = {"garbage": 0, "truncated": 0, "bad args": 0, "wrong address": 0, "oversize": 0}
    good = []
    for step in range(1, 251):
        t = round(step * 0.02, 6)
        clock.advance_to(t)
        for _ in range(40):
            kind = list(sent)[int(rng.integers(len(sent)))]
            packet = rng.bytes(MAX_PACKET + 1 + int(rng.integers(1000))) if kind == "oversize" else bad(kind)
            flood.sendto(packet, target)
            sent[kind] += 1
        if step % 5 == 0:
            pitch = 50 + step % 30
            visitor.note(NoteEvent(0.0, pitch, 90, 0, 0.25))
            good.append(pitch)
        inputs.poll(t)
        session.step(t, 0, None, audio=False)
    inputs.close()
    flood.close()
    visitor.close()
    assert listener.oversize == sent["oversize"]
    assert listener.malformed == sum(sent.values()) - sent["oversize"] - sent["wrong address"]
    assert session.inputs.counts["unmapped osc"] == sent["wrong address"]  # outside /creature/: the input map's
    assert listener.received == len(good) == 50
    assert [p for _, p in _heard(log, "visitor")] == good
    assert session.ticks == 250


# -- full or read-only disk ------------------------------------------------------------------
def _colony_session(inst, seconds: float) -> Session:
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(), MemorySink())
    for note in phrase_notes(rng=session.input_rng):
        session.world.inject(note)
    for step in range(1, int(seconds / 0.02) + 1):
        clock.advance_to(step * 0.02)
        session.step(step * 0.02, 0, None, audio=False)
    return session


def _tree(directory: Path) -> dict[str, bytes | None]:
    """Everything under ``directory``, hidden files and empty directories too (None)."""
    return {str(p.relative_to(directory)): p.read_bytes() if p.is_file() else None
            for p in sorted(directory.rglob("*"))}


def _where(path, dir_fd: int | None = None) -> Path:
    """The absolute path a file call refers to (a name relative to ``dir_fd``, as
    shutil.rmtree passes, or an open file descriptor)."""
    if isinstance(path, int):
        return Path(os.readlink(f"/proc/self/fd/{path}"))
    base = os.readlink(f"/proc/self/fd/{dir_fd}") if dir_fd is not None else os.getcwd()
    return Path(os.path.abspath(os.path.join(base, os.fsdecode(path))))


class FillingFile:
    """A file on a disk with ``room`` bytes left: the write that would pass it writes what
    fits and fails with ENOSPC, as a full disk does, and so does every later write."""

    def __init__(self, handle, room: int, path: Path, failures: list[Path]) -> None:
        self.handle, self.room, self.path, self.failures = handle, room, path, failures

    def write(self, data):
        if len(data) > self.room:
            self.handle.write(data[: self.room])
            self.room = 0
            self.failures.append(self.path)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.room -= len(data)
        return self.handle.write(data)

    def __getattr__(self, name):
        return getattr(self.handle, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.handle.close()


def _fill_disk(monkeypatch, directory: Path, name: str, room: int) -> list[Path]:
    """From now on every file opened for writing (``open``, ``Path.open``, ``os.fdopen``)
    under ``directory`` whose name contains ``name`` fills the disk after ``room`` bytes.
    Returns the files whose writes failed, as they fail."""
    real_open, failures = io.open, []

    def open_(file, mode="r", *args, **kwargs):
        handle = real_open(file, mode, *args, **kwargs)
        path = _where(file)
        if set(mode) & set("wax+") and path.is_relative_to(directory) and name in path.name:
            return FillingFile(handle, room, path, failures)
        return handle

    monkeypatch.setattr(io, "open", open_)
    return failures


def _read_only(monkeypatch, directory: Path, code: int) -> list[Path]:
    """From now on ``directory`` behaves as read-only even for root (``code``: EROFS, a
    read-only mount, or EACCES, no write permission): every call that would create, write,
    rename or remove anything in it fails. Returns the refused paths, as they are refused."""
    refused: list[Path] = []

    def refuse(path: Path) -> None:
        if path.is_relative_to(directory):
            refused.append(path)
            raise OSError(code, os.strerror(code), str(path))

    def guard(real, *, arguments: int = 1, writes=lambda *a, **k: True):
        def call(*args, **kwargs):
            if writes(*args, **kwargs):
                for path in args[:arguments]:
                    refuse(_where(path, kwargs.get("dir_fd")))
            return real(*args, **kwargs)
        return call

    changing = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND
    monkeypatch.setattr(os, "open", guard(os.open, writes=lambda path, flags, *a, **k: flags & changing))
    monkeypatch.setattr(io, "open", guard(io.open, writes=lambda file, mode="r", *a, **k: set(mode) & set("wax+")))
    # mkdir of what exists fails with EEXIST first, on a read-only mount too
    monkeypatch.setattr(os, "mkdir", guard(os.mkdir, writes=lambda path, *a, **k: not _where(path, k.get("dir_fd"))
                                           .exists()))
    for name in ("unlink", "remove", "rmdir"):
        monkeypatch.setattr(os, name, guard(getattr(os, name)))
    for name in ("replace", "rename"):
        monkeypatch.setattr(os, name, guard(getattr(os, name), arguments=2))
    return refused


def test_disk_full_during_a_state_save_keeps_the_previous_state(colony, tmp_path, monkeypatch):
    state = tmp_path / "state"
    session = _colony_session(colony, 2.0)
    session.save_state(state)
    before = _tree(state)
    session.world.clock.advance(1.0)
    session.step(session.world.clock.now(), 0, None, audio=False)

    failures = _fill_disk(monkeypatch, state, ".json", room=10)  # each file fills the disk part-way
    with pytest.raises(OSError) as caught:
        session.save_state(state)
    monkeypatch.undo()
    assert caught.value.errno == errno.ENOSPC and caught.value.filename == str(state / ".saving" / "ada.json")
    assert len(failures) == 1  # the first file failed; the save stopped there
    assert _tree(state) == before  # previous files intact, no partial temp file left
    assert _colony_session(colony, 0.02).load_state(state) == ["ada", "bo"]

    # A live run whose periodic saves hit a full disk reports it and keeps running.
    colony.settings.save_every = 0.05
    colony.settings.midi.input_port = colony.settings.midi.output_port = None
    failures = _fill_disk(monkeypatch, state, ".json", room=10)
    said = []
    summary = live.run_live(colony, duration=0.3, state=state, say=said.append)
    monkeypatch.undo()
    assert summary.ticks >= 10 and summary.failed_saves >= 2 and len(failures) == summary.failed_saves
    assert sum("could not save creature state" in s for s in said) == summary.failed_saves
    assert _tree(state) == before


@pytest.mark.parametrize("code", [errno.EROFS, errno.EACCES], ids=["EROFS", "EACCES"])
def test_read_only_state_directory_is_a_clear_error_and_keeps_the_files(code, colony, tmp_path, monkeypatch):
    state = tmp_path / "state"
    session = _colony_session(colony, 1.0)
    session.save_state(state)
    before = _tree(state)

    refused = _read_only(monkeypatch, state, code)
    with pytest.raises(OSError) as caught:
        session.save_state(state)
    assert caught.value.errno == code and Path(caught.value.filename).parent == state
    assert len(refused) == 1  # the first file was refused; the save stopped there

    # A live run saving into it reports every refused save and keeps running.
    colony.settings.save_every = 0.05
    colony.settings.midi.input_port = colony.settings.midi.output_port = None
    said = []
    summary = live.run_live(colony, duration=0.3, state=state, say=said.append)
    monkeypatch.undo()
    assert summary.ticks >= 10 and summary.failed_saves >= 2
    assert sum("could not save creature state" in s and os.strerror(code) in s for s in said) == summary.failed_saves
    assert _tree(state) == before
    assert _colony_session(colony, 0.02).load_state(state) == ["ada", "bo"]


@pytest.mark.parametrize("code", [errno.EROFS, errno.EACCES], ids=["EROFS", "EACCES"])
def test_read_only_output_directory_is_a_clear_error_and_keeps_the_previous_run(code, colony, tmp_path,
                                                                               monkeypatch, capsys):
    out = tmp_path / "out"
    run_offline(colony, out, duration=0.5)
    before = _tree(out)
    assert {"events.jsonl", "out.wav", "out.mid"} <= set(before)

    refused = _read_only(monkeypatch, out, code)
    assert main(["offline", str(tmp_path / "colony.toml"), "--out", str(out), "--duration", "1",
                 "--no-progress"]) == 2
    monkeypatch.undo()
    assert f"cannot write outputs to {out}: {os.strerror(code)}" in capsys.readouterr().err
    assert len(refused) == 1  # refused at the first thing it tried to create; nothing was run
    assert _tree(out) == before


@pytest.mark.parametrize("made", [True, False], ids=["existing", "to be made"])
@pytest.mark.parametrize("code", [errno.EROFS, errno.EACCES], ids=["EROFS", "EACCES"])
def test_frames_on_a_read_only_disk_is_refused_naming_frames(made, code, colony, tmp_path, monkeypatch, capsys):
    """``--frames`` on a read-only disk said only "Read-only file system" (or, for a folder
    that existed, drew nothing in silence): it is refused before the run, naming ``--frames``."""
    disk = tmp_path / "disk"
    disk.mkdir()
    frames = disk / "frames"
    if made:
        frames.mkdir()
    refused = _read_only(monkeypatch, disk, code)
    assert main(["run", str(tmp_path / "colony.toml"), "--frames", str(frames), "--duration", "0.2"]) == 2
    monkeypatch.undo()
    err = capsys.readouterr().err
    assert f"--frames {frames}: cannot write there ({os.strerror(code)})" in err and err.count("\n") == 1
    assert refused and _tree(disk) == ({"frames": None} if made else {})


def test_midi_messages_with_no_output_port_are_counted_in_the_summary_and_the_log(colony, tmp_path, capsys):
    """A synth that is never there: every message the run sent it was dropped in silence;
    now the count ends the ``creatures run`` summary line and the events log."""
    log = tmp_path / "events.jsonl"
    assert main(["run", str(tmp_path / "colony.toml"), "--duration", "1", "--log", str(log)]) == 0
    out = capsys.readouterr().out
    (event,) = [e for e in read_events(log) if e["kind"] == "midi output"]
    assert event["port"] == "Fake Synth" and event["dropped"] > 0  # at least the closing all-notes-off
    assert f"; {event['dropped']} MIDI messages dropped (no output port)" in out


def _full_wav(monkeypatch, out: Path) -> list[Path]:
    """The 20th audio block written fills the disk (libsndfile writes from C, beyond ``open``)."""
    real_write, failures, blocks = WavOutput._write, [], []

    def fills_up(self, block):
        blocks.append(len(block))
        if len(blocks) == 20:
            failures.append(self.path)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.path))
        real_write(self, block)

    monkeypatch.setattr(WavOutput, "_write", fills_up)
    return failures


@pytest.mark.parametrize("full_at", ["out.wav", "out.mid"])
def test_disk_full_while_writing_offline_outputs_keeps_the_previous_run(full_at, colony, tmp_path, monkeypatch):
    """(A full disk under the events log alone is counted loss, not a failed run:
    tests/test_reliability_outputs.py.)"""
    out = tmp_path / "out"
    run_offline(colony, out, duration=1.0)
    before = _tree(out)
    assert {"events.jsonl", "out.wav", "out.mid"} <= set(before)

    if full_at == "out.wav":
        failures = _full_wav(monkeypatch, out)
    else:  # the MIDI file fills the disk in its first bytes
        failures = _fill_disk(monkeypatch, out, full_at, room=20)
    with pytest.raises(OSError, match="No space left") as caught:
        run_offline(colony, out, duration=1.5)
    monkeypatch.undo()
    assert len(failures) >= 1 and all(full_at in path.name for path in failures)
    # It names the output as published, not the hidden staging folder's copy, and says nothing changed.
    assert caught.value.filename == str(out / full_at), caught.value.filename
    assert f"while writing {out / full_at}; nothing in {out} was changed" in str(caught.value)
    assert _tree(out) == before  # the previous run whole; nothing of the failed one left

    summary = run_offline(colony, out, duration=1.5)  # with room again, the next run replaces it
    assert summary.files["events"] == out / "events.jsonl"
    assert read_events(out / "events.jsonl")[0]["duration"] == 1.5
    assert sorted(_tree(out)) == sorted(before)


# -- killed while saving ---------------------------------------------------------------------
SAVER = r"""
import hashlib, json, signal, sys
from pathlib import Path
import numpy as np
from creatures.clock import SimulatedClock
from creatures.cli import main
from creatures.events import EventLog, read_events
from creatures.persist import save_json
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink

if sys.argv[3] == "exit-on-term":  # like the live runner: SIGTERM unwinds (temp files go)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
out = Path(sys.argv[2])
clock = SimulatedClock()
session = Session(load_installation(sys.argv[1]), clock, EventLog(), MemorySink())
for n in range(1, 10_000):
    clock.advance_to(n * 0.05)
    session.step(n * 0.05, 0, None, audio=False)
    digest = hashlib.sha256(json.dumps(session.creatures[0].state(), sort_keys=True).encode()).hexdigest()
    print(f"saving {n} {digest}", flush=True)
    save_json(out / "big.json", {"n": n, "data": np.random.default_rng(n).random(60_000).tolist()},
              kind="soak payload")
    session.save_state(out)
    print(f"saved {n}", flush=True)
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_killed_during_state_saves_the_files_always_load(sig, colony, tmp_path, rng):
    script = tmp_path / "saver.py"
    script.write_text(SAVER)
    out = tmp_path / "state"
    out.mkdir()
    reader = _colony_session(colony, 0.02)
    announced: dict[int, str] = {}  # every version any run began to save (runs are seeded alike)
    for _ in range(3):
        process = subprocess.Popen([sys.executable, str(script), str(tmp_path / "colony.toml"), str(out),
                                    "exit-on-term"], stdout=subprocess.PIPE, text=True)
        wanted = int(rng.integers(1, 4))  # kill inside the wanted-th save, or just after it
        moment = "saving" if rng.integers(2) else "saved"
        try:
            for line in process.stdout:
                word, n, *digest = line.split()
                if word == "saving":
                    announced[int(n)] = digest[0]
                if int(n) == wanted and word == moment:
                    process.send_signal(sig)
                    break
            process.communicate(timeout=60)
        finally:
            process.kill()
            process.wait()
        assert process.returncode == (143 if sig == signal.SIGTERM else -signal.SIGKILL)

        big = load_json(out / "big.json", kind="soak payload")  # whole, never torn
        assert big["n"] in announced
        assert big["data"] == np.random.default_rng(big["n"]).random(60_000).tolist()
        ada = load_json(out / "ada.json", kind=STATE_KIND)
        digest = hashlib.sha256(json.dumps(ada["state"], sort_keys=True).encode()).hexdigest()
        assert digest in announced.values()  # exactly a version that was saved
        assert reader.load_state(out) == ["ada", "bo"]
        left = list(out.glob(".*.tmp"))
        if sig == signal.SIGTERM:
            assert left == []  # an orderly exit removes its temporary file
        assert len(left) <= 1  # SIGKILL may leave one stray temporary file, never a torn target
        reader.save_state(out)  # the next good saves clear such leftovers
        save_json(out / "big.json", big, kind="soak payload")
        assert list(out.glob(".*.tmp")) == []


def test_the_health_status_says_the_synth_is_gone_and_what_it_dropped(colony, tmp_path, monkeypatch):
    """A watchdog reading /health saw ``"state": "running"`` and ``notes_played`` growing while
    every note went nowhere (fluidsynth killed mid-run): the status now says whether the
    synth's port is there, how often it was lost and what found no port."""
    from creatures.runtime.health import Health

    published: list[dict] = []
    real = Health.publish

    def keep(self, **status):
        published.append(status)
        real(self, **status)

    monkeypatch.setattr(Health, "publish", keep)
    assert main(["run", str(tmp_path / "colony.toml"), "--duration", "2.5"]) == 0
    assert published, "the run published no status"
    midi = published[-1]["midi_output"]
    # (the colony plays nothing in 2.5 s unheard: what the port drops is counted by its own tests)
    assert set(midi) == {"connected", "lost", "dropped"} and midi["connected"] is False and midi["lost"] == 0
