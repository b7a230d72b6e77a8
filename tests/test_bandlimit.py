"""Band-limited scanning (audio/bandlimit.py): a high note's energy stays on its harmonics, a note
with nothing above the band sounds as before, and the projection is the DFT's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from audio.bandlimit import FULL_BAND, above_band, band_limit, dft_basis, harmonics, kept_harmonics
from audio.scanned import ScannedString, StringParameters, default_trajectory
from audio.voices import VoicePool, midi_to_hz


def off_harmonics(signal: np.ndarray, f0: float, sample_rate: float, *, width: float = 20.0) -> float:
    """Share of ``signal``'s energy (above 20 Hz, Hann-windowed) farther than ``width`` Hz from
    every harmonic of ``f0``: what aliasing puts between a note's partials. ``width`` holds the
    sidebands of the shape's own motion (modes below 15 Hz)."""
    power = np.abs(np.fft.rfft(signal * np.hanning(len(signal)))) ** 2
    freqs = np.fft.rfftfreq(len(signal), 1.0 / sample_rate)
    k = np.round(freqs / f0)
    near = (k >= 1) & (np.abs(freqs - k * f0) <= width)
    audible = freqs > 20.0
    return float(power[audible & ~near].sum() / power[audible].sum())


def played(pitch: float, sample_rate: float, *, ring: bool = False, naive: bool = False,
           monkeypatch: pytest.MonkeyPatch | None = None) -> np.ndarray:
    """A second of a 128-mass string plucked at ``pitch``, band-limited, or (``naive``) read as
    before band-limiting (every harmonic of the shape, whatever the band)."""
    if naive:
        monkeypatch.setattr(ScannedString, "band", lambda self: (0, 0, True))
    string = ScannedString(StringParameters(ring=ring), sample_rate=sample_rate)
    string.note_on(midi_to_hz(pitch), 1.0)
    return string.render_raw(np.empty(int(sample_rate)))


@pytest.mark.parametrize("ring", [False, True])
@pytest.mark.parametrize("pitch, before", [(96, 0.08), (108, 0.6)])
def test_a_high_note_at_22050_keeps_its_energy_on_its_harmonics(pitch, before, ring, monkeypatch):
    """Read naively, 8.8 % of a MIDI 96's energy and 64 % of a 108's fall between their
    harmonics at 22050 Hz (the numbers docs/config.md gave); band-limited, under 0.01 %."""
    f0 = midi_to_hz(pitch)
    assert off_harmonics(played(pitch, 22050, ring=ring), f0, 22050) < 1e-4
    assert off_harmonics(played(pitch, 22050, ring=ring, naive=True, monkeypatch=monkeypatch), f0, 22050) > before


@pytest.mark.parametrize("pitch", [84, 96, 108])
def test_a_voice_pool_at_22050_does_not_alias(pitch):
    """The path a creature's voice takes (the string bank): the same bound."""
    pool = VoicePool(2, StringParameters(), sample_rate=22050, block_size=512)
    pool.note_on(pitch, 1.0)
    out = pool.render(np.empty(22050))
    assert off_harmonics(out, midi_to_hz(pitch), 22050) < 1e-4


# A second of each note rendered by efa5654 (before band-limiting), every 2,500th sample and the RMS.
BEFORE = {
    (48, 22050, False): ([0.0, -0.09449677323017, -0.095635537487372, -0.09126907587842, -0.13197223180813,
                          0.287085527768425, -0.028657217996187, -0.012632005551354, 0.005900551719913],
                         0.16013609799204673),
    (64, 48000, True): ([0.0, -0.088508349275754, 0.513481629686755, -0.100785512149004, -0.094343333007488,
                         -0.087325396124957, -0.079863689409992, 0.204260973985813, 0.092548256432552,
                         -0.066954655594844, -0.05769796571427, -0.048122595899956, -0.038796573981389,
                         0.102978215189935, -0.212078509592529, 0.158247553966843, -0.006282130829341,
                         0.002119912360444, 0.102661802442225, -0.203374044838176], 0.16055372244509367),
}


@pytest.mark.parametrize("pitch, sample_rate, ring", list(BEFORE))
def test_a_note_with_nothing_above_the_band_sounds_as_before(pitch, sample_rate, ring):
    """MIDI 48 at 22050 Hz (its 64th harmonic at 8.4 kHz) and MIDI 64 at 48 kHz (21.1 kHz): the
    samples efa5654 rendered, to 1e-12."""
    samples, rms = BEFORE[pitch, sample_rate, ring]
    out = played(pitch, sample_rate, ring=ring)
    np.testing.assert_allclose(out[::2500], samples, rtol=0, atol=1e-12)
    assert np.sqrt(np.mean(out**2)) == pytest.approx(rms, rel=1e-12)


def test_a_limited_note_keeps_the_harmonics_within_the_band(monkeypatch):
    """MIDI 84 at 22050 Hz keeps its 9 harmonics below 9.9 kHz: their levels are the naive
    reading's, to 0.1 dB, while what lay between them goes."""
    f0, sample_rate = midi_to_hz(84), 22050
    limited = played(84, sample_rate)
    naive = played(84, sample_rate, naive=True, monkeypatch=monkeypatch)
    t = np.arange(sample_rate) / sample_rate
    window = np.hanning(sample_rate)

    def level(signal: np.ndarray, k: int) -> float:
        return 20.0 * np.log10(np.abs(np.sum(signal * window * np.exp(-2j * np.pi * k * f0 * t))))

    kept = int(kept_harmonics(f0 / sample_rate))
    assert kept == 9
    for k in range(1, kept + 1):
        assert level(limited, k) == pytest.approx(level(naive, k), abs=0.1)
    assert off_harmonics(naive, f0, sample_rate) > 100 * off_harmonics(limited, f0, sample_rate)


@pytest.mark.parametrize("masses, ring", [(1, True), (1, False), (2, False), (7, True), (8, True), (40, True),
                                          (128, False), (1024, False)])
def test_the_projection_is_the_dft_with_the_harmonics_above_zeroed(masses, ring):
    """For every count of harmonics kept that is projected (fewer than FULL_BAND), the table read
    along the trajectory and projected equals numpy's FFT of it with the harmonics above zeroed
    (odd and even tables, kept or removed side: 40 masses on a ring project the removed side)."""
    rng = np.random.default_rng(masses)
    trajectory = default_trajectory(masses, ring=ring)
    n = len(trajectory)
    shape = rng.normal(size=masses)
    read = np.where(trajectory >= 0, shape[np.maximum(trajectory, 0)], 0.0)
    spectrum = np.fft.rfft(read)
    for kept in range(0, n // 2 + 2, max(1, n // 40)):
        first, stop, keep = (int(v) for v in harmonics(np.array(kept), n))
        if not above_band(kept, n):
            assert first == stop  # nothing above the band, or a band of FULL_BAND harmonics: not projected at all
            continue
        assert stop - first <= n // 4 + 1  # the smaller side
        table = np.empty(n)
        band_limit(table, shape, trajectory, dft_basis(n), first, stop, keep, np.empty((5, n)))
        expected = spectrum.copy()
        expected[kept + 1:] = 0.0
        np.testing.assert_allclose(table, np.fft.irfft(expected, n), rtol=0, atol=1e-12)


def test_a_note_just_below_the_nyquist_still_sounds_its_fundamental():
    """At 0.47 × the rate no harmonic but the fundamental fits the band, which aliases nowhere:
    the string sounds it (a sine at f₀), not silence."""
    sample_rate = 22050
    f0 = 0.47 * sample_rate
    string = ScannedString(StringParameters(), sample_rate=sample_rate, frequency=f0)
    string.pluck(amplitude=1.0)
    out = string.render_raw(np.empty(sample_rate))
    assert string.band() == (0, 2, True)  # the mean and the fundamental
    assert np.sqrt(np.mean(out[2000:] ** 2)) > 0.01
    assert off_harmonics(out, f0, sample_rate) < 1e-3



def test_a_note_whose_band_holds_full_band_harmonics_is_read_as_it_is_and_folds_inaudibly():
    """Projection is for notes whose band holds fewer than FULL_BAND harmonics: the lowest note
    above them at 22050 Hz (MIDI 74, K = 16) reads its shape as it is, and what its shape has
    above the band folds to under 0.005 % of its energy (−43 dB); the bank's mid-range voices
    cost what they did."""
    pitch = 74
    f0 = midi_to_hz(pitch)
    assert int(kept_harmonics(f0 / 22050)) == FULL_BAND
    string = ScannedString(StringParameters(), sample_rate=22050)
    string.note_on(f0, 1.0)
    first, stop, _ = string.band()
    assert first == stop
    assert off_harmonics(played(pitch, 22050), f0, 22050) < 5e-5
    assert not above_band(kept_harmonics(midi_to_hz(87) / 48000), 128)  # bench voice's top note at 48 kHz


PREPARED = """
import numpy as np
from numba.core import event
from audio import string_bank
from audio.scanned import ScannedString, StringParameters
from audio.voices import VoicePool, midi_to_hz

string_bank.prepare(22050)
compiled = []
class Heard(event.Listener):
    def on_start(self, ev): compiled.append(ev.data["dispatcher"].py_func.__name__)
    def on_end(self, ev): pass
event.register("numba:compile", Heard())
pool = VoicePool(2, StringParameters(), sample_rate=22050, block_size=512)
pool.note_on(100, 1.0)
pool.note_on(60, 1.0)
pool.render(np.empty(1024))
lone = ScannedString(StringParameters(ring=True), sample_rate=22050)
lone.note_on(midi_to_hz(100), 1.0)
lone.render_raw(np.empty(512))
print("compiled after prepare:", compiled)
"""


def test_prepare_compiles_what_a_band_limited_note_takes_before_the_show(tmp_path):
    """A fresh install's first live run compiled the band-limited kernels when the show first
    played a high note (the rehearsal had played none): one tick 13 s late. After
    ``string_bank.prepare`` (which the rehearsal calls) a high note and a low one, in a pool and
    on a lone ring, compile nothing; on an empty numba cache, in a process of its own."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    done = subprocess.run([sys.executable, "-c", PREPARED], capture_output=True, text=True, env=env, timeout=600,
                          cwd=Path(__file__).resolve().parents[1])
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "compiled after prepare: []", done.stdout
