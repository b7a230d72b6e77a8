"""Several pitches at once: harmonic salience with iterative estimation and cancellation.

The method is Klapuri's ("Multiple fundamental frequency estimation by summing harmonic
amplitudes", ISMIR 2006): the salience of a candidate fundamental ``f`` is a weighted sum of
the spectrum's largest magnitude near each of its harmonics ``m f``, with weights
``g(f, m) = (f + α) / (m f + β)`` that make a true fundamental outscore its octaves and
sub-octaves. The strongest candidate is taken, its harmonics are cancelled from a residual
spectrum (only their *smoothed* amplitudes, so a partial shared with another note is left
for it), and the search repeats until the accumulated salience, discounted by the polyphony
``j ** γ``, stops growing.

:mod:`audio.onset_ear` calls it on the spectrum of what *began* at an onset (the positive
difference between the spectrum just after and just before it), so notes still sounding from
before are not found again. Everything per frame is one matrix–vector product over the
whole candidate grid (MIDI 28–100 by default): each harmonic's search range is a few bins, so
a compiled gather of the largest peak in each range (``_partials``) is the search.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.ndimage import maximum_filter1d

ALPHA, BETA = 52.0, 320.0
"""Klapuri's harmonic weights for a 93 ms frame (2048 samples at 22.05 kHz), Hz."""
MAX_HARMONIC_HZ = 9000.0
"""Partials above this are not summed (the analysis rate's band, less its anti-alias edge)."""
STRETCH = 0.02
"""How far above ``m f`` a partial may lie (a fraction): a piano's strings are stiff, so its
partials run sharp (2nd partial of C7 ~1 % high, measured on the GM soundfont's piano)."""
SMOOTH = np.ones(3) / 3
"""The moving average over three harmonics that gives a found note's series its envelope."""


class HarmonicSalience:
    """The candidate grid, its harmonics' search ranges and weights, for one FFT size and rate.

    ``gamma``: the polyphony discount — 0.27 for 93 ms looks (Klapuri's table), 0.6 measured
    best for 46 ms ones (shorter frames hear fewer partials per note, so each further note must
    add more). ``range_db`` and ``power``: see :meth:`estimate`; the defaults are the best of a
    sweep on sampled piano (docs/hearing.md). ``min_ratio``: a later pitch must have this
    fraction of the first one's salience. ``support``: the fraction of a pitch's strongest
    partial its fundamental (or its 2nd and 3rd partials) must reach. ``octave_ratio``: the
    fraction of the first salience a pitch one or two octaves above a found one needs, since
    every partial of it is also one of the found note's (a guitar's strong 2nd partial was
    heard as a second note an octave up; measured: guitar lines F1 0.87 → 0.96, chords and
    piano unchanged).
    """

    def __init__(self, samplerate: int, n_fft: int, midi_range: tuple[int, int] = (28, 100), *,
                 gamma: float = 0.27, range_db: float = 25.0, power: float = 0.7, min_ratio: float = 0.3,
                 support: float = 0.2, octave_ratio: float = 0.5, max_harmonics: int = 20) -> None:
        self.samplerate, self.n_fft = int(samplerate), int(n_fft)
        self.gamma, self.range_db, self.power = float(gamma), float(range_db), float(power)
        self.min_ratio, self.support, self.octave_ratio = float(min_ratio), float(support), float(octave_ratio)
        self.pitches = np.arange(midi_range[0], midi_range[1] + 1)
        f0 = 440.0 * 2.0 ** ((self.pitches - 69) / 12.0)
        n_bins = n_fft // 2 + 1
        df = samplerate / n_fft
        freqs = np.outer(f0, np.arange(1, max_harmonics + 1))  # (pitches, harmonics)
        self.valid = freqs < min(MAX_HARMONIC_HZ, 0.45 * samplerate)
        self.bins = np.minimum(np.round(freqs / df).astype(int), n_bins - 1)
        low = self.bins - 1
        high = np.maximum(self.bins + 1, np.round(freqs * (1 + STRETCH) / df).astype(int))
        # Harmonic m of pitch p may lie in bins low[p, m] … high[p, m] (an empty range if it
        # is above the band).
        self.low = np.where(self.valid, np.maximum(low, 0), 1).astype(np.int64)
        self.high = np.where(self.valid, np.minimum(high, n_bins - 1), 0).astype(np.int64)
        # Partials among the first six a note must show: three; two above 500 Hz and one above
        # 1 kHz, where fewer fall below the band's edge, a piano's run sharpest and a flute has
        # little but its fundamental.
        self.needed = np.where(f0 > 1000.0, 1, np.where(f0 > 500.0, 2, 3))
        self.weights = np.where(self.valid, (f0[:, None] + ALPHA) / (freqs + BETA), 0.0)

    def estimate(self, spectrum: np.ndarray, *, floor: float | np.ndarray,
                 max_polyphony: int = 6) -> list[tuple[int, float]]:
        """The pitches in ``spectrum`` (linear magnitudes), strongest first, with the amplitude
        of each one's strongest partial.

        Only spectral peaks count (local maxima over ±2 bins, above ``floor`` — the noise that
        came with the sound — and within ``range_db`` of the strongest): a dense comb of a low
        candidate must not collect the spectrum between partials. Magnitudes are compressed
        (``** power``) so one loud partial does not outweigh a note's whole series. A pitch
        needs a strong partial at its fundamental or at both its 2nd and 3rd harmonics, and
        enough of its first six (else it is a sub-harmonic made of another note's partials).
        """
        floor = np.broadcast_to(np.asarray(floor, dtype=float), spectrum.shape)
        local = maximum_filter1d(spectrum, size=5, mode="nearest")
        top = spectrum.max() * 10 ** (-self.range_db / 20)
        at = np.flatnonzero((spectrum >= local) & (spectrum > floor) & (spectrum > top))
        compressed = spectrum[at] ** self.power
        residual = np.zeros(len(spectrum), dtype=compressed.dtype)  # the peaks' compressed magnitudes, 0 between
        residual[at] = compressed
        found: list[tuple[int, float]] = []
        total, best = 0.0, 0.0
        taken = np.zeros(len(self.pitches), dtype=bool)
        partials = np.empty(self.low.shape, dtype=residual.dtype)  # (pitches, harmonics): the largest peak in each range
        peaks = np.empty(self.low.shape, dtype=np.int64)  # and its bin
        for _ in range(2 * max_polyphony):
            if len(found) == max_polyphony or not len(at):
                break
            _partials(residual, self.low, self.high, partials, peaks)
            salience = (self.weights * partials).sum(axis=1)
            salience[taken] = -np.inf  # a pitch, or its semitone neighbours, found already
            k = int(np.argmax(salience))
            s = float(salience[k])
            if s <= 0.0 or (found and s < self.min_ratio * best):
                break
            above = any(self.pitches[k] - p in (12, 24) for p, _ in found)
            if above and s < self.octave_ratio * best:
                taken[k] = True  # all its partials are a found note's: it needs more to count
                continue
            j = len(found) + 1
            if found and (total + s) / j**self.gamma <= total / (j - 1) ** self.gamma:
                break
            taken[max(k - 1, 0): k + 2] = True
            amps = partials[k]
            strong = amps >= self.support * amps.max()
            if (strong[0] or (strong[1] and strong[2])) and np.count_nonzero(amps[:6]) >= self.needed[k]:
                found.append((int(self.pitches[k]), float(amps.max()) ** (1 / self.power)))
                best, total = max(best, s), total + s
            # Cancel its partials' smoothed amplitudes: a partial it shares with a note not
            # found yet keeps what stands above the series' envelope (Klapuri 2006).
            # (Each end padded with itself: np.pad(amps, 1, mode="edge") cost 20 times the smoothing.)
            smooth = np.convolve(np.concatenate((amps[:1], amps, amps[-1:])), SMOOTH, mode="valid")
            cancel = np.minimum(amps, smooth)
            for m in np.flatnonzero(amps > 0):
                peak = peaks[k, m]
                residual[peak] = max(residual[peak] - cancel[m], 0.0)
        return found


@numba.njit(cache=True, nogil=True)
def _partials(residual, low, high, partials, peaks):  # pragma: no cover
    """For each pitch and harmonic, the largest residual in its bin range (0 if none) and the
    first bin holding it."""
    for p in range(low.shape[0]):
        for m in range(low.shape[1]):
            value, where = 0.0, low[p, m]
            for b in range(low[p, m], high[p, m] + 1):
                if residual[b] > value:
                    value, where = residual[b], b
            partials[p, m], peaks[p, m] = value, where
