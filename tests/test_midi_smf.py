"""The compiled file reader (midi.smf) reads what mido reads, the same way, or leaves it to mido."""

from __future__ import annotations

from unittest import mock

import mido
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from midi import smf
from midi.files import MidiFileError, TempoMap, read_messages, read_notes, write_notes
from tests.test_midi_files import random_notes


def outcome(read, path):
    """What a reader gives for ``path``: its result, or the type and text of its error."""
    try:
        return "read", read(path)
    except Exception as exc:  # any error must be the same error
        return type(exc).__name__, str(exc)


def both(read, path):
    """``read(path)`` through midi.smf and through mido alone (the reader before midi.smf)."""
    fast = outcome(read, path)
    with mock.patch.object(smf, "parse", return_value=None):
        slow = outcome(read, path)
    return fast, slow


def smf_bytes(file_type: int, tracks: list[bytes], ticks_per_beat: int = 480) -> bytes:
    data = b"MThd" + (6).to_bytes(4, "big") + file_type.to_bytes(2, "big") + len(tracks).to_bytes(2, "big")
    data += ticks_per_beat.to_bytes(2, "big")
    for track in tracks:
        data += b"MTrk" + len(track).to_bytes(4, "big") + track
    return data


# Running status (note-on, then data only), a velocity-0 note-off, a sysex, a text meta, a
# tempo change mid-track, control/program/pitch-wheel/aftertouch messages, running status
# resumed after a meta event, and two overlapping notes of one pitch (FIFO pairing).
BUSY = bytes.fromhex(
    "00 FF 03 04 6C 65 61 64"  # track name "lead"
    "00 F0 05 7E 7F 09 01 F7"  # sysex
    "00 90 3C 40  10 3E 50  10 3C 00"  # on 60, running-status on 62, on 60 velocity 0
    "20 FF 51 03 07 A1 20"  # tempo 500000 at tick 0x30
    "00 3E 00"  # running status resumed after the meta: note 62 off
    "05 B1 07 64  00 C2 05  00 E3 00 40  00 D4 30  00 A5 3C 10"
    "00 91 40 60  10 91 40 61  10 81 40 00  81 00 81 40 00"  # overlapping 64s on channel 2
    "00 99 24 7F"  # a note never ended: closed at the last message
    "00 FF 2F 00"
)


def test_handmade_files_read_the_same_and_through_the_fast_reader(tmp_path):
    second = bytes.fromhex("00 FF 51 03 0F 42 40 83 60 92 30 50 83 60 82 30 00 00 FF 2F 00")
    files = {
        "format0.mid": smf_bytes(0, [BUSY]),
        "format1.mid": smf_bytes(1, [BUSY, second, BUSY]),
        "format2.mid": smf_bytes(2, [BUSY, second]),
        "empty.mid": smf_bytes(1, []),
    }
    for name, data in files.items():
        path = tmp_path / name
        path.write_bytes(data)
        assert smf.parse(data) is not None, name  # the fast reader took it
        for read in (read_notes, read_messages):
            fast, slow = both(read, path)
            assert fast == slow and fast[0] == "read", (name, read.__name__)
    notes = read_notes(tmp_path / "format0.mid")
    assert [(n.pitch, n.channel) for n in notes].count((64, 1)) == 2 and len(notes) == 5


def test_written_files_with_tempo_changes_read_the_same(rng, tmp_path):
    notes = random_notes(rng, 3000)
    tempo = TempoMap.from_seconds(480, [(12.5, 90.0), (40.0, 173.0), (77.7, 61.0)])
    for split in (True, False):
        path = tmp_path / f"split{split}.mid"
        write_notes(path, notes, tempo=tempo, split_channels=split)
        assert smf.parse(path.read_bytes()) is not None
        for read in (read_notes, read_messages):
            fast, slow = both(read, path)
            assert fast == slow and len(fast[1]) >= 3000


def test_files_the_fast_reader_declines_are_read_by_mido(tmp_path):
    """A system message in a track, a delta of five bytes, a meta mido cannot decode, a message
    past its chunk: declined, and read (or refused) as before."""
    cases = [
        bytes.fromhex("00 F8 00 90 3C 40 00 FF 2F 00"),
        bytes.fromhex("81 80 80 80 00 90 3C 40 00 FF 2F 00"),
        bytes.fromhex("00 FF 51 02 07 A1 00 90 3C 40"),
        bytes.fromhex("00 90 3C"),
    ]
    for k, track in enumerate(cases):
        data = smf_bytes(1, [track])
        assert smf.parse(data) is None, k
        path = tmp_path / f"odd{k}.mid"
        path.write_bytes(data)
        for read in (read_notes, read_messages):
            fast, slow = both(read, path)
            assert fast == slow, (k, fast, slow)


# Running status resumed after a text meta (accepted, as mido accepts it), then after a sysex.
AFTER_SYSEX = bytes.fromhex("00 90 3C 64  00 FF 01 01 61  0A 3E 64  00 F0 01 F7  0A 40 64  00 FF 2F 00")


@pytest.mark.parametrize("sysex", ["F0", "F7"])
def test_running_status_after_a_sysex_is_refused_for_what_it_is(tmp_path, sysex):
    """The SMF spec: a sysex cancels running status. mido read the data byte after it as the
    sysex's and called a whole chunk "truncated"; the message now says where and why."""
    path = tmp_path / "after.mid"
    path.write_bytes(smf_bytes(1, [AFTER_SYSEX.replace(b"\xF0", bytes.fromhex(sysex))]))
    expected = (r"after\.mid: track 1, byte 39: data byte 0x40 with no running status "
                r"\(a sysex event cancels it\)$")
    for read in (read_notes, read_messages):
        with pytest.raises(MidiFileError, match=expected):
            read(path)


def test_running_status_after_a_meta_event_is_read_as_mido_reads_it(tmp_path):
    """Sequencers write it and readers (mido's too) accept it, though the spec says a meta
    cancels running status: the decision is to read it (midi/smf.py's module docstring)."""
    path = tmp_path / "after_meta.mid"
    path.write_bytes(smf_bytes(1, [AFTER_SYSEX[:12] + bytes.fromhex("0A 40 64  00 FF 2F 00")]))
    for read in (read_notes, read_messages):
        fast, slow = both(read, path)
        assert fast == slow
    assert [n.pitch for n in read_notes(path)] == [60, 62, 64]


def refused_after_sysex(outcome: tuple) -> bool:
    """The one refusal only the fast reader gives (mido's error there is "truncated", or none)."""
    return outcome[0] == "MidiFileError" and "(a sysex event cancels it)" in outcome[1]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_fuzzed_files_give_the_same_notes_or_the_same_error(tmp_path, data):
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    notes = random_notes(rng, 30, seconds=5.0)
    path = tmp_path / "fuzzed.mid"
    write_notes(path, notes, tempo=TempoMap.from_seconds(96, [(1.0, 150.0)]), split_channels=data.draw(st.booleans()))
    raw = bytearray(path.read_bytes())
    for _ in range(data.draw(st.integers(1, 4))):
        how = data.draw(st.sampled_from(["truncate", "flip", "splice"]))
        if how == "truncate":
            raw = raw[: data.draw(st.integers(0, len(raw)))]
        elif how == "flip" and raw:
            raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
        else:
            at = data.draw(st.integers(0, len(raw)))
            raw[at:at] = data.draw(st.binary(min_size=1, max_size=12))
    path.write_bytes(bytes(raw))
    for read in (read_notes, read_messages):
        fast, slow = both(read, path)
        assert fast == slow or refused_after_sysex(fast)


def test_mido_still_writes_what_the_fast_reader_reads(rng, tmp_path):
    """Round trip: mido writes, midi.smf reads the notes back (as test_midi_files asserts
    within a tick for the whole path)."""
    notes = random_notes(rng, 200)
    write_notes(tmp_path / "x.mid", notes)
    back = read_notes(tmp_path / "x.mid")
    assert len(back) == 200
    assert sorted((n.pitch, n.velocity, n.channel) for n in back) == sorted((n.pitch, n.velocity, n.channel) for n in notes)
    assert isinstance(mido.MidiFile(tmp_path / "x.mid"), mido.MidiFile)
