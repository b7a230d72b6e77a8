"""Bad and unusual input to the streaming transcriber (audio/transcribe.py): handled, counted,
no crash, no phantom notes — and the notes that are there still heard."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from audio.transcribe import LIVE, OFFLINE, QUICK, Transcriber, velocity_from_level
from creatures.runtime.inputs import phrase_notes, render_notes

PITCHES = [60, 64, 67]


def chord_line(rate: int, seconds: float = 3.0) -> np.ndarray:
    """Three synthetic notes, one every 0.8 s from 0.5 s, rendered at ``rate``."""
    from midi.notes import NoteEvent

    notes = [NoteEvent(0.5 + 0.8 * i, p, 90, 0, 0.6) for i, p in enumerate(PITCHES)]
    return render_notes(notes, rate, seconds)


def hear(x: np.ndarray, rate: int, *, block: int = 1000, look: str = OFFLINE) -> tuple[Transcriber, list]:
    ear = Transcriber(rate, look=look)
    notes = [n for i in range(0, len(x), block) for n in ear.feed(x[i:i + block])]
    return ear, notes


@pytest.mark.parametrize("look", [LIVE, OFFLINE])
@pytest.mark.parametrize("rate", [8000, 16000, 44100, 96000, 192000])
def test_every_rate_hears_the_same_notes(rate: int, look: str) -> None:
    _, notes = hear(chord_line(rate), rate, block=rate // 50, look=look)
    assert [n.pitch for n in notes] == PITCHES
    assert all(abs(n.time - (0.5 + 0.8 * i)) < 0.03 for i, n in enumerate(notes))


@pytest.mark.parametrize("channels", [1, 2, 8])
def test_channels_are_mixed(channels: int) -> None:
    x = chord_line(22050)
    wide = np.repeat(x[:, None], channels, axis=1) * np.linspace(1.0, 0.2, channels)[None, :]
    _, notes = hear(wide, 22050)
    assert [n.pitch for n in notes] == PITCHES


def test_non_finite_samples_are_counted_and_repaired() -> None:
    """Bursts of NaN and inf from a failing driver, in the middle of notes: counted, and no
    note is heard from the steps they leave."""
    x = chord_line(22050)
    for start, value in ((int(0.9 * 22050), np.nan), (int(1.6 * 22050), np.inf), (int(2.5 * 22050), -np.inf)):
        x[start:start + 100] = value
    ear, notes = hear(x, 22050)
    assert ear.bad_samples == 300
    assert [n.pitch for n in notes] == PITCHES


def test_samples_far_beyond_full_scale_are_counted_and_repaired() -> None:
    """Finite junk (a driver writing garbage) is repaired like NaN: ×1e30 overflowed the spectra."""
    x = chord_line(22050)
    for start, value in ((int(0.9 * 22050), 1e30), (int(1.6 * 22050), -1e18), (int(2.5 * 22050), 1e4)):
        x[start:start + 100] = value
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow on the way
        ear, notes = hear(x, 22050)
    assert ear.bad_samples == 300
    assert [n.pitch for n in notes] == PITCHES


def test_clipping_is_counted_and_the_notes_survive() -> None:
    x = np.clip(chord_line(22050) * 20.0, -1.0, 1.0)
    ear, notes = hear(x, 22050)
    assert ear.clipped > 1000
    assert [n.pitch for n in notes] == PITCHES


def test_dc_offset_changes_nothing() -> None:
    _, plain = hear(chord_line(22050), 22050)
    _, offset = hear(chord_line(22050) + 0.3, 22050)
    assert [(n.pitch, round(n.time, 3)) for n in offset] == [(n.pitch, round(n.time, 3)) for n in plain]


@pytest.mark.parametrize("look", [LIVE, OFFLINE])
def test_no_phantom_notes_from_silence_noise_or_steps(rng: np.random.Generator, look: str) -> None:
    rate = 22050
    cases = {
        "digital silence": np.zeros(10 * rate, dtype=np.float32),
        "dither": rng.integers(-1, 2, 10 * rate) / 32768.0,  # ±1 LSB of 16-bit audio
        "white noise at -20 dBFS": 0.1 * rng.standard_normal(10 * rate),
        "DC switched on": np.r_[np.zeros(rate), np.full(9 * rate, 0.5)],
        # noise after silence: for seconds it stands far above the floors learnt in silence (FLOOR_RISE)
        "white noise at -20 dBFS switched on": np.r_[np.zeros(2 * rate), 0.1 * rng.standard_normal(8 * rate)],
        "room noise at -40 dBFS switched on": np.r_[np.zeros(2 * rate), room_noise(8.0, rate, rng, -40.0)],
    }
    for name, x in cases.items():
        ear, notes = hear(x.astype(np.float32), rate, look=look)
        assert notes == [], name
        assert ear.bad_samples == 0


def test_a_rate_change_mid_stream_keeps_the_timeline() -> None:
    """A live device reopened at another rate: the transcriber is told, and the notes after the
    change are heard at their times (the stream's clock counts analysis samples)."""
    first, second = chord_line(44100, 1.0), chord_line(48000, 3.0)[48000:]  # one timeline, two rates
    ear = Transcriber(44100)
    heard = [n for i in range(0, len(first), 441) for n in ear.feed(first[i:i + 441])]
    ear.set_rate(48000)
    heard += [n for i in range(0, len(second), 480) for n in ear.feed(second[i:i + 480])]
    ear.feed(np.zeros(48000, dtype=np.float32))
    assert [n.pitch for n in heard] == PITCHES
    assert abs(heard[1].time - 1.3) < 0.03 and abs(heard[2].time - 2.1) < 0.03


@pytest.mark.parametrize("look, bound", [(LIVE, 0.05), (QUICK, 0.03)])
def test_the_live_looks_answer_in_time(look: str, bound: float) -> None:
    """The note event of an attack is given by the block that holds onset + 50 ms (the issue asks 60):
    3 hops after the hop it lands in (measured at most 39.5 ms with 64-frame blocks); the quick look
    within 30 ms (4 of its 128-sample hops: measured at most 29.5 ms), every note heard as played."""
    rate = 22050
    played = phrase_notes(start=0.5, gap=4.0)
    x = render_notes(played, rate, 13.0)
    ear = Transcriber(rate, look=look)
    block = 64
    given = []  # (when the note event came out, the note)
    for i in range(0, len(x), block):
        given += [((i + block) / rate, note) for note in ear.feed(x[i:i + block])]
    assert [n.pitch for _, n in given] == [n.pitch for n in played]
    delays = [out - note.time for (out, _), note in zip(given, played)]
    print(f"onset → note event: max {1e3 * max(delays):.1f} ms")
    assert max(delays) <= bound, delays


def room_noise(seconds: float, rate: int, rng: np.random.Generator, dbfs: float) -> np.ndarray:
    """A room's noise: brown-ish (a fan's rumble and hiss, falling with frequency) at ``dbfs`` RMS."""
    from scipy import signal

    x = signal.lfilter([1.0], [1.0, -0.9], rng.standard_normal(int(seconds * rate)))
    return (x * 10 ** (dbfs / 20) / np.sqrt(np.mean(x**2))).astype(np.float32)


@pytest.mark.parametrize("look", [LIVE, OFFLINE])
def test_a_minute_of_room_noise_gives_no_notes_and_no_utterances(rng: np.random.Generator, look: str) -> None:
    from creatures.kinds.hearing_parts import Ear, HearingSpec

    rate = 22050
    x = room_noise(60.0, rate, rng, -40.0)
    ear, notes = hear(x, rate, block=882, look=look)
    assert notes == [] and ear.onsets == 0
    if look == LIVE:
        utterances = Ear(HearingSpec())
        heard = [u for i in range(0, len(x), 882) for u in utterances.listen((i + 882) / rate, x[i:i + 882], rate)]
        assert heard == []


@pytest.mark.parametrize("look", [LIVE, OFFLINE])
def test_the_notes_do_not_depend_on_how_the_stream_is_cut(look: str) -> None:
    """64-sample blocks, 20 ms blocks, a second at a time or the whole phrase at once: the same
    notes at the same times (the spectra, the model's context and the gates are all per hop)."""
    played = phrase_notes(start=0.5, gap=4.0, rng=np.random.default_rng(4))
    x = render_notes(played, 22050, 13.0)
    heard = []
    for block in (64, 441, 22050, len(x)):
        ear = Transcriber(22050, look=look)
        heard.append([(round(n.time, 4), n.pitch, n.velocity) for i in range(0, len(x), block)
                      for n in ear.feed(x[i:i + block])])
    assert [p for _, p, _ in heard[0]] == [n.pitch for n in played]
    assert all(h == heard[0] for h in heard[1:])


def test_the_resampler_hands_every_block_on_at_once() -> None:
    """44.1 kHz in 512-frame blocks → 22.05 kHz: each block gives its 256 samples at once (soxr's
    HQ stream held up to 830 back, in bursts), and an impulse comes out within a millisecond."""
    from audio.resample import Resampler

    resampler = Resampler(44100, 22050)
    x = np.zeros(44100, dtype=np.float32)
    x[10000] = 1.0
    outs = [resampler(x[i:i + 512]) for i in range(0, len(x), 512)]
    assert all(abs(len(o) - 256) <= 1 for o in outs[1:-1])  # the last block is 68 frames
    y = np.concatenate(outs)
    assert abs(int(np.argmax(np.abs(y))) * 2 - 10000) <= 44  # 1 ms at 44.1 kHz


def swells(rate: int, pitches: list[int], attack: float = 0.15) -> np.ndarray:
    """Bowed or blown notes: each a plain tone swelling in over ``attack`` seconds, 1 s apart."""
    t = np.arange(int(0.8 * rate)) / rate
    x = np.zeros(int((len(pitches) + 1) * rate), dtype=np.float32)
    for i, p in enumerate(pitches):
        f0 = 440.0 * 2 ** ((p - 69) / 12)
        tone = sum(np.sin(2 * np.pi * k * f0 * t) / k for k in range(1, 6))
        start = int((0.5 + i) * rate)
        x[start:start + len(t)] += 0.1 * np.minimum(1.0, t / attack) * np.minimum(1.0, (0.8 - t) / 0.05) * tone
    return x


@pytest.mark.parametrize("look", [LIVE, OFFLINE])
def test_a_note_both_ears_hear_is_given_once(look: str) -> None:
    """Tones swelling in over 150 ms from silence: the onset ear finds each one, and so does the
    model; the transcriber gives each once, at its time."""
    from audio.logspectrum import LogSpectrum
    from audio.note_model import NoteModel, default
    from audio.onset_ear import LIVE_WINDOW, OFFLINE_WINDOW, OnsetEar

    pitches = [55, 62, 67, 72]
    x = swells(22050, pitches)
    alone = OnsetEar(LIVE_WINDOW if look == LIVE else OFFLINE_WINDOW)
    assert [c.pitch for i in range(0, len(x), 441) for c in alone.feed(x[i:i + 441])] == pitches
    ear, notes = hear(x, 22050, block=441, look=look)
    judged = NoteModel(default(look))(LogSpectrum().feed(x))  # the model alone, on the same stream
    assert all(judged.onset[:, p - 21].max() >= ear.threshold for p in pitches)
    assert [n.pitch for n in notes] == pitches
    assert all(abs(n.time - (0.5 + i)) < 0.05 for i, n in enumerate(notes))


def test_velocity_follows_level_from_the_floor_to_full_scale() -> None:
    levels = [-80.0, -60.0, -30.0, -6.0, 0.0, 6.0]
    velocities = [velocity_from_level(db) for db in levels]
    assert velocities == sorted(velocities) and velocities[0] == velocities[1] == 1
    assert velocities[-2] == velocities[-1] == 127
