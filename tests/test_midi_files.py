"""Standard MIDI files: notes survive a write/read round trip through a tempo map."""

from __future__ import annotations

from dataclasses import replace

import mido
import numpy as np
import pytest

from midi import smf
from midi.files import MidiFileError, TempoMap, read_messages, read_notes, write_notes
from midi.notes import NoteEvent, from_messages, is_note_off


def random_notes(rng: np.random.Generator, n: int, *, seconds: float = 120.0) -> list[NoteEvent]:
    """Random notes on 16 channels; same-pitch notes may overlap, but a later start never ends
    earlier (so each key's last overlapping note ends at the last of their ends)."""
    starts = np.sort(rng.uniform(0.0, seconds, n))
    pitches, channels = rng.integers(48, 72, n), rng.integers(0, 16, n)
    ends = starts + rng.uniform(0.01, 3.0, n)
    last_end: dict[tuple[int, int], float] = {}
    notes = []
    for t, p, v, c, end in zip(starts, pitches, rng.integers(1, 128, n), channels, ends):
        end = max(end, last_end.get((c, p), 0.0) + 0.01)
        last_end[c, p] = end
        notes.append(NoteEvent(float(t), int(p), int(v), int(c), float(end - t)))
    return notes


def by_voice(notes: list[NoteEvent]) -> list[NoteEvent]:
    return sorted(notes, key=lambda n: (n.channel, n.pitch, n.time))


def re_struck(voices: list[NoteEvent]) -> list[NoteEvent]:
    """``voices`` (:func:`by_voice`, later starts never ending earlier) as a file sounds them:
    a note still sounding when its key is struck again ends there."""
    return [replace(a, duration=b.time - a.time) if (b.channel, b.pitch) == (a.channel, a.pitch) and b.time < a.end
            else a for a, b in zip(voices, voices[1:])] + voices[-1:]


def key_events(track: mido.MidiTrack) -> list[tuple[int, str, int, int]]:
    """(absolute tick, "on"/"off", channel, pitch) of a track's notes, in file order."""
    ticks = np.cumsum([m.time for m in track]).tolist()
    return [(tick, "off" if is_note_off(m) else "on", m.channel, m.note)
            for tick, m in zip(ticks, track) if m.type in ("note_on", "note_off")]


def one_key_at_a_time(events: list[tuple[int, str, int, int]]) -> bool:
    """No note-on of a key already sounding, no note-off of a key silent (as a synth keeps keys)."""
    down: set[tuple[int, int]] = set()
    for _, kind, channel, pitch in events:
        if (kind == "on") == ((channel, pitch) in down):
            return False
        (down.add if kind == "on" else down.remove)((channel, pitch))
    return not down


def tick_length(tempo: TempoMap, seconds: np.ndarray) -> np.ndarray:
    """Seconds per tick under the tempo in force at each time in ``seconds``."""
    i = np.searchsorted(tempo.seconds, seconds, side="right") - 1
    return tempo.tempos[i] * 1e-6 / tempo.ticks_per_beat


@pytest.mark.parametrize("split_channels", [True, False])
def test_thousand_notes_with_tempo_changes_round_trip_within_one_tick(rng, tmp_path, split_channels):
    notes = random_notes(rng, 1000)
    voices = by_voice(notes)
    overlapping = sum(
        a.channel == b.channel and a.pitch == b.pitch and b.time < a.end for a, b in zip(voices, voices[1:])
    )
    assert overlapping > 10  # the re-strike of overlapping same-pitch notes is exercised
    tempo = TempoMap.from_seconds(480, [(12.5, 90.0), (40.0, 173.0), (77.7, 61.0), (100.0, 140.0)])
    path = tmp_path / "phrase.mid"
    write_notes(path, notes, tempo=tempo, split_channels=split_channels)

    back = read_notes(path)
    assert len(back) == len(notes)
    assert all(one_key_at_a_time(key_events(track)) for track in mido.MidiFile(path).tracks)
    originals, reads = re_struck(voices), by_voice(back)
    for original, read in zip(originals, reads):
        assert (read.pitch, read.velocity, read.channel) == (original.pitch, original.velocity, original.channel)
    for when in (lambda n: n.time, lambda n: n.end):
        wanted = np.array([when(n) for n in originals])
        got = np.array([when(n) for n in reads])
        # Each difference in ticks, measured with the tick length where the note is.
        assert np.all(np.abs(got - wanted) / tick_length(tempo, wanted) <= 1.0 + 1e-9)


def test_a_key_struck_again_while_it_sounds_is_written_off_then_on_at_one_tick(tmp_path):
    """on, on, off, off of one key plays as a second note cut short by the first's end (or a
    hanging note): the file ends the sounding note at the re-strike, off first, and the key
    sounds to the later of the two ends. Read back by every reader, the onsets and pitches are
    the notes'; the earlier note is shortened to the re-strike."""
    notes = [NoteEvent(0.0, 60, 100, 0, 2.0), NoteEvent(1.0, 60, 90, 0, 2.0),  # overlapping by a second
             NoteEvent(4.0, 62, 100, 1, 3.0), NoteEvent(5.0, 62, 70, 1, 0.5),  # inside the first
             NoteEvent(8.0, 64, 100, 2, 1.0), NoteEvent(8.0, 64, 80, 2, 0.0),  # the same instant, no length
             NoteEvent(9.5, 65, 100, 3, 1.0), NoteEvent(10.4999, 65, 100, 3, 1.0)]  # rounds onto the first's end
    path = tmp_path / "again.mid"
    write_notes(path, notes, split_channels=False)

    track = mido.MidiFile(path).tracks[1]  # a real reader: ticks of 960 a beat at 120 bpm, 1920 a second
    assert key_events(track) == [(0, "on", 0, 60), (1920, "off", 0, 60), (1920, "on", 0, 60), (5760, "off", 0, 60),
                                 (7680, "on", 1, 62), (9600, "off", 1, 62), (9600, "on", 1, 62),
                                 (13440, "off", 1, 62),
                                 (15360, "on", 2, 64), (15360, "off", 2, 64), (15360, "on", 2, 64),
                                 (17280, "off", 2, 64),
                                 (18240, "on", 3, 65), (20160, "off", 3, 65), (20160, "on", 3, 65),
                                 (22080, "off", 3, 65)]
    assert one_key_at_a_time(key_events(track))
    wanted = [(0.0, 60, 1.0), (1.0, 60, 2.0), (4.0, 62, 1.0), (5.0, 62, 2.0), (8.0, 64, 0.0), (8.0, 64, 1.0),
              (9.5, 65, 1.0), (10.5, 65, 1.0)]
    for back in (read_notes(path), from_messages(read_messages(path))):  # read_messages: FileSource's reader
        assert [(n.time, n.pitch, round(n.duration, 4)) for n in back] == wanted


def test_written_file_is_type_1_with_tempo_track_and_one_track_per_channel(rng, tmp_path):
    notes = [n for n in random_notes(rng, 200) if n.channel in (0, 3, 9)]
    tempo = TempoMap.from_seconds(96, [(5.0, 100.0)])
    write_notes(tmp_path / "x.mid", notes, tempo=tempo)
    midi = mido.MidiFile(tmp_path / "x.mid")
    assert midi.type == 1 and midi.ticks_per_beat == 96
    assert [m.tempo for m in midi.tracks[0] if m.type == "set_tempo"] == [500_000, 600_000]
    channels = [{m.channel for m in track if not m.is_meta} for track in midi.tracks[1:]]
    assert channels == [{0}, {3}, {9}]
    # mido's own tempo-aware playback agrees with ours on when the last note ends.
    assert midi.length == pytest.approx(max(n.end for n in notes), abs=tempo.tempos.max() * 1e-6 / 96)


def test_tempo_map_is_inverse_of_itself(rng):
    tempo = TempoMap(480, [(1000, 400_000), (5000, 1_000_000), (5000, 300_000), (9000, 800_000)])
    ticks = rng.integers(0, 20_000, 500)
    assert np.array_equal(tempo.to_ticks(tempo.to_seconds(ticks)), ticks)
    assert tempo.changes()[2] == (5000, 300_000)  # the later of two changes at one tick wins
    assert tempo.to_seconds(np.array([1000]))[0] == pytest.approx(1000 * 0.5 / 480)


def test_type_2_tracks_keep_their_own_tempo(tmp_path):
    midi = mido.MidiFile(type=2, ticks_per_beat=100)
    for tempo in (500_000, 1_000_000):
        midi.tracks.append(mido.MidiTrack([
            mido.MetaMessage("set_tempo", tempo=tempo),
            mido.Message("note_on", note=60, velocity=64, time=100),
            mido.Message("note_off", note=60, time=100),
        ]))
    midi.save(tmp_path / "t2.mid")
    starts = sorted(n.time for n in read_notes(tmp_path / "t2.mid"))
    assert starts == pytest.approx([0.5, 1.0])


def test_running_status_in_file_and_velocity_zero_note_offs(tmp_path):
    # MThd, one MTrk: note-on 60, running-status note-on 60 vel 0 (= note-off) after 480 ticks.
    track = bytes.fromhex("00 90 3C 40 83 60 3C 00 00 FF 2F 00")
    data = b"MThd" + (6).to_bytes(4, "big") + bytes.fromhex("0000 0001 01E0")
    data += b"MTrk" + len(track).to_bytes(4, "big") + track
    (tmp_path / "rs.mid").write_bytes(data)
    assert read_notes(tmp_path / "rs.mid") == [NoteEvent(0.0, 60, 64, 0, 0.5)]


def test_missing_and_garbage_files_name_the_file(tmp_path):
    with pytest.raises(MidiFileError, match="nowhere.mid: MIDI file not found"):
        read_notes(tmp_path / "nowhere.mid")
    (tmp_path / "junk.mid").write_bytes(b"RIFF not a midi file at all")
    with pytest.raises(MidiFileError, match=r"junk\.mid: malformed MIDI file \(MThd not found"):
        read_messages(tmp_path / "junk.mid")


@pytest.mark.parametrize("division, message", [
    ("0000", r"zero\.mid: ticks per beat 0 in the header \(must be 1\.\.32767\)"),
    ("E728", r"zero\.mid: SMPTE time division is not supported"),  # -25 fps, 40 ticks per frame
])
def test_a_division_no_tick_can_be_timed_by_is_named_for_what_it_is(tmp_path, division, message):
    track = bytes.fromhex("00 90 3C 40 83 60 3C 00 00 FF 2F 00")
    data = b"MThd" + (6).to_bytes(4, "big") + bytes.fromhex("0001 0001" + division)
    (tmp_path / "zero.mid").write_bytes(data + b"MTrk" + len(track).to_bytes(4, "big") + track)
    for read in (read_notes, read_messages):
        with pytest.raises(MidiFileError, match=message):
            read(tmp_path / "zero.mid")


def test_failed_write_leaves_previous_file_intact(rng, tmp_path):
    path = tmp_path / "keep.mid"
    notes = random_notes(rng, 20)
    write_notes(path, notes)
    before = path.read_bytes()
    bad = [*notes, "not a note"]
    with pytest.raises(AttributeError):
        write_notes(path, bad)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["keep.mid"]


def test_zero_tempo_in_a_file_is_a_clear_error(tmp_path):
    midi = mido.MidiFile(type=0)
    midi.tracks.append(mido.MidiTrack([mido.MetaMessage("set_tempo", tempo=0), mido.Message("note_on", time=10)]))
    midi.save(tmp_path / "stopped.mid")
    with pytest.raises(MidiFileError, match=r"stopped\.mid: bad tempo map"):
        read_notes(tmp_path / "stopped.mid")
    with pytest.raises(ValueError, match="bpm must be > 0"):
        TempoMap.from_seconds(480, [(1.0, 0.0)])


def test_a_valid_file_padded_past_the_size_cap_is_refused(tmp_path):
    """The compiled reader read the whole file itself and ignored bytes after the last track, so
    a good header and track followed by 64 MB (sparse here) were read and their notes played."""
    from midi.files import MAX_MIDI_BYTES

    track = bytes.fromhex("00 90 3C 40 83 60 3C 00 00 FF 2F 00")
    path = tmp_path / "padded.mid"
    with open(path, "wb") as handle:
        handle.write(b"MThd" + (6).to_bytes(4, "big") + bytes.fromhex("0000 0001 01E0"))
        handle.write(b"MTrk" + len(track).to_bytes(4, "big") + track)
        handle.truncate(MAX_MIDI_BYTES + 1)
    for read in (read_notes, read_messages):
        with pytest.raises(MidiFileError, match=r"padded\.mid: MIDI file larger than"):
            read(path)
    with open(path, "r+b") as handle:  # at the cap it is read
        handle.truncate(MAX_MIDI_BYTES)
    assert read_notes(path) == [NoteEvent(0.0, 60, 64, 0, 0.5)]


def test_a_directory_or_unreadable_path_is_named(tmp_path):
    with pytest.raises(MidiFileError, match=r"folder\.mid: cannot read the MIDI file \(Is a directory\)"):
        read_notes((tmp_path / "folder.mid").mkdir() or tmp_path / "folder.mid")


@pytest.mark.parametrize("reader", ["compiled", "mido"])
def test_a_note_past_the_latest_time_is_a_clear_error_not_a_traceback(tmp_path, reader):
    """300 deltas of 2^28 - 1 ticks at one tick a beat and 16.7 s a beat put a note at 1.35e12 s:
    NoteEvent raised a ValueError and `creatures offline --midi` ended in a traceback. A system
    real-time byte (which only mido reads) sends the file down mido's path."""
    far = b"\xff\xff\xff\x7f\xff\x01\x00" * 300  # each: the longest delta, an empty text event
    track = (bytes.fromhex("00 FF 51 03 FF FF FF") + (bytes.fromhex("00 F8") if reader == "mido" else b"")
             + bytes.fromhex("00 90 40 50 60 80 40 00") + far + bytes.fromhex("00 90 3C 50 60 80 3C 00 00 FF 2F 00"))
    data = b"MThd" + (6).to_bytes(4, "big") + bytes.fromhex("0000 0001 0001")
    (tmp_path / "far.mid").write_bytes(data + b"MTrk" + len(track).to_bytes(4, "big") + track)
    for read in (read_notes, read_messages):
        with pytest.raises(MidiFileError, match=r"far\.mid: 2 messages fall past 1e\+12 s, .*first at 1\.351e\+12 s"):
            read(tmp_path / "far.mid")
    track = track.replace(far, far[:7 * 200])  # 200 of them: 9.0e11 s, within
    (tmp_path / "far.mid").write_bytes(data + b"MTrk" + len(track).to_bytes(4, "big") + track)
    assert [n.pitch for n in read_notes(tmp_path / "far.mid")] == [64, 60]


def test_an_empty_file_is_said_to_be_empty(tmp_path):
    """As an empty sound file is; mido called it 'truncated MIDI file (ended inside a chunk)'."""
    (tmp_path / "none.mid").write_bytes(b"")
    for read in (read_notes, read_messages):
        with pytest.raises(MidiFileError, match=r"none\.mid: empty file \(0 bytes\)"):
            read(tmp_path / "none.mid")


def test_a_pause_longer_than_a_delta_can_say_is_bridged(tmp_path):
    """Four bytes of delta are 2^28 ticks (78 hours at 120 bpm): a note a million seconds in
    is reached through filler events, so the strict reader takes the file, note for note."""
    path = tmp_path / "long.mid"
    notes = [NoteEvent(1.0, 60, 100, 0, 1.0), NoteEvent(1e6, 62, 90, 0, 1.0)]
    write_notes(path, notes)
    assert smf.parse(path.read_bytes()) is not None  # no delta past four bytes
    assert read_notes(path) == notes


def test_a_note_written_at_a_slow_heard_tempo_lands_within_a_millisecond(tmp_path):
    """At 480 ticks a beat a 40 bpm pulse placed notes up to 1.6 ms off where they were played;
    a file of a slow piece moved its notes by more than a struck key's own jitter."""
    from midi.files import TICKS_PER_BEAT

    rng = np.random.default_rng(7)
    notes = [NoteEvent(float(t), 60, 90, 0, 0.1) for t in np.sort(rng.uniform(0.0, 60.0, 200))]
    path = tmp_path / "slow.mid"
    write_notes(path, notes, tempo=TempoMap.from_seconds(TICKS_PER_BEAT, [(0.0, 40.0)]))
    back = read_notes(path)
    assert len(back) == len(notes)
    assert max(abs(a.time - b.time) for a, b in zip(back, notes)) < 1e-3
