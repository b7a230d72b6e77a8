"""Heard audio → note events, as it streams: how audio-only installations hear notes.

A creature that listens to notes (exchange, listen, sand:stone) should hear a piano's chords,
a flute or a voice as readily as a MIDI keyboard. The method (measured against basic-pitch's
published model and the earlier monophonic YIN path in ``docs/hearing.md``):

1. **Onsets.** Every 11.6 ms (256 samples at the 22.05 kHz analysis rate) a short spectrum
   (512 samples) is compared with the previous one: the summed rise of its log magnitudes
   above each bin's noise floor, after a 3-bin maximum filter across frequency so vibrato
   does not count (Böck & Widmer's "SuperFlux", 2013). A rise above ``threshold`` (and
   above what the recent music gave, so a dense texture does not fire on every frame) is an
   onset.
   onset. A stronger onset within ``REFRACTORY`` replaces a weaker one, and so does the next
   one after an onset that came as the sound fell (the click of a note cut off).
2. **What began.** Once ``window`` samples have followed the onset, the positive difference
   between their spectrum and that of the ``window`` samples before it is the sound that
   started there; notes still ringing from before are not in it. The live look is 1024 samples
   (46 ms), the offline one 2048 (93 ms: nobody waits offline, and chords are heard better).
3. **Which pitches.** :class:`audio.salience.HarmonicSalience` finds the notes in it
   (Klapuri 2006: harmonic salience, iterative cancellation, polyphony by the discounted
   salience sum), each with a velocity from its strongest partial's level.
4. **How long.** Each started note is followed in the spectrum (its first partials) until it
   falls ``release_db`` below its peak or is struck again; its measured duration goes to
   :attr:`Transcriber.ended`.

A note event is given as soon as its pitches are known (live: ≤ 60 ms after the attack, so a
creature answers a chord as promptly as a MIDI key), with the provisional duration
``heard_length`` — as the live MIDI input gives a note-on (its length is not known until it
ends).

Any rate (8–192 kHz), any number of channels (averaged) is taken; non-finite samples hold the
last good one and are counted (:attr:`Transcriber.bad_samples`), and no onset is taken in the
frames they touch; a change of input rate (:meth:`Transcriber.set_rate`) restarts the
resampler without losing the timeline.
"""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass

import numpy as np
import soxr

from audio.pitch import velocity_from_level
from audio.salience import HarmonicSalience
from midi.notes import NoteEvent

RATE = 22050
"""Analysis rate: partials up to 9 kHz, and MIDI 100's fundamental (2.6 kHz) has three."""
HOP = 256
SHORT = 512
WINDOW = 1024
"""Samples (46 ms) of a note looked at to tell its pitches live: the most that keeps the onset →
note event latency under 60 ms (46 ms + a hop + the onset's own detection). Offline runs,
where latency costs nothing, look at twice as much (:data:`OFFLINE_WINDOW`)."""
OFFLINE_WINDOW = 2048
WARM_UP = 8
"""Frames (93 ms) heard before the first onset may be taken: the noise floors are learnt first."""
NEWNESS = 0.4
"""Fraction of a found pitch's first partials that must be new at its onset (else it was
sounding already, and only fluctuated)."""
REFRACTORY = 0.05
"""Seconds after an onset in which no second onset is taken (one attack's flux lasts that long)."""


@dataclass
class _Sounding:
    """A note being followed until it ends."""

    note: NoteEvent
    bins: np.ndarray  # its first partials in the long spectrum
    peak: float


class Transcriber:
    """Streams audio blocks in, gives the notes that began, as soon as each is recognised."""

    def __init__(self, samplerate: int, *, t0: float = 0.0, midi_range: tuple[int, int] = (28, 100),
                 window: int = OFFLINE_WINDOW, threshold: float = 6.0, release_db: float = 25.0,
                 heard_length: float = 0.25, max_length: float = 8.0) -> None:
        self.t0 = float(t0)
        self.window_length = int(window)
        self.n_fft = 2 * self.window_length  # zero-padded: partials placed to a quarter of a lobe
        self.delay_frames = -(-(self.window_length - SHORT // 2) // HOP)  # frames until a window follows the onset
        self.threshold = float(threshold)
        self.release = 10 ** (-release_db / 20)
        self.heard_length = float(heard_length)
        self.max_length = float(max_length)
        self.salience = HarmonicSalience(RATE, self.n_fft, midi_range,
                                         gamma=0.27 if self.window_length >= OFFLINE_WINDOW else 0.6)
        self._short_window = np.hanning(SHORT).astype(np.float32)
        self._window = np.hanning(self.window_length).astype(np.float32)
        self._keep = 2 * self.window_length + (self.delay_frames + 2) * HOP  # samples an onset's analysis may need
        self._buffer = np.zeros(self._keep, dtype=np.float32)  # the latest samples at RATE
        self._stream_end = 0  # samples at RATE taken in so far (the buffer's end)
        self._pending = np.zeros(0, dtype=np.float32)  # samples not yet a whole hop
        self._frame = 0  # frames analysed so far; frame i ends at sample (i + 1) * HOP
        self._previous: np.ndarray | None = None  # last short log spectrum
        # Noise floors: each bin's, learnt from the first frame on (a room is noisy from the start).
        self._noise_short: np.ndarray | None = None
        self._noise_long: np.ndarray | None = None
        self._energy: deque[float] = deque([0.0, 0.0], maxlen=2)  # short-window energy, last frames
        self._flux: deque[float] = deque(maxlen=round(0.3 * RATE / HOP))
        self._last_onset, self._last_flux, self._last_falling = -np.inf, 0.0, False
        self._bad_frames = 0  # frames still to pass before onsets are taken again
        self._due: list[tuple[int, int]] = []  # (frame to analyse at, onset frame)
        self._sounding: dict[int, _Sounding] = {}
        self.ended: deque[NoteEvent] = deque(maxlen=1024)
        """Notes that ended, with their measured durations (the latest 1024)."""
        self.onsets = 0  # onsets heard
        self.notes = 0  # notes given
        self.bad_samples = 0  # non-finite samples replaced by silence
        self.clipped = 0  # samples at or beyond full scale
        self._last_good = 0.0
        self._rate = 0
        self._resampler: soxr.ResampleStream | None = None
        self.set_rate(samplerate)

    def set_rate(self, samplerate: int) -> None:
        """The input's rate from now on (a live device reopened at another rate)."""
        samplerate = int(samplerate)
        if samplerate == self._rate:
            return
        if self._rate:
            # The old resampler's tail is lost and the new one starts cold: a seam in the
            # stream, which must not be heard as an attack.
            self._bad_frames = max(self._bad_frames, SHORT // HOP + 2)
        self._rate = samplerate
        self._resampler = None if samplerate == RATE else soxr.ResampleStream(samplerate, RATE, 1, dtype="float32")

    def feed(self, block: np.ndarray) -> list[NoteEvent]:
        """The notes recognised within ``block`` (any shape ``(frames,)`` or ``(frames, ch)``)."""
        x = np.asarray(block, dtype=np.float32)
        if x.ndim == 2:
            x = x.mean(axis=1)
        bad = ~np.isfinite(x)
        if bad.any():
            # Each bad sample holds the last good one: a zero in a loud tone would be a click.
            self.bad_samples += int(bad.sum())
            self._bad_frames = -(-len(x) * RATE // (self._rate * HOP)) + SHORT // HOP + 1
            good = np.where(bad, 0, np.arange(len(x)))
            np.maximum.accumulate(good, out=good)
            x = np.where(bad[good], self._last_good, x[good]).astype(np.float32)
        if len(x):
            self._last_good = float(x[-1])
        self.clipped += int(np.count_nonzero(np.abs(x) >= 0.999))
        if self._resampler is not None:
            x = self._resampler.resample_chunk(x)
        x = np.concatenate([self._pending, x])
        hops = len(x) // HOP
        self._pending = x[hops * HOP:]
        if hops == 0:
            return []
        stream = np.concatenate([self._buffer, x[: hops * HOP]])
        self._buffer = stream  # the whole block while its frames are analysed, then trimmed
        self._stream_end += hops * HOP
        ends = len(stream) - HOP * np.arange(hops - 1, -1, -1)  # each frame's window ends there
        frames = stream[ends[:, None] + np.arange(-self.window_length, 0)[None, :]]
        long = self._spectra(frames)
        short = np.abs(np.fft.rfft(frames[:, -SHORT:] * self._short_window, axis=1))
        notes: list[NoteEvent] = []
        for i in range(hops):
            notes.extend(self._step(long[i], short[i]))
        self._buffer = stream[-self._keep:]
        return notes

    def _spectra(self, frames: np.ndarray) -> np.ndarray:
        """Magnitude spectra (zero-padded) of window-length frames, DC removed."""
        frames = frames - frames.mean(axis=-1, keepdims=True)  # DC offset is no sound
        return np.abs(np.fft.rfft(frames * self._window, n=self.n_fft, axis=-1))

    def flush(self) -> list[NoteEvent]:
        """End every note still sounding (the input stopped); returns nothing new."""
        for pitch in list(self._sounding):
            self._end(pitch)
        return []

    @property
    def fed_until(self) -> float:
        """The time just after the last sample fed: where the next block begins, counted in samples."""
        return self.t0 + (self._stream_end + len(self._pending)) / RATE

    def skip(self, seconds: float) -> None:
        """The clock jumped ``seconds`` ahead between two blocks (``creatures.clock.clock_gap``):
        times are counted in samples, so without this every note heard after a suspended night
        would be dated before it. Notes sounding end where they were heard; an onset still
        being analysed is dropped (one lost note is cheap, a note dated a night early is not);
        the next sample is dated after the gap."""
        self.flush()
        self._due.clear()
        self.t0 += float(seconds)

    # -- per frame ---------------------------------------------------------------------------
    def _time(self, frame: int) -> float:
        return self.t0 + (frame + 1) * HOP / RATE

    def _step(self, long: np.ndarray, short: np.ndarray) -> list[NoteEvent]:
        frame = self._frame
        self._frame += 1
        if self._noise_short is None:
            self._noise_short, self._noise_long = np.maximum(short, 1e-7), np.maximum(long, 1e-7)
        self._track_noise(self._noise_short, short)
        self._track_noise(self._noise_long, long)
        energy = float(np.sum(short**2))
        falling = energy < self._energy[0]  # quieter than two frames ago: perhaps a note cut off
        self._energy.append(energy)
        level = np.log1p(np.maximum(short - 2.0 * self._noise_short, 0.0) / (SHORT * 1e-4))
        if self._previous is not None:
            before = self._previous.copy()  # its 3-bin maximum, by shifted slices
            np.maximum(before[1:], self._previous[:-1], out=before[1:])
            np.maximum(before[:-1], self._previous[1:], out=before[:-1])
            rise = level - before
            flux = float(np.maximum(rise, 0.0).sum())
            self._detect(frame, flux, falling)
        self._previous = level
        self._follow(long, frame)
        notes = []
        while self._due and self._due[0][0] <= frame:
            _, onset = self._due.pop(0)
            notes.extend(self._recognise(onset, long))
        return notes

    def _detect(self, frame: int, flux: float, falling: bool) -> None:
        """Take ``frame`` as an onset if its flux stands out. Within REFRACTORY of the last
        one, only instead of it, if it is stronger or the last one came as the sound fell (the
        click of a note cut off, just before the next note's attack)."""
        recent = statistics.median(self._flux) if self._flux else 0.0  # 26 floats: no numpy round trip
        self._flux.append(flux)
        settled = len(self._flux) >= WARM_UP  # the floors and the flux's median have been learnt
        if self._bad_frames > 0:
            self._bad_frames -= 1  # repaired samples make steps: no onsets in their frames
            return
        if not (settled and flux > self.threshold + 2.0 * recent):
            return
        t = self._time(frame)
        if t - self._last_onset > REFRACTORY:
            self.onsets += 1
            self._due.append((frame + self.delay_frames, frame))
        elif self._due and (flux > self._last_flux or self._last_falling):
            self._due[-1] = (frame + self.delay_frames, frame)
        else:
            return
        self._last_onset, self._last_flux, self._last_falling = t, flux, falling

    @staticmethod
    def _track_noise(floor: np.ndarray, spectrum: np.ndarray) -> None:
        """Each bin's noise floor: follows a fall at once, a rise by 1 % a frame (~ +7 dB/s),
        so a sustained note (seconds) is not mistaken for the room, but a fan is learnt."""
        np.minimum(floor * 1.01, np.maximum(spectrum, 1e-7), out=floor)

    def _recognise(self, onset: int, now: np.ndarray) -> list[NoteEvent]:
        """The notes that began at ``onset``: the positive difference between the spectra of
        the window's samples after it and as many before it."""
        t = self._time(onset) - SHORT / 2 / RATE  # the short window's centre
        at = len(self._buffer) - (self._stream_end - (onset + 1) * HOP + SHORT // 2)
        after, before = self._spectra(np.stack([self._buffer[at:at + self.window_length], self._buffer[at - self.window_length:at]]))
        edge = self._buffer[at - SHORT:at + SHORT]
        if np.sum(edge[SHORT:] ** 2) < 0.5 * np.sum(edge[:SHORT] ** 2):
            return []  # quieter just after than just before: a note cut off (its click), not an attack
        began = np.maximum(after - before, 0.0)
        notes = []
        for pitch, amplitude in self.salience.estimate(began, floor=2.0 * self._noise_long):
            k = pitch - int(self.salience.pitches[0])
            bins = self.salience.bins[k][self.salience.valid[k]][:4]
            if began[bins].sum() < NEWNESS * after[bins].sum():
                continue  # it was sounding before: a fluctuation, not a note
            level_db = 20.0 * np.log10(max(amplitude * 4.0 / self.window_length, 1e-10))
            if pitch in self._sounding:
                if t - self._sounding[pitch].note.time < self.window_length / RATE:
                    continue  # the last onset's look already heard this note begin
                self._end(pitch, at=t)
            note = NoteEvent(max(t, 0.0), pitch, velocity_from_level(level_db), 0, self.heard_length)
            self._sounding[pitch] = _Sounding(note, bins, float(now[bins].sum()))
            notes.append(note)
        self.notes += len(notes)
        return notes

    def _follow(self, long: np.ndarray, frame: int) -> None:
        t = self._time(frame)
        for pitch, s in list(self._sounding.items()):
            energy = float(long[s.bins].sum())
            s.peak = max(s.peak, energy)
            if energy < self.release * s.peak or t - s.note.time > self.max_length:
                self._end(pitch, at=t)

    def _end(self, pitch: int, at: float | None = None) -> None:
        s = self._sounding.pop(pitch)
        end = self._time(self._frame) if at is None else at
        n = s.note
        self.ended.append(NoteEvent(n.time, n.pitch, n.velocity, n.channel, max(end - n.time, 0.0)))
