"""Band-limited scanning: the string's shape read as a wavetable with no harmonic above the band.

Scanned synthesis reads the shape as one period of a waveform at the note's frequency f₀ (thesis
"scanned synthesis models (technology)", step 3), so the shape's k-th harmonic sounds at k·f₀.
A table of N trajectory points holds harmonics up to N/2; above the output's Nyquist they fold
back, off the note's harmonics: at 22050 Hz, 128 masses read naively put 8.8 % of a MIDI 96's
energy and 64 % of a MIDI 108's off its harmonics (``tests/test_bandlimit.py`` measures it).

How, as wavetable oscillators do it: the table is projected onto its harmonics up to
``K = ⌊LIMIT · sample_rate / f₀⌋`` (a real DFT across the trajectory's points, the others
zeroed) and the scanner reads the projected table exactly as it read the shape — linearly
between points and between the last two haptic frames. The projection is linear, so
interpolating projected frames is projecting the interpolated shape: what sounds is the naive
scan with the harmonics above the band taken out, nothing else changed. It runs once per haptic
frame (the shape changes at the gestural rate, 500–1000 frames a second), not per sample, and
only for a string whose band holds fewer than :data:`FULL_BAND` of its harmonics: what a
string's shape has above its 16th harmonic is too little to hear folded, and projecting every
note whose table merely reaches past the band made a bank of mid-range voices three times
dearer. A lower note reads its shape as before, sample for sample (:func:`above_band`).

Why a projection per frame rather than the alternatives: mip-mapped tables (one per octave,
as for a fixed wavetable) would each need the same projection, since the table changes every
frame, and would also cut up to an octave of harmonics that fit; oversampling by R and
decimating removes only what lies between the Nyquist and R times it, while a 128-point table
at MIDI 108 reaches 130 times the Nyquist of 22050 Hz. The projection is exact, and it costs
about ``2·N·M`` multiply-adds a frame, M the smaller of the harmonics kept and removed
(:func:`harmonics`): little for a high note (MIDI 96 at 22050 Hz keeps 4 harmonics), most for a
note whose band falls half-way up its table.

What stays: the linear reading's own images (the table read between its points has harmonics
above N/2, each its table harmonic times sinc² of its place in the table), which are 60 dB
down or more where the band is small; and ``interpolation = "none"`` (Csound's ``scantable``:
the nearest node, its steps are its sound) is read as it always was, not band-limited.
"""

from __future__ import annotations

from functools import lru_cache

import numba
import numpy as np

LIMIT = 0.45
"""Highest harmonic frequency kept, as a fraction of the sample rate: below the Nyquist (0.5),
leaving the linear reading's first images room to fall above it."""

FULL_BAND = 16
"""A note whose band holds this many of its table's harmonics or more is read as it is, not
projected. A plucked 128-mass string read naively at 22050 Hz puts 0.005 % of its energy off its
harmonics at MIDI 75 (K = 15.9, −43 dB), 0.009 % at 78 (K = 13.4), 0.03 % at 81, 0.08 % at 84
(K = 9.5), 0.9 % at 90 and 8.8 % at 96 (K = 4.7); at 48 kHz 0.008 % at MIDI 90 (K = 14.6) and
0.001 % at 84 (K = 20.6), against a measuring floor of 0.0003 %. Projecting every note with
any harmonic of its table above the band (K < 64) took the bank's linear row (MIDI 40–87 at
48 kHz, bench voice) from 2,197 voices to ~700; at K < 16 it projects MIDI 89 up there (76 up
at 22050 Hz), the notes whose folding would be heard, and the projection of a small band costs
least (2·N·K multiply-adds a frame)."""

NO_BASIS = np.zeros((2, 0, 0))
"""The basis passed for a string that is not band-limited (the kernels take an array)."""


def kept_harmonics(increment: np.ndarray | float) -> np.ndarray:
    """``K``, the harmonics of a scan of ``increment`` cycles a sample (f₀ / sample rate) that lie
    within :data:`LIMIT`, and always the fundamental (below the Nyquist, it aliases nowhere: a
    note between 0.45 and 0.5 × the rate sounds it rather than silence); a still scan
    (increment 0) keeps every one (a number past any table's harmonics)."""
    return np.maximum(np.floor(LIMIT / np.maximum(increment, 1e-300)), 1.0)


def above_band(kept: np.ndarray | float, n_points: int) -> np.ndarray | bool:
    """Whether a table of ``n_points`` read keeping ``kept`` harmonics is band-limited: it has
    harmonics above them (its top harmonic is N/2), and the band holds fewer than
    :data:`FULL_BAND` (above that, what folds is too little to hear)."""
    return kept < min(n_points // 2, FULL_BAND)


def harmonics(kept: np.ndarray, n_points: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which harmonics of tables of ``n_points`` keeping ``kept`` harmonics each to project on:
    ``(first, stop, keep)``, the kept ``0…K`` (``keep``) or the removed ``K+1…N/2``, whichever
    are fewer; ``first == stop`` where the table is read as it is (not :func:`above_band`)."""
    top = n_points // 2
    limited = above_band(kept, n_points)
    kept = np.minimum(kept, top).astype(np.int64)
    keep = kept + 1 <= top - kept
    first = np.where(limited & ~keep, kept + 1, 0)
    stop = np.where(limited, np.where(keep, kept + 1, top + 1), 0)
    return first, stop, keep


@lru_cache(maxsize=8)
def dft_basis(n_points: int) -> np.ndarray:
    """The real DFT of ``n_points``, orthonormal, folded: ``[0, k, t]`` and ``[1, k, t]`` are the
    cosine and sine of harmonic ``k`` at points ``t`` and ``N − t`` (t = 0…N/2), scaled so the
    projection on harmonic k is its coefficient times them. A cosine is the same at ``t`` and
    ``N − t`` and a sine opposite, so half of each row is all of it: half the work."""
    top = n_points // 2
    k = np.arange(top + 1)[:, None]
    angle = 2.0 * np.pi * k * np.arange(top + 1)[None, :] / n_points
    scale = np.where((k == 0) | (2 * k == n_points), np.sqrt(1.0 / n_points), np.sqrt(2.0 / n_points))
    basis = np.stack([scale * np.cos(angle), scale * np.sin(angle)])
    basis[1, :, 0] = 0.0
    if n_points % 2 == 0:
        basis[1, :, top] = 0.0  # sin(πk): exactly 0, not its rounding
    basis.setflags(write=False)
    return basis


@numba.njit(cache=True, fastmath={"reassoc", "contract"})
def band_limit(table, shape, trajectory, basis, first, stop, keep, scratch):
    """``table`` ← the shape read along ``trajectory`` (``-1`` a fixed end, 0), projected on
    harmonics ``first…stop`` of ``basis`` (``keep``) or with them taken out; ``scratch`` is
    (5, ≥ N) of work space. The table is folded into its even and odd halves about point 0
    (:func:`dft_basis`), projected there two harmonics a pass, and unfolded. Reassociation is
    allowed here only: the sums over the table then vectorise, and the bank and the lone string
    call this same code, so they still agree."""
    n = table.shape[0]
    half = n // 2 + 1
    pairs = (n + 1) // 2  # points 1…pairs−1 have their mirror n − t apart from them
    raw, even, odd, cos_part, sin_part = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4]
    for t in range(n):
        j = trajectory[t]
        raw[t] = shape[j] if j >= 0 else 0.0
    even[0] = raw[0]
    odd[0] = 0.0
    for t in range(1, pairs):
        even[t] = raw[t] + raw[n - t]
        odd[t] = raw[t] - raw[n - t]
    if pairs < half:
        even[pairs] = raw[pairs]
        odd[pairs] = 0.0
    cos_part[:half] = 0.0
    sin_part[:half] = 0.0
    cosines, sines = basis[0], basis[1]
    k = first
    while k + 2 <= stop:
        c0, c1, s0, s1 = cosines[k], cosines[k + 1], sines[k], sines[k + 1]
        a0 = a1 = b0 = b1 = 0.0
        for t in range(half):
            a0 += c0[t] * even[t]
            a1 += c1[t] * even[t]
            b0 += s0[t] * odd[t]
            b1 += s1[t] * odd[t]
        for t in range(half):
            cos_part[t] += a0 * c0[t] + a1 * c1[t]
            sin_part[t] += b0 * s0[t] + b1 * s1[t]
        k += 2
    if k < stop:
        c0, s0 = cosines[k], sines[k]
        a0 = b0 = 0.0
        for t in range(half):
            a0 += c0[t] * even[t]
            b0 += s0[t] * odd[t]
        for t in range(half):
            cos_part[t] += a0 * c0[t]
            sin_part[t] += b0 * s0[t]
    sign = 1.0 if keep else -1.0
    table[0] = sign * cos_part[0]
    for t in range(1, pairs):
        table[t] = sign * (cos_part[t] + sin_part[t])
        table[n - t] = sign * (cos_part[t] - sin_part[t])
    if pairs < half:
        table[pairs] = sign * cos_part[pairs]
    if not keep:
        for t in range(n):
            table[t] += raw[t]
