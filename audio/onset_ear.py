"""The onset ear: notes found where an attack is, by what began there — one of hearing's two ears.

This is the hand-built method the project heard with before its note model (docs/hearing.md has
both measured): it is exact on struck sounds — a piano's or a guitar's line, independent voices —
where the model hears a bright note's partials as notes of their own, and deaf to bowed and blown
swells, which the model hears. :class:`audio.transcribe.Transcriber` runs both on one stream and
lets the model judge this ear's candidates.

1. **Onsets.** Every hop (256 samples at 22.05 kHz, 11.6 ms, the note model's hop too) a short
   spectrum (512 samples) is compared with the previous one: the summed rise of its log
   magnitudes above each bin's noise floor, after a 3-bin maximum filter across frequency so
   vibrato does not count (Böck & Widmer's "SuperFlux", 2013). A rise above ``threshold`` (and
   above what the recent music gave, so a dense texture does not fire on every frame) is an
   onset. A stronger onset within :data:`REFRACTORY` replaces a weaker one, and so does the next
   one after an onset that came as the sound fell (the click of a note cut off). The attack
   began :data:`LEAD` hop before it.
2. **What began.** Once ``window`` samples have followed the onset, the positive difference
   between their spectrum and that of the ``window`` samples before it is the sound that started
   there; notes still ringing from before are not in it. The live look is 1024 samples (46 ms),
   the offline one 2048 (93 ms).
3. **Which pitches.** :class:`audio.salience.HarmonicSalience` finds the notes in it (Klapuri
   2006: harmonic salience, iterative cancellation, polyphony by the discounted salience sum),
   each with its strongest partial's level.
"""

from __future__ import annotations

import statistics
from collections import deque
from typing import NamedTuple

import numba
import numpy as np

from audio.logspectrum import HOP, RATE
from audio.rfft import magnitudes
from audio.salience import HarmonicSalience

SHORT = 512
LIVE_WINDOW = 1024
"""Samples (46 ms) of a note looked at to tell its pitches live: the most that keeps the onset →
note event latency under 60 ms (46 ms + a hop + the onset's own detection)."""
OFFLINE_WINDOW = 2048
WARM_UP = 8
"""Frames (93 ms) heard before the first onset may be taken: the noise floors are learnt first."""
NEWNESS = 0.4
"""Fraction of a found pitch's first partials that must be new at its onset (else it was
sounding already, and only fluctuated)."""
REFRACTORY = 0.05
"""Seconds after an onset in which no second onset is taken (one attack's flux lasts that long)."""
LEAD = 1
"""Hops between the hop an attack began in and the frame taken as its onset: a note of this ear
is dated that much earlier (:class:`audio.transcribe.Transcriber`; its rules keep the onset
frame). The short window (512 samples, Hann) weighs an attack fully only once it reaches the
window's middle, so the strongest flux, the one kept, comes a hop after the attack's. Measured
on FluidR3 piano and guitar (the validation renders, seeds 101–102), the two ears' notes were
dated p50 16–19 ms after their MIDI onsets offline (p90 22–25) and 3–12 ms live (p90 11–21),
the note model's own 3–7 ms: two ears told one rhythm in two times. Dated a hop earlier: p50 5–8
ms offline (p90 11–14), 2–7 ms live (p90 11–13). Note F1 on the tuning renders rose a little or
held (offline 0.8283 → 0.8323, live 0.7962 → 0.7968, quick 0.7772 → 0.7781), on validation held
(offline 0.8139 → 0.8144, live and quick unchanged). Moving the candidates themselves a hop
earlier, so that the rules saw them there too, lost live (validation 0.7643 → 0.7620, the
chorale 0.671 → 0.655). (2026-12-06, twentieth session.)"""
RISE = 1.01
"""A noise floor's rise per hop (~ +7 dB/s): a sustained note (seconds) is not mistaken for the
room, but a fan is learnt."""
NOISE_EVERY = 4
"""Hops between two looks at the long spectrum for its noise floor (46 ms). A room's noise
changes over seconds; the long spectrum (a 4096-point FFT offline) was the ear's largest cost
when taken every hop, and the floor it gives the salience is as good taken every 4th."""


class Candidate(NamedTuple):
    """A note this ear found: the hop of its onset (:data:`LEAD` after its attack's), its pitch,
    its level (dBFS)."""

    frame: int
    pitch: int
    level_db: float


class OnsetEar:
    """Samples at :data:`audio.logspectrum.RATE` in (cleaned), candidates out, as each is recognised."""

    def __init__(self, window: int = OFFLINE_WINDOW, *, threshold: float = 6.0,
                 midi_range: tuple[int, int] = (28, 100)) -> None:
        self.window_length = int(window)
        self.n_fft = 2 * self.window_length  # zero-padded: partials placed to a quarter of a lobe
        self.delay_frames = -(-(self.window_length - SHORT // 2) // HOP)
        """Hops from an onset's frame until the window after it has been heard."""
        self.threshold = float(threshold)
        self.salience = HarmonicSalience(RATE, self.n_fft, midi_range,
                                         gamma=0.27 if self.window_length >= OFFLINE_WINDOW else 0.6)
        self._short_window = np.hanning(SHORT).astype(np.float32)
        self._window = np.hanning(self.window_length).astype(np.float32)
        self._keep = 2 * self.window_length + (self.delay_frames + 2) * HOP  # samples an onset's analysis may need
        self._buffer = np.zeros(self._keep, dtype=np.float32)  # the latest samples
        self._pending = np.zeros(0, dtype=np.float32)  # samples not yet a whole hop
        self._end = 0  # the current frame's end in the buffer, while a block is analysed
        self.frames = 0  # frames analysed so far; frame i ends at sample (i + 1) * HOP
        self._level = self._previous = np.zeros(0)  # this frame's short log spectrum, and the last one's
        # Noise floors: each bin's, learnt from the first frame on (a room is noisy from the start).
        self._noise_short: np.ndarray | None = None
        self._noise_long: np.ndarray | None = None
        self._energy: deque[float] = deque([0.0, 0.0], maxlen=2)  # short-window energy, last frames
        self._flux: deque[float] = deque(maxlen=round(0.3 * RATE / HOP))
        self._last_onset, self._last_flux, self._last_falling = -np.inf, 0.0, False
        self._quiet_until = 0  # no onset is taken in a frame before this one
        self._due: list[tuple[int, int]] = []  # (frame to analyse at, onset frame)

    def seam(self, frames: int) -> None:
        """The next ``frames`` hops hold a step that is not an attack (a repair, a new rate, a gap)."""
        self._quiet_until = max(self._quiet_until, self.frames + frames)

    def skip(self) -> None:
        """The stream jumped (a clock gap): an onset still being looked at is dropped."""
        self._due.clear()

    def feed(self, x: np.ndarray) -> list[Candidate]:
        """The candidates recognised in the hops that ``x`` (float32 at RATE) completes."""
        x = np.concatenate([self._pending, x])
        hops = len(x) // HOP
        self._pending = x[hops * HOP:]
        if hops == 0:
            return []
        stream = np.concatenate([self._buffer, x[: hops * HOP]])
        self._buffer = stream  # the whole block while its frames are analysed, then trimmed
        ends = [len(stream) - HOP * (hops - 1 - i) for i in range(hops)]  # each frame's window ends there
        looked = [i for i in range(hops) if (self.frames + i) % NOISE_EVERY == 0]
        long = {}
        if looked:
            frames = np.stack([stream[ends[i] - self.window_length:ends[i]] for i in looked])
            long = dict(zip(looked, self._spectra(frames)))
        short = magnitudes(np.stack([stream[end - SHORT:end] for end in ends]) * self._short_window)
        found: list[Candidate] = []
        for i in range(hops):
            self._end = ends[i]
            found.extend(self._step(long.get(i), short[i]))
        self._buffer = stream[-self._keep:]
        return found

    def _spectra(self, frames: np.ndarray) -> np.ndarray:
        """Magnitude spectra (zero-padded) of window-length frames, DC removed."""
        frames = frames - frames.mean(axis=-1, keepdims=True)  # DC offset is no sound
        return magnitudes(frames * self._window, self.n_fft)

    def _step(self, long: np.ndarray | None, short: np.ndarray) -> list[Candidate]:
        """One hop; ``long`` is its long spectrum on every NOISE_EVERY-th hop, else ``None``."""
        frame = self.frames
        self.frames += 1
        if self._noise_short is None:  # the first frame: the floors start from it, no flux yet
            self._noise_short, self._noise_long = np.maximum(short, 1e-7), np.maximum(long, 1e-7)
            self._level, self._previous = np.zeros_like(short), np.zeros_like(short)
        if long is not None:
            _track_noise(self._noise_long, long, RISE ** NOISE_EVERY)
        self._previous, self._level = self._level, self._previous  # the last frame's level is now the one before
        energy, flux = _flux(short, self._noise_short, self._previous, self._level)
        falling = energy < self._energy[0]  # quieter than two frames ago: perhaps a note cut off
        self._energy.append(energy)
        if frame > 0:
            self._detect(frame, flux, falling)
        found = []
        while self._due and self._due[0][0] <= frame:
            _, onset = self._due.pop(0)
            found.extend(self._recognise(onset, frame))
        return found

    def _detect(self, frame: int, flux: float, falling: bool) -> None:
        """Take ``frame`` as an onset if its flux stands out. Within REFRACTORY of the last
        one, only instead of it, if it is stronger or the last one came as the sound fell (the
        click of a note cut off, just before the next note's attack)."""
        recent = statistics.median(self._flux) if self._flux else 0.0  # 26 floats: no numpy round trip
        self._flux.append(flux)
        settled = len(self._flux) >= WARM_UP  # the floors and the flux's median have been learnt
        if frame < self._quiet_until or not (settled and flux > self.threshold + 2.0 * recent):
            return
        t = frame * HOP / RATE
        if t - self._last_onset > REFRACTORY:
            self._due.append((frame + self.delay_frames, frame))
        elif self._due and (flux > self._last_flux or self._last_falling):
            self._due[-1] = (frame + self.delay_frames, frame)
        else:
            return
        self._last_onset, self._last_flux, self._last_falling = t, flux, falling

    def _recognise(self, onset: int, frame: int) -> list[Candidate]:
        """The notes that began at ``onset``: the positive difference between the spectra of
        the window's samples after it and as many before it."""
        at = self._end - (frame - onset) * HOP - SHORT // 2  # the short window's centre in the buffer
        after, before = self._spectra(np.stack([self._buffer[at:at + self.window_length],
                                                self._buffer[at - self.window_length:at]]))
        edge = self._buffer[at - SHORT:at + SHORT]
        if np.sum(edge[SHORT:] ** 2) < 0.5 * np.sum(edge[:SHORT] ** 2):
            return []  # quieter just after than just before: a note cut off (its click), not an attack
        began = np.maximum(after - before, 0.0)
        found = []
        for pitch, amplitude in self.salience.estimate(began, floor=2.0 * self._noise_long):
            k = pitch - int(self.salience.pitches[0])
            bins = self.salience.bins[k][self.salience.valid[k]][:4]
            if began[bins].sum() < NEWNESS * after[bins].sum():
                continue  # it was sounding before: a fluctuation, not a note
            found.append(Candidate(onset, pitch, 20.0 * np.log10(max(amplitude * 4.0 / self.window_length, 1e-10))))
        return found


@numba.njit(cache=True, nogil=True)
def _track_noise(floor, spectrum, rise):  # pragma: no cover
    """Each bin's noise floor: follows a fall at once, a rise by ``rise`` a look."""
    for k in range(len(floor)):
        floor[k] = min(floor[k] * rise, max(spectrum[k], 1e-7))


@numba.njit(cache=True, nogil=True)
def _flux(short, noise, previous, level):  # pragma: no cover
    """A short spectrum's energy, and its flux: the summed rise of its log level above twice
    each bin's noise floor (followed here) over the previous frame's 3-bin maximum (the
    maximum so vibrato does not count). ``level`` becomes this frame's."""
    _track_noise(noise, short, RISE)
    energy = 0.0
    for k in range(len(short)):
        energy += short[k] * short[k]
        level[k] = np.log1p(max(short[k] - 2.0 * noise[k], 0.0) / (SHORT * 1e-4))
    flux = 0.0
    n = len(level)
    for k in range(n):
        before = previous[k]
        if k > 0:
            before = max(before, previous[k - 1])
        if k < n - 1:
            before = max(before, previous[k + 1])
        flux += max(level[k] - before, 0.0)
    return energy, flux
