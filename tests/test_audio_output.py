"""Audio out: WAV files (atomic), the mixer, the live callback stream and its silent fallback."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import soundfile

import audio.device as device
from audio.device import AudioDeviceUnavailable, sounddevice_module
from audio.mixer import Mixer
from audio.output import LiveOutput, SilentOutput, WavOutput, open_output

SR = 48000


def test_wav_output_writes_rate_length_and_channels(tmp_path, rng):
    path = tmp_path / "creature.wav"
    blocks = [rng.uniform(-0.5, 0.5, size=(300, 2)) for _ in range(7)]
    with WavOutput(path, SR, channels=2, subtype="FLOAT") as wav:
        for block in blocks:
            wav.write(block)
        assert not path.exists()  # only renamed into place on close
    data, rate = soundfile.read(path)
    assert rate == SR and data.shape == (2100, 2)
    np.testing.assert_allclose(data, np.concatenate(blocks), atol=1e-7)
    assert not list(tmp_path.glob(".*.tmp"))


def test_wav_output_failure_keeps_the_previous_file(tmp_path):
    path = tmp_path / "take.wav"
    soundfile.write(path, np.zeros(100), SR)
    with pytest.raises(RuntimeError, match="boom"):
        with WavOutput(path, SR, channels=1) as wav:
            wav.write(np.ones(50) * 0.5)
            raise RuntimeError("boom")
    assert soundfile.info(path).frames == 100
    assert not list(tmp_path.glob(".*.tmp"))


FULL_DISK = textwrap.dedent("""
    import errno, resource, signal, sys
    from pathlib import Path
    import numpy as np
    import soundfile
    from audio.output import WavOutput

    path = Path(sys.argv[1])
    soundfile.write(path, np.zeros(100), 48000)  # the previous take
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # past the limit a write fails with EFBIG
    resource.setrlimit(resource.RLIMIT_FSIZE, (64 * 1024, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
    try:
        with WavOutput(path, 48000, channels=2) as wav:
            for _ in range(20):
                wav.write(np.zeros((16384, 2)))
    except OSError as exc:
        print("OSError", errno.errorcode[exc.errno], exc.filename)
""")


def test_a_wav_the_disk_cannot_hold_is_an_os_error_naming_it_and_the_previous_take_stays(tmp_path):
    """libsndfile writes from C: a write the file system refuses (a full disk; here a file-size
    limit, EFBIG) came out as ``LibsndfileError: System error.``, which no ``except OSError``
    took, and an offline run on a full disk ended in a traceback."""
    path = tmp_path / "take.wav"
    done = subprocess.run([sys.executable, "-c", FULL_DISK, str(path)], capture_output=True, text=True,
                          timeout=120, cwd=Path(__file__).resolve().parents[1])
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["OSError", "EFBIG", str(path)]
    assert soundfile.info(path).frames == 100  # the previous take, untouched
    assert not list(tmp_path.glob(".*.tmp"))  # nothing of the failed one left


def test_output_rejects_wrong_channel_count(tmp_path):
    with WavOutput(tmp_path / "x.wav", SR, channels=2) as wav:
        with pytest.raises(ValueError, match=r"\(frames, 2\)"):
            wav.write(np.zeros((10, 3)))


def test_mixer_sums_with_gain_and_equal_power_pan(rng):
    mixer = Mixer(3, block_size=128)
    mixer.set(0, gain=0.5, pan=-1.0)  # hard left
    mixer.set(1, gain=2.0, pan=1.0)  # hard right
    mixer.set(2, pan=0.0)  # centre: −3 dB each side
    blocks = rng.standard_normal((3, 100))
    out = mixer.mix(blocks)
    centre = blocks[2] / np.sqrt(2)
    np.testing.assert_allclose(out[:, 0], 0.5 * blocks[0] + centre, atol=1e-12)
    np.testing.assert_allclose(out[:, 1], 2.0 * blocks[1] + centre, atol=1e-12)
    assert np.shares_memory(out, mixer.mix(blocks))  # the same preallocated buffer each block
    with pytest.raises(ValueError, match="blocks must be"):
        mixer.mix(np.zeros((3, 129)))


def test_mixer_counts_the_samples_past_full_scale_that_the_output_clips():
    """Each voice is soft-limited but the sum of loud creatures is not: libsndfile writes 1.5
    as full scale. The mixer says how many samples went past it, and the loudest."""
    mixer = Mixer(2, block_size=64)
    mixer.set(0, gain=4.0, pan=-1.0)
    mixer.set(1, pan=1.0)
    quiet = np.full((2, 64), 0.2)
    mixer.mix(quiet)
    assert mixer.clipped == 0 and mixer.peak == pytest.approx(0.8)
    loud = quiet.copy()
    loud[0, :10] = -0.3  # 10 samples at −1.2 on the left
    mixer.mix(loud)
    assert mixer.clipped == 10 and mixer.peak == pytest.approx(1.2)


def test_live_output_degrades_to_silence_with_a_clear_message(monkeypatch, caplog):
    def missing():
        raise AudioDeviceUnavailable("live audio unavailable: PortAudio library not found; install PortAudio")

    monkeypatch.setattr(device, "sounddevice_module", missing)
    with pytest.raises(AudioDeviceUnavailable, match="PortAudio"):
        LiveOutput(SR, 2)
    with caplog.at_level("WARNING"), open_output(SR, 2) as out:
        assert isinstance(out, SilentOutput)
        assert "PortAudio library not found" in out.reason
        out.write(np.zeros((64, 2)))  # the installation keeps running
        assert out.frames_written == 64
    assert "continuing without sound" in caplog.text


def jack_running() -> bool:
    try:
        apis = sounddevice_module().query_hostapis()
    except AudioDeviceUnavailable:
        return False
    return any("JACK" in api["name"] and api["devices"] for api in apis)


@pytest.mark.jack
def test_live_output_runs_callbacks_under_jack():
    if not jack_running():
        pytest.skip("no JACK server running (start: jackd --no-realtime -d dummy -r 48000 -p 512)")
    rate = int(sounddevice_module().query_devices(kind="output")["default_samplerate"])
    with LiveOutput(rate, 2, blocksize=512) as live:
        tone = np.sin(2 * np.pi * 440 * np.arange(rate // 2) / rate)
        live.write(np.repeat(0.1 * tone[:, None], 2, axis=1).astype(np.float32))
        assert live.frames_written == rate // 2
        deadline = time.monotonic() + 5.0
        while live.ring.available() and time.monotonic() < deadline:
            time.sleep(0.01)  # waiting for the device to drain the ring, not timing anything
        assert live.ring.available() == 0
        assert live.callbacks >= (rate // 2) // 512
        drained, underruns = live.callbacks, live.underruns
        deadline = time.monotonic() + 5.0
        while live.callbacks < drained + 3 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert live.underruns >= underruns + 3  # nothing queued: the callback padded with silence and counted it


def test_two_creatures_mixed_to_a_wav_keep_their_places(tmp_path):
    """A scanned-string creature panned left and a sampler creature panned right, to a file."""
    from audio.sampler import Sampler
    from audio.scanned import ScannedString

    string = ScannedString(frequency=220.0)
    string.pluck(amplitude=0.5)
    sampler = Sampler(SR, block_size=512)
    sampler.play(sampler.add(0.5 * np.sin(2 * np.pi * 330.0 * np.arange(SR) / SR)))
    mixer = Mixer(2, block_size=512)
    mixer.set(0, pan=-1.0)
    mixer.set(1, pan=1.0)
    sources = np.empty((2, 512))
    with WavOutput(tmp_path / "colony.wav", SR, channels=2, subtype="FLOAT") as wav:
        for _ in range(SR // 512):
            string.render(512, out=sources[0])
            sampler.render(sources[1], amplitude=1.0, cutoff_hz=5000.0)
            wav.write(mixer.mix(sources))
    data, _ = soundfile.read(tmp_path / "colony.wav")
    assert data.shape == (SR // 512 * 512, 2)
    spectrum = np.abs(np.fft.rfft(data * np.hanning(len(data))[:, None], axis=0))
    string_bin, sampler_bin = (round(hz * len(data) / SR) for hz in (220.0, 330.0))
    left, right = spectrum[:, 0], spectrum[:, 1]
    assert left[string_bin] > 100 * left[sampler_bin]  # the string (no 330 Hz partial) on the left
    assert right[sampler_bin] > 100 * right[string_bin]  # the sampler's 330 Hz tone on the right
