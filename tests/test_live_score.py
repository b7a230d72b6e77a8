"""A live run's out.mid (``creatures run --out DIR``, creatures/runtime/live_score.py), without
devices: notes sent over OSC by python-osc's client are the input track, the colony's channel
setup and answers its named tracks, times from the run's start; the folder is checked before
anything runs and published all or none. The same on JACK with fluidsynth is in
tests/test_live_show.py."""

from __future__ import annotations

import threading
import time

import mido
import pytest
from pythonosc.udp_client import SimpleUDPClient

from bench.live_parts import free_udp_port
from creatures.runtime import live, live_score
from creatures.runtime.live_score import RecordingSink
from creatures.runtime.outputs import MANIFEST, OutputDirectoryError
from creatures.runtime.schema import load_installation
from midi.channel_setup import midi_pan
from midi.sinks import MemorySink

PITCHES = [60, 64, 67, 72, 76]


def colony(tmp_path, port: int):
    config = tmp_path / "live.toml"
    config.write_text(f'title = "live score"\ntick = 0.02\n[audio]\noutput = false\n[osc]\nport = {port}\n'
                      '[midi]\nprogram = 11\n'
                      '[[creature]]\nname = "ada"\nkind = "exchange"\nchannel = 0\npan = -0.5\nspace.answer = 1.0\n'
                      '[[creature]]\nname = "bo"\nkind = "exchange"\nchannel = 1\nhears_input = false\n')
    return load_installation(config)


def test_a_live_run_publishes_out_mid_with_what_it_heard_and_played(tmp_path):
    port = free_udp_port()
    out = tmp_path / "out"

    def send(message: str) -> None:
        if "running; Ctrl-C" in message:  # said just before the loop starts
            def notes() -> None:
                client = SimpleUDPClient("127.0.0.1", port)
                for pitch in PITCHES:
                    client.send_message("/creature/visitor/note", [pitch, 90.0, 0.25])  # floats, as Max sends
                    time.sleep(0.1)
            threading.Thread(target=notes, daemon=True).start()

    live.run_live(colony(tmp_path, port), duration=2.0, out=out, say=send)

    midi = mido.MidiFile(out / "out.mid")
    tracks = {track.name: track for track in midi.tracks}
    assert list(tracks) == ["tempo", "input", "ada", "bo"]
    heard = [m.note for m in tracks["input"] if m.type == "note_on" and m.velocity > 0]
    assert heard == PITCHES
    for name, pan in (("ada", midi_pan(-0.5)), ("bo", midi_pan(0.0))):
        assert [m.program for m in tracks[name] if m.type == "program_change"] == [11]
        assert [m.value for m in tracks[name] if m.type == "control_change" and m.control == 10] == [pan]
    assert any(m.type == "note_on" and m.velocity > 0 for m in tracks["ada"])  # she answered what she heard
    # Times count from the run's start (not the machine's uptime): the whole score lasts the run.
    assert 0.5 < midi.length < 2.0 + 1.0, midi.length
    assert (out / MANIFEST).is_file()  # published as offline outputs are


def test_a_folder_holding_someone_elses_out_mid_is_refused_before_anything_runs(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "out.mid").write_bytes(b"the artist's own")
    said: list[str] = []
    with pytest.raises(OutputDirectoryError, match="out.mid"):
        live.run_live(colony(tmp_path, free_udp_port()), duration=0.5, out=out, say=said.append)
    assert (out / "out.mid").read_bytes() == b"the artist's own"
    assert not any("running" in message for message in said)


def test_the_record_is_bounded_and_sends_everything_on():
    inner = MemorySink()
    recorded = RecordingSink(inner, keep=3)
    for i in range(5):
        recorded.send(i * 0.1, mido.Message("note_on", note=60 + i))
    assert len(inner.messages) == 5 and [m.note for _, m in recorded.messages] == [62, 63, 64]
    assert recorded.sent == 5


def test_a_later_run_replaces_its_out_mid_and_one_that_cannot_write_keeps_the_last(tmp_path, monkeypatch):
    out = tmp_path / "out"
    said: list[str] = []
    live.run_live(colony(tmp_path, free_udp_port()), duration=0.3, out=out, say=said.append)
    live.run_live(colony(tmp_path, free_udp_port()), duration=0.3, out=out, say=said.append)  # ours: replaced
    assert sum(f"wrote {out / 'out.mid'}" in m for m in said) == 2
    kept = (out / "out.mid").read_bytes()

    def full_disk(*args: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(live_score, "write_score", full_disk)
    said.clear()
    live.run_live(colony(tmp_path, free_udp_port()), duration=0.3, out=out, say=said.append)
    assert any("could not write" in m and "No space left" in m for m in said), said
    assert (out / "out.mid").read_bytes() == kept and kept[:4] == b"MThd"
    assert not list(out.glob(".creatures-run-*"))  # the staging folder went
