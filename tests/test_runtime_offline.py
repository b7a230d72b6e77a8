"""Offline runs: valid outputs, deterministic, and bad input stops before anything is written."""

from __future__ import annotations

from pathlib import Path

import mido
import pytest
import soundfile

from creatures.cli import main
from creatures.events import read_events
from creatures.runtime.offline import run_offline
from creatures.runtime.outputs import MANIFEST, stage
from creatures.runtime.schema import load_installation

EXCHANGE = Path(__file__).resolve().parents[1] / "installations" / "exchange.toml"


@pytest.fixture(scope="module")
def exchange_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("exchange")
    assert main(["offline", str(EXCHANGE), "--out", str(out), "--duration", "20", "--no-progress"]) == 0
    return out


def test_offline_outputs_are_valid(exchange_run):
    info = soundfile.info(exchange_run / "out.wav")
    assert (info.samplerate, info.channels) == (22050, 2)
    assert info.frames == 20 * 22050
    midi = mido.MidiFile(exchange_run / "out.mid")
    ons = [m for track in midi.tracks for m in track if m.type == "note_on" and m.velocity > 0]
    offs = [m for track in midi.tracks for m in track if m.type == "note_off" or (m.type == "note_on" and m.velocity == 0)]
    assert len(ons) > 5 and len(ons) == len(offs)
    events = read_events(exchange_run / "events.jsonl")
    kinds = {e["kind"] for e in events}
    assert {"run", "heard", "placed", "selection", "note", "values", "motivation", "end"} <= kinds
    assert (exchange_run / "report" / "index.html").read_text().count("<img") >= 4


def test_input_notes_are_logged_when_they_are_heard(exchange_run):
    """The generated input is injected ahead of time; its notes are logged as the creatures
    hear them (a replay used to show every one of them heard at 0 s)."""
    events = read_events(exchange_run / "events.jsonl")
    tick = load_installation(EXCHANGE).settings.tick
    heard = [e for e in events if e["kind"] == "heard"]
    assert len(heard) > 10 and heard[-1]["t"] > 10.0
    assert all(0.0 <= e["t"] - e["time"] < tick + 1e-9 for e in heard)


def test_offline_is_deterministic(exchange_run, tmp_path):
    assert main(["offline", str(EXCHANGE), "--out", str(tmp_path), "--duration", "20", "--no-progress"]) == 0
    first = (exchange_run / "events.jsonl").read_text()
    assert (tmp_path / "events.jsonl").read_text() == first
    assert (tmp_path / "out.mid").read_bytes() == (exchange_run / "out.mid").read_bytes()
    a, _ = soundfile.read(exchange_run / "out.wav")
    b, _ = soundfile.read(tmp_path / "out.wav")
    assert (a == b).all()


BAD_CONFIGS = {
    "unknown key": ('title = "x"\n[[creature]]\nname = "a"\nkind = "exchange"\nspace.strike_radus = 0.2\n',
                    "creature.0.space.strike_radus", 5, "did you mean 'strike_radius'"),
    "wrong type": ('title = "x"\ntick = "fast"\n[[creature]]\nname = "a"\nkind = "exchange"\n', "tick", 2, "valid number"),
    "missing file": ('title = "x"\n[input]\nmidi = "nowhere.mid"\n[[creature]]\nname = "a"\nkind = "exchange"\n',
                     "input.midi", 3, "file not found"),
    "unstable synth": ('title = "x"\n[[creature]]\nname = "a"\nkind = "exchange"\n[creature.voice]\nstiffness = 1e9\n',
                       "creature.0.voice", 5, "unstable string"),
    "unknown kind": ('title = "x"\n[[creature]]\nname = "a"\nkind = "exchnage"\n', "creature.0.kind", 4,
                     "did you mean 'exchange'"),
}


@pytest.mark.parametrize("case", sorted(BAD_CONFIGS))
def test_bad_config_exits_2_naming_key_and_line_and_writes_nothing(case, tmp_path, capsys):
    text, key, line, phrase = BAD_CONFIGS[case]
    config = tmp_path / "bad.toml"
    config.write_text(text)
    out = tmp_path / "out"
    assert main(["offline", str(config), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert f"bad.toml:{line}: {key}" in err and phrase in err
    assert not out.exists()


def test_unwritable_output_directory_is_a_clear_error(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    assert main(["offline", str(EXCHANGE), "--out", str(blocker / "out"), "--no-progress"]) == 2
    assert "cannot write outputs" in capsys.readouterr().err


def test_recorded_midi_input_overrides_generated(tmp_path):
    from midi.files import write_notes
    from midi.notes import NoteEvent

    recorded = tmp_path / "in.mid"
    write_notes(recorded, [NoteEvent(0.5 + 0.25 * i, 50 + i, 90, 0, 0.2) for i in range(8)])
    inst = load_installation(EXCHANGE)
    inst.settings.output.wav = inst.settings.output.report = False
    run_offline(inst, tmp_path / "out", midi=recorded, duration=5)
    heard = [e["pitch"] for e in read_events(tmp_path / "out" / "events.jsonl") if e["kind"] == "heard"]
    assert heard == [50 + i for i in range(8)]


def test_an_offline_run_reads_no_more_of_a_long_recording_than_it_hears(tmp_path):
    """A 5 s run of a one-hour stereo recording read all of it first (27 s, 3.3 GB at 44.1
    kHz; a 4 GB WAV, more memory than the machine had). Here 10 minutes at 8 kHz (sparse)."""
    import struct

    import numpy as np

    from creatures.runtime.offline import _inputs

    rate, frames = 8000, 8000 * 600
    path = tmp_path / "hour.wav"
    with open(path, "wb") as handle:
        handle.write(b"RIFF" + struct.pack("<I", 36 + 2 * frames) + b"WAVEfmt "
                     + struct.pack("<IHHIIHH", 16, 1, 1, rate, 2 * rate, 2, 16)
                     + b"data" + struct.pack("<I", 2 * frames))
        handle.truncate(44 + 2 * frames)
    inst = load_installation(EXCHANGE)
    sr = inst.settings.audio.sample_rate
    _, samples = _inputs(inst, path, None, 5.0, np.random.default_rng(0), print)
    assert samples is not None and 5 * sr <= len(samples) <= 6.01 * sr


def test_a_finished_run_replaces_every_output_of_the_previous_one(tmp_path):
    inst = load_installation(EXCHANGE)
    out = tmp_path / "out"
    run_offline(inst, out, duration=2)
    assert (out / "report" / "index.html").is_file()
    # Leftovers of a run that was killed: its staging directory (nothing else could have removed it).
    killed = stage(out)
    (killed / "events.jsonl").write_text("")
    (out / "notes.txt").write_text("the artist's own file")

    inst.settings.output.report = False  # the older run's report must not stay beside this run's files
    summary = run_offline(inst, out, duration=3)
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "events.jsonl", "notes.txt", "out.mid", "out.wav",
                                                     "state"]
    assert summary.files == {"events": out / "events.jsonl", "wav": out / "out.wav", "midi": out / "out.mid",
                             "state": out / "state"}
    assert read_events(out / "events.jsonl")[0]["duration"] == 3
    assert soundfile.info(out / "out.wav").frames == 3 * 22050
    assert (out / "notes.txt").read_text() == "the artist's own file"


def test_the_coarsest_tick_the_schema_accepts_renders_audio(tmp_path):
    """0.5 s ticks at 22,050 Hz ask the voices for 11,025 frames a tick: more than one voice
    block, rendered in pieces rather than refused."""
    inst = load_installation(EXCHANGE)
    inst.settings.tick = 0.5
    inst.settings.output.report = False
    run_offline(inst, tmp_path / "out", duration=6)
    assert soundfile.info(tmp_path / "out" / "out.wav").frames == 6 * 22050


def test_a_mix_driven_past_full_scale_is_said_and_logged(tmp_path):
    """Creatures at gain 4 singing through strings at gain 4 sum past full scale, which out.wav
    clips hard: the run says so (the samples, the peak) instead of a distorted file and no word."""
    inst = load_installation(EXCHANGE)
    inst.settings.output.report = False
    for spec in inst.specs:
        spec.gain = 4.0
        spec.voice.gain = 4.0
    summary = run_offline(inst, tmp_path / "out", duration=7)  # the first notes are played from 5.4 s
    said = [m for m in summary.messages if m.startswith("out.wav: the mix clipped")]
    clipped = [e for e in read_events(tmp_path / "out" / "events.jsonl") if e["kind"] == "clipped"]
    assert len(said) == 1 and len(clipped) == 1 and clipped[0]["samples"] > 0 and clipped[0]["peak"] > 1
    data, _ = soundfile.read(tmp_path / "out" / "out.wav")
    assert (abs(data) >= 32767 / 32768).sum() >= clipped[0]["samples"] // 2  # what was counted is in the file, clipped


def _played(path: Path) -> list:
    """The notes of ``out.mid``'s creature tracks (the tempo track's map, the input track left out)."""
    from midi.notes import from_messages

    midi = mido.MidiFile(path)
    now, tempo, timed = 0.0, 500_000, []
    for msg in mido.merge_tracks([t for t in midi.tracks if t.name != "input"]):
        now += mido.tick2second(msg.time, midi.ticks_per_beat, tempo)
        tempo = msg.tempo if msg.type == "set_tempo" else tempo
        if not msg.is_meta:
            timed.append((now, msg))
    return from_messages(timed)


def test_every_logged_note_is_in_out_mid_as_it_sounded(exchange_run):
    """Note for note, the events log and out.mid agree: pitch, velocity, channel, start, and
    the end the log gives (a struck note rings on: ``rang_on``; the run's end cuts the rest),
    to a tick (1/960 s at 120 bpm). Before ``rang_on`` was logged a ringing note's length in the
    log was the one it was played with, up to half as long again as it sounded."""
    events = read_events(exchange_run / "events.jsonl")
    stop = next(e["t"] for e in events if e["kind"] == "end")
    ends = {(e["time"], e["pitch"], e["channel"]): e["end"] for e in events if e["kind"] in ("rang_on", "released")}
    assert ends and not any(e["kind"] == "restruck" for e in events)  # this take's notes ring on; none re-strikes
    logged = sorted((e["channel"], e["pitch"], e["time"], e["velocity"],
                     min(ends.get((e["time"], e["pitch"], e["channel"]), e["time"] + e["duration"]), stop) - e["time"])
                    for e in events if e["kind"] == "note")
    played = sorted((n.channel, n.pitch, n.time, n.velocity, n.duration) for n in _played(exchange_run / "out.mid"))
    assert len(logged) > 20 and [(w[0], w[1], w[3]) for w in logged] == [(p[0], p[1], p[3]) for p in played]
    tick = 1.0 / 960 + 1e-9
    assert all(abs(w[2] - p[2]) <= tick / 2 and abs(w[4] - p[4]) <= tick for w, p in zip(logged, played))
