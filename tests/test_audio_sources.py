"""Audio input sources: files, arrays and live input, and how they fail (audio/sources.py)."""

from __future__ import annotations

import importlib.abc
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import soundfile

import installations

from audio.device import AudioDeviceUnavailable
from audio.segment import Segmenter
from audio.sources import (
    ANALYSIS_RATE,
    MAX_FILE_RATE,
    ArraySource,
    AudioFileError,
    FileSource,
    LiveInput,
    RingBuffer,
    load_audio,
)
from audio_fixtures import SR, noise, tone, write_wav
from bench._sampled import SOUNDFONT, fluidsynth, have_sampler
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from midi.files import write_notes
from midi.notes import NoteEvent


def peak_hz(x: np.ndarray, sr: int) -> float:
    spectrum = np.abs(np.fft.rfft(x * np.hanning(len(x))))
    return float(np.fft.rfftfreq(len(x), 1 / sr)[np.argmax(spectrum)])


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda p: p.write_bytes(b""), "empty file"),
        (lambda p: soundfile.write(p, np.zeros(0), SR), "no samples"),
        (lambda p: p.write_bytes(np.random.default_rng(1).bytes(5000)), "corrupt"),
        (lambda p: p.write_bytes(write_wav(p, tone(440, 0.5)).read_bytes()[:30]), "corrupt"),
    ],
    ids=["empty", "zero-length", "garbage", "header-cut"],
)
def test_unusable_files_raise_a_clear_error_naming_the_file(tmp_path: Path, make, message) -> None:
    path = tmp_path / "heard.wav"
    make(path)
    with pytest.raises(AudioFileError, match=message) as err:
        load_audio(path)
    assert str(path) in str(err.value)


def test_missing_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(AudioFileError, match="no such sound file"):
        FileSource(tmp_path / "nowhere.wav")


def test_nan_and_inf_samples_are_refused_with_their_count_and_place(tmp_path: Path) -> None:
    x = tone(440, 1.0).astype(np.float32)
    x[11025], x[15000] = np.nan, np.inf
    path = write_wav(tmp_path / "broken.wav", x, subtype="FLOAT")
    with pytest.raises(AudioFileError, match=r"2 NaN/inf samples \(first at 0\.500 s\)"):
        load_audio(path)


@pytest.mark.parametrize("scale", [1e4, 1e18, 1e30])
def test_samples_far_beyond_full_scale_are_refused_with_their_count_and_place(tmp_path: Path, scale: float) -> None:
    # Finite junk past +60 dB overflowed the offline ear's spectra (×1e18: a scipy traceback).
    x = tone(440, 1.0).astype(np.float32)
    x[11025:11035] = scale
    path = write_wav(tmp_path / "loud.wav", x, subtype="FLOAT")
    with pytest.raises(AudioFileError, match=r"loud\.wav: 10 samples beyond ±1000, \+60 dB over full scale \(first at 0\.500 s\)"):
        load_audio(path)


def test_a_double_file_far_past_full_scale_is_told_from_nan(tmp_path: Path) -> None:
    """1e300 in a 64-bit float file became inf when read as float32, and was refused as NaN/inf."""
    x = tone(440, 1.0)
    x[11025:11028] = 1e300
    x[15000] = np.nan
    path = write_wav(tmp_path / "double.wav", x, subtype="DOUBLE")
    with pytest.raises(AudioFileError, match=r"double\.wav: 1 NaN/inf samples \(first at 0\.680 s\)"):
        load_audio(path)
    x[15000] = 0.0
    write_wav(path, x, subtype="DOUBLE")
    with pytest.raises(AudioFileError, match=r"double\.wav: 3 samples beyond ±1000, .* \(first at 0\.500 s\)"):
        load_audio(path)
    x[11025:11028] = 0.5
    assert load_audio(write_wav(path, x, subtype="DOUBLE")).dtype == np.float32


def test_a_float_file_a_little_past_full_scale_is_heard(tmp_path: Path) -> None:
    x = (tone(440, 1.0) * 900.0).astype(np.float32)  # loud, but within the +60 dB bound
    np.testing.assert_allclose(load_audio(write_wav(tmp_path / "hot.wav", x, subtype="FLOAT")), x, atol=1e-2)


def test_the_offline_run_refuses_a_far_too_loud_file_in_one_line(tmp_path: Path, capsys) -> None:
    from creatures.cli import main

    x = np.zeros(SR, np.float32)
    x[SR // 2:] = 1e30 * np.sin(2 * np.pi * 300 * np.arange(SR - SR // 2) / SR)
    path = write_wav(tmp_path / "loud.wav", x, subtype="FLOAT")
    code = main(["offline", "soundcreatures", "--audio", str(path), "--out", str(tmp_path / "o"), "--duration", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "loud.wav" in err[0] and "beyond ±1000" in err[0]


def test_file_cut_inside_the_data_keeps_what_was_recorded_and_says_so(tmp_path: Path) -> None:
    """A WAV holding less than its header promises (a recorder that crashed) is heard up to
    where it ends; it was heard silently, and the creatures falling quiet early had no cause."""
    x = tone(440, 1.0)
    data = write_wav(tmp_path / "full.wav", x).read_bytes()
    cut = tmp_path / "cut.wav"
    cut.write_bytes(data[: len(data) // 2])
    said: list[str] = []
    y = load_audio(cut, say=said.append)
    assert 0.45 * SR < len(y) < 0.55 * SR
    np.testing.assert_allclose(y, x[: len(y)], atol=1 / 2**15)
    assert len(said) == 1 and "cut.wav: cut short: it holds 0.5 s of the 1.0 s" in said[0]
    said.clear()
    load_audio(cut, seconds=0.2, say=said.append)  # the part a short run hears is whole
    assert said == []
    load_audio(write_wav(tmp_path / "whole.wav", x), say=said.append)
    assert said == []


def test_a_wav_cut_before_its_first_sample_is_one_line_not_a_traceback(tmp_path: Path, capsys) -> None:
    """A recorder that stopped as it began leaves a WAV header and no sound: the offline run
    ended in a ZeroDivisionError traceback (the header's promise divided by the 0 bytes held)."""
    from creatures.cli import main

    data = write_wav(tmp_path / "full.wav", tone(440, 2.0)).read_bytes()
    cut = tmp_path / "cut.wav"
    cut.write_bytes(data[:44])  # RIFF, fmt and the data chunk's header: not one sample
    code = main(["offline", "exchange", "--audio", str(cut), "--out", str(tmp_path / "o"), "--duration", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "cut.wav: cut short: it holds no samples of the 2.0 s its header promises" in err[0]
    assert not (tmp_path / "o").exists()


@pytest.mark.skipif(shutil.which("espeak-ng") is None, reason="espeak-ng is not installed")
def test_a_streamed_wav_whose_header_gives_no_length_is_heard_whole_and_not_said_cut(tmp_path: Path) -> None:
    """A WAV written to a pipe cannot have its lengths patched in: ``espeak-ng --stdout``
    writes 0x7ffff000, ffmpeg 0xffffffff. Such a file was said to hold "1.6 s of the 48,695.7 s
    its header promises", cut short, when it holds all there is."""
    spoken = tmp_path / "spoken.wav"
    with spoken.open("wb") as handle:
        subprocess.run(["espeak-ng", "--stdout", "the creatures sing again"], stdout=handle, check=True)
    whole = soundfile.read(spoken)[0]
    streamed = bytearray(spoken.read_bytes())
    streamed[4:8] = streamed[40:44] = (0xFFFFFFFF).to_bytes(4, "little")
    (tmp_path / "ffmpeg.wav").write_bytes(streamed)
    for path in (spoken, tmp_path / "ffmpeg.wav"):
        said: list[str] = []
        heard = load_audio(path, samplerate=22050, say=said.append)
        assert said == [] and len(heard) == len(whole)


@pytest.mark.parametrize("fmt", ["AIFF", "OGG"])
def test_an_aiff_or_ogg_cut_short_is_heard_up_to_there_and_said(tmp_path: Path, fmt: str) -> None:
    """Only a WAV's cut was said: an AIFF holding half of what its header promises, or an Ogg
    stream cut before its end-of-stream page, was heard up to there in silence."""
    x = tone(440.0, 6.0, SR) + noise(6.0, np.random.default_rng(2), rms=0.01)  # a room: Vorbis pages fill
    path = tmp_path / f"cut.{fmt.lower()}"
    soundfile.write(path, x, SR, format=fmt)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    said: list[str] = []
    y = load_audio(path, say=said.append)
    assert 1.5 * SR < len(y) < 3.5 * SR
    lacks = {"AIFF": "of the 6.0 s its header promises", "OGG": "and ends without its end-of-stream page"}[fmt]
    assert said == [f"{path}: cut short: it holds {len(y) / SR:.1f} s {lacks}; heard up to there"]
    said.clear()
    load_audio(path, seconds=0.5, say=said.append)  # the part a short run hears is whole
    assert said == []


@pytest.mark.skipif(not have_sampler(), reason="needs fluidsynth and the GM soundfont")
def test_a_midi_file_and_its_render_given_the_wrong_way_round_are_each_named_for_what_they_are(
        tmp_path: Path, capsys) -> None:
    """A phrase and its fluidsynth render side by side, given to the wrong flags: the MIDI file
    was "unreadable or corrupt (Format not recognised)" and the WAV "malformed MIDI file (MThd not
    found…)", as if either were damaged; each is now said to be the other kind, with the flag
    that takes it."""
    from creatures.cli import main

    phrase = tmp_path / "phrase.mid"
    write_notes(phrase, [NoteEvent(0.2 + 0.5 * i, p, 90, 0, 0.4) for i, p in enumerate((60, 64, 67))])
    render = tmp_path / "phrase.wav"
    fluidsynth(SOUNDFONT, phrase, render, 44100)
    for flag, path, said in (
            ("--audio", phrase, "a MIDI file, not a sound file (an offline run takes MIDI with --midi)"),
            ("--midi", render, "a WAV sound file, not a MIDI file (an offline run takes sound with --audio)")):
        code = main(["offline", "exchange", flag, str(path), "--out", str(tmp_path / "o"), "--duration", "1"])
        assert code == 2 and capsys.readouterr().err.strip().splitlines() == [f"creatures: {path}: {said}"]
        assert not (tmp_path / "o").exists()


def test_a_flac_cut_short_keeps_what_decodes(tmp_path: Path) -> None:
    """A FLAC cut inside its data fails in the decoder part-way; one read of the whole file
    returned only the error, and the whole recording was refused as corrupt."""
    x = tone(440.0, 6.0, SR, harmonics=1)
    path = tmp_path / "cut.flac"
    soundfile.write(path, x, SR, format="FLAC")
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    said: list[str] = []
    y = load_audio(path, say=said.append)
    assert 2.5 * SR < len(y) < 3.5 * SR
    np.testing.assert_allclose(y, x[: len(y)], atol=1e-4)
    assert len(said) == 1 and "cut.flac: cut short: it decodes to" in said[0] and "6.0 s" in said[0]


def test_an_ogg_cut_short_is_refused_with_the_likely_cause(tmp_path: Path) -> None:
    """libsndfile finds no samples at all in an Ogg file cut short (it reads the length from
    the end); the message said only "zero-length recording"."""
    path = tmp_path / "cut.ogg"
    soundfile.write(path, tone(440.0, 6.0, SR, harmonics=1), SR, format="OGG")
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(AudioFileError, match="cut.ogg: cut short: it holds no samples and ends without its end-of"):
        load_audio(path)


def test_the_offline_run_says_its_recording_was_cut_short(tmp_path: Path) -> None:
    data = write_wav(tmp_path / "full.wav", tone(440, 2.0)).read_bytes()
    cut = tmp_path / "cut.wav"
    cut.write_bytes(data[: len(data) // 2])
    summary = run_offline(load_installation(installations.path("soundcreatures")), tmp_path / "o", audio=cut,
                          duration=3.0)
    assert any("cut.wav: cut short" in m for m in summary.messages)


def test_a_part_of_a_long_file_is_read_exactly_as_the_whole_would_give_it(tmp_path: Path) -> None:
    """``seconds`` bounds what is read (an offline run of 5 s read a whole hour first), and the
    samples up to it are those of the whole file, resampled (44.1 kHz in)."""
    rng = np.random.default_rng(3)
    x = 0.1 * rng.standard_normal(44100 * 12)
    path = write_wav(tmp_path / "long.wav", x, 44100)
    whole, part = load_audio(path), load_audio(path, seconds=2.0)
    assert 2 * ANALYSIS_RATE <= len(part) <= 3.01 * ANALYSIS_RATE < len(whole)
    np.testing.assert_array_equal(part[: 2 * ANALYSIS_RATE], whole[: 2 * ANALYSIS_RATE])
    assert len(load_audio(path, seconds=60.0)) == len(whole)  # a file shorter than asked: all of it


@pytest.mark.parametrize(
    "subtype, tolerance", [("PCM_U8", 1 / 2**7), ("PCM_24", 1e-6), ("PCM_16", 1 / 2**15)]
)
def test_integer_wavs_read_as_floats(tmp_path: Path, subtype: str, tolerance: float) -> None:
    x = tone(440, 0.5, rms=0.3)
    y = load_audio(write_wav(tmp_path / "x.wav", x, subtype=subtype))
    np.testing.assert_allclose(y, x, atol=tolerance)


def test_96_khz_is_resampled_to_the_analysis_rate(tmp_path: Path) -> None:
    x = tone(1000.0, 1.0, 96000, harmonics=1)
    y = load_audio(write_wav(tmp_path / "hi.wav", x, 96000))
    assert abs(len(y) - ANALYSIS_RATE) <= 1
    assert peak_hz(y, ANALYSIS_RATE) == pytest.approx(1000.0, abs=2.0)


def test_a_header_claiming_a_rate_no_recorder_makes_is_refused_not_heard_as_nothing(tmp_path: Path) -> None:
    """A damaged header's rate of 2 GHz made six seconds of a phrase 0.1 ms long: the run heard
    nothing, silently. Only a rate below 1 kHz was refused; above :data:`MAX_FILE_RATE` is too."""
    x = tone(440.0, 6.0, 44100)
    data = bytearray(write_wav(tmp_path / "phrase.wav", x, 44100).read_bytes())
    data[24:32] = (2_000_000_000).to_bytes(4, "little") + (0xFFFFFFFF).to_bytes(4, "little")  # rate, bytes a second
    (tmp_path / "damaged.wav").write_bytes(data)
    with pytest.raises(AudioFileError, match=r"damaged.wav: sample rate 2,000,000,000 Hz is above 768,000 Hz "
                                             r"\(a damaged header\?\)"):
        load_audio(tmp_path / "damaged.wav")
    y = load_audio(write_wav(tmp_path / "dxd.wav", tone(440.0, 0.5, MAX_FILE_RATE), MAX_FILE_RATE))
    assert abs(len(y) - ANALYSIS_RATE // 2) <= 1 and peak_hz(y, ANALYSIS_RATE) == pytest.approx(440.0, abs=3.0)


@pytest.mark.skipif(not have_sampler(), reason="needs fluidsynth and the GM soundfont")
def test_channels_that_cancel_when_mixed_are_said_not_heard_as_silence_in_silence(tmp_path: Path) -> None:
    """One microphone recorded on both channels, one through a balanced lead wired the other way
    round, mixes to nothing: the run heard not one of the phrase's notes and said nothing. Now it
    says why; the stereo render as it is, its channels inverted (a sampled piano's two sides
    differ: 3 dB), and two channels of unrelated noise are not said."""
    phrase = tmp_path / "phrase.mid"
    write_notes(phrase, [NoteEvent(0.2 + 0.5 * i, p, 90, 0, 0.4) for i, p in enumerate((60, 64, 67))])
    fluidsynth(SOUNDFONT, phrase, tmp_path / "render.wav", 44100)
    stereo, rate = soundfile.read(tmp_path / "render.wav")
    soundfile.write(tmp_path / "wide.wav", stereo * [1.0, -1.0], rate, subtype="PCM_16")
    one = stereo.mean(axis=1, keepdims=True)
    soundfile.write(tmp_path / "inverted.wav", one * [1.0, -1.0], rate, subtype="PCM_16")
    noisy = np.random.default_rng(3).normal(0.0, 0.1, (rate, 2))
    soundfile.write(tmp_path / "noise.wav", noisy, rate, subtype="PCM_16")
    said: list[str] = []
    for name in ("render.wav", "wide.wav", "noise.wav", "inverted.wav"):
        load_audio(tmp_path / name, say=said.append)
    assert len(said) == 1 and said[0].startswith(f"{tmp_path / 'inverted.wav'}: its 2 channels cancel when mixed")


def test_a_clipped_recording_is_said_with_where_it_first_clips(tmp_path: Path) -> None:
    """A recording made too hot (a tone driven 3× past full scale from 0.5 s) was heard with
    nothing said: the transcriber counted its clipped samples and takes no note from a clipped
    tone's own partials, so notes went missing with no word why. A tone just under full scale is
    not said."""
    x = tone(220.0, 1.0, 44100, harmonics=1)
    hot = np.clip(np.where(np.arange(len(x)) >= 22050, 3.0, 0.9) * x / np.abs(x).max(), -1.0, 1.0)
    said: list[str] = []
    load_audio(write_wav(tmp_path / "hot.wav", hot, 44100, subtype="FLOAT"), say=said.append)
    load_audio(write_wav(tmp_path / "fine.wav", 0.99 * x / np.abs(x).max(), 44100, subtype="FLOAT"), say=said.append)
    assert len(said) == 1 and said[0].startswith(f"{tmp_path / 'hot.wav'}: "), said
    count = int(np.count_nonzero(np.abs(hot) >= 0.999))
    assert f"{count:,} samples at full scale, the first at 0.50 s: clipped" in said[0] and count > 10_000


def test_multichannel_is_mixed_down(tmp_path: Path) -> None:
    a, b = tone(300.0, 0.5, harmonics=1), tone(700.0, 0.5, harmonics=1)
    quad = np.stack([a, b, a, -a], axis=1)
    y = load_audio(write_wav(tmp_path / "quad.wav", quad, subtype="FLOAT"))
    np.testing.assert_allclose(y, (a + b) / 4, atol=1e-6)


@pytest.mark.parametrize("fmt", ["FLAC", "OGG"])
def test_flac_and_ogg_read_through_the_same_path(tmp_path: Path, fmt: str) -> None:
    x = tone(440.0, 1.0, 44100, harmonics=1)
    path = tmp_path / f"x.{fmt.lower()}"
    soundfile.write(path, x, 44100, format=fmt)
    y = load_audio(path)
    assert abs(len(y) - ANALYSIS_RATE) <= 1
    assert peak_hz(y, ANALYSIS_RATE) == pytest.approx(440.0, abs=2.0)


def test_file_and_array_sources_give_the_same_blocks(tmp_path: Path) -> None:
    x = tone(440.0, 0.3).astype(np.float32)
    path = write_wav(tmp_path / "x.wav", x, subtype="FLOAT")
    from_file = list(FileSource(path, block_size=1000))
    from_array = list(ArraySource(x, SR, block_size=1000))
    assert [len(b) for b in from_file] == [1000] * 6 + [615]
    np.testing.assert_array_equal(np.concatenate(from_file), np.concatenate(from_array))


def test_ring_buffer_wraps_and_counts_overruns() -> None:
    ring = RingBuffer(10)
    out = np.zeros(10, np.float32)
    assert ring.write(np.arange(6, dtype=np.float32))
    assert ring.read(out[:4]) == 4
    assert ring.write(np.arange(6, 14, dtype=np.float32))  # wraps round the end
    assert not ring.write(np.zeros(3, np.float32))  # only 0 free: dropped whole
    assert ring.overruns == 1
    assert ring.read(out) == 10
    np.testing.assert_array_equal(out, np.arange(4, 14))


def test_live_loop_survives_bad_blocks() -> None:
    """Drive the callback as PortAudio would, with NaN/inf, odd sizes and overflows."""
    live = LiveInput(buffer_seconds=0.1)
    live.prepare(44100)  # device rate differs: blocks are resampled to 22.05 kHz
    seg = Segmenter(ANALYSIS_RATE, adaptive=False)
    rng = np.random.default_rng(3)
    heard = 0
    for i in range(200):
        block = rng.standard_normal((int(rng.integers(1, 2048)), 1)).astype(np.float32) * 0.1
        if i % 7 == 0:
            block[::3] = np.nan
        if i % 11 == 0:
            block[1::5] = -np.inf
        live.callback(block, len(block), None, "input overflow" if i % 50 == 0 else None)
        if i % 4 == 0:  # the creature reads less often than blocks arrive
            out = live.read()
            assert np.isfinite(out).all()
            heard += len(out)
            seg.feed(out)
    assert live.bad_samples > 0
    assert live.overruns > 0  # 0.1 s of ring cannot hold four 2048-frame blocks
    assert live.driver_overflows == 4
    assert heard > 0


@pytest.mark.parametrize("junk", [1e4, -1e30, 3e38])
def test_live_samples_far_beyond_full_scale_are_zeroed_and_counted(junk: float) -> None:
    """A driver writing junk (finite but huge) is treated like one writing NaN: the creature's
    thread never sees it, so its spectra cannot overflow."""
    live = LiveInput(buffer_seconds=0.1)
    live.prepare(ANALYSIS_RATE)  # no resampling: exact counts
    block = np.full((256, 1), 0.5, np.float32)
    block[::4] = junk
    live.callback(block, len(block), None, None)
    out = live.read()
    assert live.bad_samples == 64
    assert np.abs(out).max() <= 1.0 and np.count_nonzero(out == 0.0) == 64


def test_unknown_device_is_named() -> None:
    # Whether PortAudio is missing, lists no devices or lacks this one, the message says so.
    with pytest.raises(AudioDeviceUnavailable, match="no such microphone|no audio input|PortAudio"):
        LiveInput("no such microphone").start()


def test_reading_before_start_says_so() -> None:
    with pytest.raises(AudioDeviceUnavailable, match="start"):
        LiveInput().read()


class _NoPortAudio(importlib.abc.MetaPathFinder):
    """Make `import sounddevice` fail as it does when libportaudio2 is missing."""

    def find_spec(self, name, path, target=None):
        if name == "sounddevice":
            raise OSError("PortAudio library not found")
        return None


def test_missing_portaudio_gives_a_clear_message_and_files_still_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delitem(sys.modules, "sounddevice", raising=False)
    monkeypatch.setattr(sys, "meta_path", [_NoPortAudio(), *sys.meta_path])
    with pytest.raises(AudioDeviceUnavailable, match="PortAudio library not found.*libportaudio2"):
        LiveInput().start()
    x = tone(440.0, 0.2)
    assert len(load_audio(write_wav(tmp_path / "x.wav", x))) == len(x)


def test_live_input_through_a_real_device() -> None:
    try:
        live = LiveInput(block_size=512)
        live.start()
    except AudioDeviceUnavailable as exc:
        pytest.skip(f"no live audio input here: {exc}")
    try:
        got = []
        deadline = time.monotonic() + 3.0
        while sum(map(len, got)) < ANALYSIS_RATE // 10 and time.monotonic() < deadline:
            got.append(live.read())
            time.sleep(0.01)  # waiting for the device, not measuring time
    finally:
        live.stop()
    heard = np.concatenate(got)
    assert len(heard) >= ANALYSIS_RATE // 10, "the device delivered no audio within 3 s"
    assert heard.dtype == np.float32 and np.isfinite(heard).all()
