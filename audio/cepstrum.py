"""Cepstral analysis of sound events and the time-warped distance between them.

Thesis, "aural models – cepstral models": each amplitude-bounded sound segment becomes a
sequence of cepstral vectors, and two utterances are as far apart as the smallest distance
between one and any time-warped version of the other (dynamic time warping). What is kept of
the spectrum decides which sounds count as the same; the choices below were made on words said
by several espeak-ng voices, synthetic formant words and phrases of five sampled instruments,
and checked on held-out words, voices and phrases (``python -m bench sound_classes``;
docs/hearing.md, "Sound classes on real voices", has the numbers and what was tried):

* **Perceptual linear prediction** (Hermansky 1990, "Perceptual linear predictive (PLP)
  analysis of speech"): the power spectrum on a Bark scale up to 5 kHz, through critical-band
  masking curves, weighted by an equal-loudness curve and cube-root compressed, then smoothed
  by a 5th-order all-pole model whose cepstrum (c1–c8) is kept. Hermansky chose the low order
  because it keeps the first formants and drops what tells one speaker from another. Under the
  same normalisation, warps and clustering, 8 mel-cepstra kept at best 89 % of three held-out
  voices' words in their class, PLP 100 %; the analysis before (13 MFCCs, lifter 22, no warps)
  keeps at best 40 % of the worst tuning corpus at any one radius.
* **c0 is left out and each coefficient's mean over the event is removed** (cepstral mean
  normalisation): that takes out the gain and a fixed channel colouring (microphone, room,
  loudspeaker). **The cepstra are then scaled to unit RMS frame norm** over the event
  (variance normalisation by one factor, so the coefficients keep their relative weights):
  distances become relative to how much a sound moves, which lets one radius serve words
  (spectra moving from consonant to vowel) and sustained instrument phrases. Without it the
  words needed a class twice as wide as the one that keeps five instruments apart.
* **No liftering**: after the variance normalisation a lifter only re-weights the
  coefficients, and every sinusoidal lifter narrowed the range of radii over which all tuning
  corpora keep ≥ 90 % in class (×1.24 without; ×1.15, ×1.10, ×1.09 at L = 8, 16, 22).
* **Vocal-tract-length warps** (VTLN, as speech recognisers normalise speakers): each event
  is analysed with its frequency axis scaled by each of :data:`WARPS`, and two events are
  compared at opposite warps (a at w, b at 1/w), the best of the five kept: relative scalings
  0.84–1.20 in 9 % steps, about the range over which adult vocal tracts differ. Without them
  the tuning corpora keep ≥ 90 % in class over radii ×1.05 only.

The DTW is a numba kernel with librosa's default step pattern (match, insertion, deletion,
unit weights). It accumulates only the cost and the length of the best path, with no cost
matrix or backtracking kept: ``bench/hearing.py`` measured ~0.73 ms against
``librosa.sequence.dtw``'s 2.0–2.4 ms for 200 × 200 frames, and the tests check both give
the same accumulated cost and path length. The distance is that cost divided by the path
length, so long and short utterances compare on the same scale. (Sakoe–Chiba's symmetric
weights and a slope constraint were tried: no better.)
"""

from __future__ import annotations

import functools

# librosa loads its parts on first use (lazy_loader): imported by name here, so the ~0.8 s
# import happens when a creature is built, not on the creature's thread at its first utterance.
from librosa import fft_frequencies, stft
import numba
import numpy as np
import scipy.sparse

ORDER = 5
"""All-pole model order (Hermansky's 5th order for speaker-independent recognition)."""
N_CEPSTRA = 8
"""Cepstral coefficients kept per frame (c1–c8)."""
FMAX = 5000.0
"""Hz: the top of the analysed band (the first three formants of any adult voice)."""
WARPS = np.exp(0.045 * np.arange(-2, 3))
"""Frequency-axis scalings each event is analysed at (0.91–1.09; pairs compared at opposite warps)."""
N_FFT = 512
HOP = 256
LIFTER = 0
"""Sinusoidal lifter length L (0: none); kept as a parameter so the bench can re-measure it."""
FEATURES = "plp5-c8-cmn-rms-vtln5"
"""Names this analysis in saved aural models: distances (and so radii) are in its units."""


def cepstra(
    samples: np.ndarray,
    samplerate: int,
    *,
    n_fft: int = N_FFT,
    hop_length: int = HOP,
    lifter: int = LIFTER,
) -> np.ndarray:
    """PLP cepstra of one sound event at each of :data:`WARPS`, shape (warps, frames, N_CEPSTRA).

    Frames are rows (C-contiguous) because the DTW walks them one by one; an event shorter
    than one window is zero-padded to one frame.

    >>> c = cepstra(event.samples, event.samplerate)
    >>> utterance_distance(c, template)
    """
    y = np.asarray(samples, dtype=np.float32)
    if len(y) < n_fft:
        y = np.pad(y, (0, n_fft - len(y)))
    power = np.abs(stft(y, n_fft=n_fft, hop_length=hop_length, center=False)) ** 2
    basis = _bark_basis(samplerate, n_fft)
    bands = np.cbrt(basis @ power.astype(np.float64) + 1e-12)  # equal loudness + cube root
    bands = bands.reshape(len(WARPS), -1, bands.shape[-1])
    bands[:, 0], bands[:, -1] = bands[:, 1], bands[:, -2]  # Hermansky: edge bands copy their neighbours
    autocorrelation = np.fft.irfft(bands, axis=1)[:, : ORDER + 1]
    c = _lpc_cepstra(_levinson(autocorrelation), N_CEPSTRA)  # (warps, frames, N_CEPSTRA)
    if lifter:
        c *= 1.0 + (lifter / 2.0) * np.sin(np.pi * np.arange(1, N_CEPSTRA + 1) / lifter)
    c -= c.mean(axis=1, keepdims=True)
    c /= np.sqrt(np.mean(np.sum(c**2, axis=2), axis=1))[:, None, None] + 1e-9
    return np.ascontiguousarray(c)


def _bark(hz: np.ndarray) -> np.ndarray:
    return 6.0 * np.arcsinh(np.asarray(hz) / 600.0)


@functools.lru_cache(maxsize=8)
def _bark_basis(samplerate: int, n_fft: int) -> scipy.sparse.csr_array:
    """Critical-band masking curves one Bark apart up to :data:`FMAX`, times the equal-loudness
    weight at each band's centre, for every warp stacked: (warps × bands, bins), sparse.

    Built once per rate (as the mel basis before it: rebuilding cost ~15 ms per event, and a
    dense product goes through multi-threaded BLAS, which on a shared 2-core machine stalled
    for 2–20 ms). Warping by w hears frequency f as f / w."""
    centres = np.linspace(0.0, _bark(FMAX), int(np.ceil(_bark(FMAX))) + 1)
    hz = fft_frequencies(sr=samplerate, n_fft=n_fft)
    omega = 2 * np.pi * 600.0 * np.sinh(centres / 6.0)
    loudness = (omega**2 + 56.8e6) * omega**4 / ((omega**2 + 6.3e6) ** 2 * (omega**2 + 0.38e9))
    rows = []
    for warp in WARPS:
        dz = _bark(hz / warp)[None, :] - centres[:, None]
        curve = np.where(dz < -1.3, 0.0, np.where(dz < -0.5, 10 ** (2.5 * (dz + 0.5)),
                         np.where(dz < 0.5, 1.0, np.where(dz < 2.5, 10 ** (0.5 - dz), 0.0))))
        rows.append(loudness[:, None] * curve)
    return scipy.sparse.csr_array(np.vstack(rows))


def _levinson(r: np.ndarray) -> np.ndarray:
    """Levinson–Durbin on autocorrelations ``r`` (..., ORDER + 1, frames): the predictor
    coefficients a1..ap of A(z) = 1 + Σ a_k z^−k, shape (..., frames, ORDER)."""
    r = np.moveaxis(r, -2, -1)
    order = r.shape[-1] - 1
    a = np.zeros(r.shape[:-1] + (order,))
    error = r[..., 0].copy()
    for i in range(order):
        k = -(r[..., i + 1] + np.sum(a[..., :i] * r[..., i:0:-1], axis=-1)) / error
        a[..., :i] = a[..., :i] + k[..., None] * a[..., :i][..., ::-1]
        a[..., i] = k
        error = error * (1.0 - k**2)
    return a


def _lpc_cepstra(a: np.ndarray, n: int) -> np.ndarray:
    """Cepstrum c1..cn of the all-pole model 1 / A(z) (the gain term c0 left out)."""
    order = a.shape[-1]
    c = np.zeros(a.shape[:-1] + (n + 1,))
    for m in range(1, n + 1):
        c[..., m] = -(a[..., m - 1] if m <= order else 0.0)
        for k in range(max(1, m - order), m):
            c[..., m] -= (k / m) * c[..., k] * a[..., m - k - 1]
    return c[..., 1:]


@numba.njit(cache=True, nogil=True)
def _dtw(a: np.ndarray, b: np.ndarray) -> tuple[float, int]:  # pragma: no cover - compiled
    n, m, k = a.shape[0], b.shape[0], a.shape[1]
    cost = np.empty(m + 1)
    length = np.empty(m + 1, dtype=np.int64)
    prev_cost = np.full(m + 1, np.inf)
    prev_len = np.zeros(m + 1, dtype=np.int64)
    prev_cost[0] = 0.0
    for i in range(n):
        cost[0] = np.inf
        length[0] = 0
        for j in range(m):
            d = 0.0
            for c in range(k):
                diff = a[i, c] - b[j, c]
                d += diff * diff
            d = np.sqrt(d)
            # Steps in librosa's order (ties go to the first): (i-1, j-1), (i, j-1), (i-1, j).
            best, best_len = prev_cost[j], prev_len[j]
            if cost[j] < best:
                best, best_len = cost[j], length[j]
            if prev_cost[j + 1] < best:
                best, best_len = prev_cost[j + 1], prev_len[j + 1]
            cost[j + 1] = d + best
            length[j + 1] = best_len + 1
        prev_cost, cost = cost, prev_cost
        prev_len, length = length, prev_len
    return prev_cost[m], prev_len[m]


@numba.njit(cache=True, nogil=True)
def _warped(a: np.ndarray, b: np.ndarray) -> float:  # pragma: no cover - compiled
    warps = a.shape[0]
    best = np.inf
    for w in range(warps):
        cost, length = _dtw(a[w], b[warps - 1 - w])
        best = min(best, cost / length)
    return best


def _checked(*items: np.ndarray, dims: int) -> list[np.ndarray]:
    """``items`` as C-contiguous float64, each with ``dims`` axes, frames, and the first's
    warps and coefficients (checked once, not per warped pair)."""
    out = [np.ascontiguousarray(x, dtype=np.float64) for x in items]
    first = out[0].shape
    for x in out:
        if x.ndim != dims or x.shape[-2] == 0 or x.shape[:-2] + x.shape[-1:] != first[:-2] + first[-1:]:
            raise ValueError(f"cannot warp cepstra of shapes {first} and {x.shape}")
    return out


def dtw_cost(a: np.ndarray, b: np.ndarray) -> tuple[float, int]:
    """Accumulated Euclidean cost of the best warping path of ``a`` onto ``b`` and its length.

    ``a`` and ``b`` are (frames, coefficients) arrays: one warp of :func:`cepstra`, or any
    other trajectories.
    """
    cost, length = _dtw(*_checked(a, b, dims=2))
    return float(cost), int(length)


def utterance_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Distance between two utterances' :func:`cepstra`: the smallest time-warped distance (best
    path cost per step, :func:`dtw_cost`) of ``a`` at warp w against ``b`` at the opposite warp, over :data:`WARPS` (symmetric)."""
    return float(_warped(*_checked(a, b, dims=3)))


def distances_to(query: np.ndarray, templates: list[np.ndarray]) -> np.ndarray:
    """:func:`utterance_distance` from ``query`` to each template (the hot path of recognition)."""
    query, *templates = _checked(query, *templates, dims=3)
    return np.array([_warped(query, t) for t in templates])


def distance_matrix(items: list[np.ndarray]) -> np.ndarray:
    """Symmetric matrix of :func:`utterance_distance` between all pairs (for clustering)."""
    n = len(items)
    out = np.zeros((n, n))
    items = _checked(*items, dims=3) if n else []
    for i in range(n):
        for j in range(i + 1, n):
            out[i, j] = out[j, i] = _warped(items[i], items[j])
    return out


def pair_distances(items: list[np.ndarray], pairs: list[tuple[int, int]]) -> np.ndarray:
    """:func:`utterance_distance` of ``items[i]`` and ``items[j]`` for each ``(i, j)`` of
    ``pairs`` (the pairs a cache of them has not seen: :class:`audio.utterance.PairDistances`)."""
    items = _checked(*items, dims=3) if items else []
    return np.array([_warped(items[i], items[j]) for i, j in pairs], dtype=float)


def nearest(query: np.ndarray, templates: list[np.ndarray]) -> tuple[int, float]:
    """Index of and distance to the template closest to ``query``."""
    d = distances_to(query, templates)
    i = int(np.argmin(d))
    return i, float(d[i])
