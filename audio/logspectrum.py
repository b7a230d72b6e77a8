"""Streaming log-frequency spectra: what the note model (:mod:`audio.note_model`) hears.

Every hop (256 samples at the 22.05 kHz analysis rate, 11.6 ms) two magnitude spectra are taken
of the samples that *end* there — a long one (2048 samples) that resolves low pitches, and a short
one (512) that follows attacks — and each is pooled into log-frequency bands: thirds of a
semitone from MIDI 21 up for the long one, semitones from MIDI 45 up for the short one. Both
windows are asymmetric (a long rise, a short fall: the shape of low-delay codecs' windows), so
the newest samples weigh almost fully and an attack shows within a hop or two of arriving; a
symmetric window ending now would hide its last few milliseconds.

Each band's noise floor is followed (it falls to a quieter band at once and rises by 0.25 % a
frame, ~1.9 dB/s) and twice it is taken off before the magnitudes are compressed
(``log1p(1000 m)``), so a room's hum or a fan is not something the model must learn to ignore
at every level. The front-end is a causal stream: fed in one piece or in blocks of any size,
it gives the same frames (tested), which is what lets the model be trained offline on whole
renders and run live block by block.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.sparse import csr_array

from audio.rfft import magnitudes

RATE = 22050
"""Analysis rate: partials up to 10 kHz, and MIDI 108's fundamental (4.2 kHz) has two."""
HOP = 256
LONG, SHORT = 2048, 512
LONG_FALL, SHORT_FALL = 256, 128
"""Samples over which each window falls to zero at its newest end."""
LONG_LOW, LONG_STEP = 21.0, 1 / 3
"""The long spectrum's bands: thirds of a semitone from MIDI 21 (A0)."""
SHORT_LOW, SHORT_STEP = 45.0, 1.0
"""The short spectrum's bands: semitones from MIDI 45 (its 43 Hz bins resolve little lower)."""
TOP = 124.0
"""The highest band (MIDI 124, 10.6 kHz: below the analysis rate's anti-alias edge)."""
SCALE = 1000.0
"""Magnitudes (a sine's is its amplitude) are compressed as ``log1p(SCALE m)``."""
FLOOR_RISE = 1.0025
"""The noise floor's rise a :data:`HOP` (~1.9 dB/s); a finer hop rises by its share.

A held note must not become its own floor: at 1 % a hop (7.4 dB/s, until 2026-12-07) the floor
under a bowed or organ chord held two seconds rose 15 dB, and, twice taken off, ate into the
note the model was hearing sound. Measured with the models' weights unchanged (they were trained
at 1 %), mean note F1 at 1.01 → 1.005 → 1.0025 → 1.001 on the TimGM6mb tuning renders (the
fourteen textures, seeds 201–202), offline 0.8323 → 0.8386 → 0.8423 → 0.8417 (string chords in
a room 0.653 and 0.626 → 0.745 and 0.771); at 1.0025 the live look 0.7968 → 0.8025 and the quick
look 0.7781 → 0.7833. Held out (FluidR3, seeds 101–102): offline 0.8144 → 0.8196, live 0.7643 →
0.7639, quick 0.7416 → 0.7447. A room's noise switched on is still learnt, at 1.9 dB/s."""
FLOOR_MARGIN = 2.0


def midi_hz(m: np.ndarray | float) -> np.ndarray:
    return 440.0 * 2.0 ** ((np.asarray(m, dtype=float) - 69.0) / 12.0)


def window(length: int, fall: int) -> np.ndarray:
    """A half-Hann rise over ``length - fall`` samples, then a half-Hann fall over ``fall``."""
    rise = length - fall
    up = np.sin(0.5 * np.pi * (np.arange(rise) + 0.5) / rise) ** 2
    down = np.cos(0.5 * np.pi * (np.arange(fall) + 0.5) / fall) ** 2
    w = np.r_[up, down]
    return (w / w.sum() * 2.0).astype(np.float32)  # a sine's peak magnitude is its amplitude


def bands(n_fft: int, low: float, step: float, top: float = TOP) -> np.ndarray:
    """A (bands, bins) matrix pooling an ``n_fft`` magnitude spectrum into log-frequency bands:
    triangles a band wide in pitch, but never narrower than the spectrum's own bins (below
    there, a band interpolates between the two bins around it)."""
    centres = np.arange(low, top + 1e-9, step)
    f = np.arange(n_fft // 2 + 1) * RATE / n_fft
    df = RATE / n_fft
    fc = midi_hz(centres)
    width = np.maximum(fc * (2.0 ** (step / 12.0) - 1.0), df)
    m = np.maximum(0.0, 1.0 - np.abs(f[None, :] - fc[:, None]) / width[:, None])
    return (m / m.sum(axis=1, keepdims=True)).astype(np.float32)


class LogSpectrum:
    """Samples at :data:`RATE` in, one feature row per hop out: ``[long bands | short bands]``."""

    def __init__(self, hop: int = HOP) -> None:
        """``hop``: samples between rows (the same windows and bands on a finer grid hear an
        attack sooner: a live look's model, docs/hearing.md); the floors rise as fast a second."""
        if not 0 < hop <= SHORT:
            raise ValueError(f"hop must be 1–{SHORT} samples, not {hop}")
        self.hop = int(hop)
        self._rise = FLOOR_RISE ** (self.hop / HOP)  # a float64, as FLOOR_RISE was compiled in
        self.long_window, self.short_window = window(LONG, LONG_FALL), window(SHORT, SHORT_FALL)
        self.long_bands = csr_array(bands(LONG, LONG_LOW, LONG_STEP))  # a few bins a band: sparse
        self.short_bands = csr_array(bands(SHORT, SHORT_LOW, SHORT_STEP))
        self._long = (self.long_bands.indptr, self.long_bands.indices, self.long_bands.data)
        self._short = (self.short_bands.indptr, self.short_bands.indices, self.short_bands.data)
        self.width = self.long_bands.shape[0] + self.short_bands.shape[0]
        self._tail = np.zeros(LONG - self.hop, dtype=np.float32)  # the samples before the next hop
        self._pending = np.zeros(0, dtype=np.float32)
        self._floor: np.ndarray | None = None
        self.floors = np.zeros((0, self.width), dtype=np.float32)
        """Each band's noise floor at each of the rows :meth:`feed` last gave."""
        self.frames = 0
        """Frames given so far; frame ``i`` ends at sample ``(i + 1) * hop``."""

    @staticmethod
    def above_floor(levels: np.ndarray, floors: np.ndarray) -> np.ndarray:
        """How many times its noise floor a band's feature value is (``levels`` and the
        ``floors`` it was taken against, from :attr:`floors`): the compression undone, the floor
        taken off given back."""
        return np.expm1(levels) / SCALE / np.maximum(floors, 1e-7) + FLOOR_MARGIN

    @property
    def pending(self) -> int:
        """Samples taken in that are not yet a whole hop."""
        return len(self._pending)

    def feed(self, x: np.ndarray) -> np.ndarray:
        """The feature rows of the hops that ``x`` (float32 at :data:`RATE`) completes."""
        x = np.concatenate([self._pending, np.asarray(x, dtype=np.float32)])
        hop = self.hop
        hops = len(x) // hop
        self._pending = x[hops * hop:]
        if hops == 0:
            self.floors = np.zeros((0, self.width), dtype=np.float32)
            return np.zeros((0, self.width), dtype=np.float32)
        stream = np.concatenate([self._tail, x[: hops * hop]])
        self._tail = stream[len(stream) - (LONG - hop):]
        self.frames += hops
        long, short = np.empty((hops, LONG), np.float32), np.empty((hops, SHORT), np.float32)
        _windowed(stream, self.long_window, long, hop)
        _windowed(stream, self.short_window, short, hop)
        rows = np.empty((hops, self.width), dtype=np.float32)
        self.floors = np.empty_like(rows)
        if self._floor is None:
            self._floor = np.zeros(self.width, dtype=np.float32)  # the first frame sets it
        _pool(magnitudes(long), magnitudes(short), *self._long, *self._short,
              self._floor, self._rise, self.frames == hops, rows, self.floors)
        return rows


@numba.njit(cache=True, nogil=True)
def _windowed(stream, window, out, hop):  # pragma: no cover
    """Each hop's frame — the ``len(window)`` samples ending on it — less its mean (DC is no
    sound), windowed, into ``out``: one pass, where numpy took six calls a frame."""
    n = len(window)
    for i in range(out.shape[0]):
        end = LONG - hop + hop * (i + 1)
        mean = 0.0
        for k in range(end - n, end):
            mean += stream[k]
        mean /= n
        for k in range(n):
            out[i, k] = (stream[end - n + k] - mean) * window[k]


@numba.njit(cache=True, nogil=True)
def _pool(long, short, l_ptr, l_idx, l_w, s_ptr, s_idx, s_w, floor, rise, first, rows, floors):  # pragma: no cover
    """Each frame's magnitudes pooled into bands (two CSR matrices), less twice each band's noise
    floor (which follows a fall at once and a rise by ``rise`` a frame), compressed."""
    n_long = len(l_ptr) - 1
    for i in range(rows.shape[0]):
        for b in range(rows.shape[1]):
            if b < n_long:
                spectrum, ptr, idx, w, band = long, l_ptr, l_idx, l_w, b
            else:
                spectrum, ptr, idx, w, band = short, s_ptr, s_idx, s_w, b - n_long
            m = 0.0
            for k in range(ptr[band], ptr[band + 1]):
                m += w[k] * spectrum[i, idx[k]]
            level = max(m, 1e-7)
            if first and i == 0:
                floor[b] = level
            floor[b] = min(floor[b] * rise, level)
            floors[i, b] = floor[b]
            rows[i, b] = np.log1p(SCALE * max(m - FLOOR_MARGIN * floor[b], 0.0))
