"""Cutting heard sound into sound events ("utterances") by amplitude threshold.

The thesis's cepstral models work on "sound segments (bounded according to amplitude
threshold)" (thesis: "aural models – cepstral models"). A :class:`Segmenter` turns a stream of
blocks into :class:`SoundEvent` objects with a hysteresis gate: an event starts when the level
rises ``on_db`` above a reference, continues while it stays ``off_db`` above it (bridging dips
shorter than ``hold``), and is kept if it lasts ``min_length``. The reference is a fixed dBFS
level or an adaptive noise floor (a low percentile of recent frame levels, so a room's hum or
a fan does not count as sound, and a continuous drone fades into the background).

Each frame's level above the reference goes through the ``hearing`` :class:`StateObject` as
saliency before the gate looks at it (thesis: "state objects"): that is where inhibition acts,
e.g. not listening while singing (see :mod:`audio.self_hearing`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from creatures.behaviour.state_object import StateObject

SILENCE_DB = -100.0
"""Frame levels are clipped here, so digital silence does not drag the floor to −∞."""


@dataclass(frozen=True, eq=False)
class SoundEvent:
    """One segmented sound: its time span (seconds), samples and loudest frame level (dBFS)."""

    start: float
    end: float
    samples: np.ndarray
    samplerate: int
    level_db: float

    @property
    def duration(self) -> float:
        return self.end - self.start


def frame_levels_db(samples: np.ndarray, frame_length: int) -> np.ndarray:
    """RMS level in dBFS of each whole, non-overlapping frame of ``samples`` (vectorised)."""
    n = len(samples) // frame_length
    frames = np.asarray(samples[: n * frame_length], dtype=np.float32).reshape(n, frame_length)
    power = np.einsum("ij,ij->i", frames, frames, dtype=np.float64) / frame_length
    return np.maximum(10.0 * np.log10(np.maximum(power, 1e-30)), SILENCE_DB)


class Segmenter:
    """Streaming amplitude-threshold segmentation with hysteresis; state carries across blocks.

    Parameters (times in seconds, levels in dB):
      ``on_db`` / ``off_db``: how far above the reference a frame must be to start / to keep
      an event. ``adaptive``: the reference is the ``floor_percentile`` of the last
      ``floor_window`` seconds of frame levels (starting from ``floor_db``); otherwise it is
      ``floor_db`` itself, so the thresholds are absolute (``floor_db + on_db`` dBFS).
      ``hold``: dips below ``off_db`` shorter than this do not end an event.
      ``min_length``: shorter events are dropped (clicks); ``max_length``: longer sounds are
      cut into several events so memory stays bounded.
      ``t0``: the time of the first sample fed (the clock time when listening began).
    """

    def __init__(
        self,
        samplerate: int,
        *,
        frame_length: int = 256,
        on_db: float = 12.0,
        off_db: float = 6.0,
        adaptive: bool = True,
        floor_db: float = -60.0,
        floor_percentile: float = 10.0,
        floor_window: float = 5.0,
        hold: float = 0.08,
        min_length: float = 0.06,
        max_length: float = 5.0,
        t0: float = 0.0,
        name: str = "hearing",
    ) -> None:
        if not on_db >= off_db > 0:
            raise ValueError(f"need on_db >= off_db > 0 for hysteresis (got {on_db}, {off_db})")
        self.samplerate = int(samplerate)
        self.frame_length = int(frame_length)
        self.on_db = float(on_db)
        self.off_db = float(off_db)
        self.adaptive = adaptive
        self.floor_db = float(floor_db)
        self.floor_percentile = float(floor_percentile)
        frame_s = self.frame_length / self.samplerate
        self._window = np.zeros(max(1, round(floor_window / frame_s)))
        self._window_pos = 0
        self._window_filled = 0
        self._hold_frames = max(0, round(hold / frame_s))
        self._min_frames = max(1, round(min_length / frame_s))
        self._max_frames = max(self._min_frames, round(max_length / frame_s))
        self._refresh = max(1, round(0.05 / frame_s))  # floor re-estimated every ~50 ms
        self._lead = max(1, round(0.05 / frame_s))  # how far back an onset may reach
        self.t0 = float(t0)
        self.hearing = StateObject(name, saliency_fn=lambda excess: max(0.0, excess) / self.on_db)
        self.rejected = 0  # events shorter than min_length
        self._frame = 0  # index of the next frame to classify
        self._audio = np.zeros(0, dtype=np.float32)  # retained samples, starting at _audio_at
        self._audio_at = 0
        self._onset: int | None = None  # first frame of the current event
        self._last_loud = 0  # last frame of the current event above off_db
        self._above_off = 0  # run of frames above off_db just before now (for onset)

    def feed(self, block: np.ndarray) -> list[SoundEvent]:
        """Classify the whole frames now available; return the events that ended."""
        self._audio = np.concatenate([self._audio, np.asarray(block, dtype=np.float32)])
        first = self._frame * self.frame_length - self._audio_at
        levels = frame_levels_db(self._audio[first:], self.frame_length)
        events: list[SoundEvent] = []
        for start in range(0, len(levels), self._refresh):
            chunk = levels[start : start + self._refresh]
            events.extend(self._gate(chunk))
            self._remember(chunk)
        self._trim()
        return events

    def flush(self) -> list[SoundEvent]:
        """End the current event at end of input (a recording that stops mid-sound)."""
        if self._onset is None:
            return []
        return self._close()

    @property
    def fed_until(self) -> float:
        """The time just after the last sample fed: where the next block begins, counted in samples."""
        return self.t0 + (self._audio_at + len(self._audio)) / self.samplerate

    def skip(self, seconds: float) -> list[SoundEvent]:
        """The clock jumped ``seconds`` ahead between two blocks (a suspended machine, a
        fast-forwarded offline run: ``creatures.clock.clock_gap``). Times are counted in
        samples, so without this every later sound would be dated before the gap, as old as
        the night is long, and a creature's memory of what it heard would never hold it. The
        sound in progress ends where it was heard; the next sample is dated after the gap.
        Returns the event that ended."""
        events = self.flush()
        self._above_off = 0
        self.t0 += float(seconds)
        return events

    @property
    def reference_db(self) -> float:
        """The level that ``on_db``/``off_db`` are measured from (the noise floor if adaptive)."""
        if not self.adaptive or self._window_filled == 0:
            return self.floor_db
        heard = self._window[: self._window_filled]
        k = int(self.floor_percentile / 100.0 * (len(heard) - 1))
        return float(np.partition(heard, k)[k])  # np.percentile costs 10× more per call

    def _remember(self, levels: np.ndarray) -> None:
        if not self.adaptive:
            return
        idx = (self._window_pos + np.arange(len(levels))) % len(self._window)
        self._window[idx] = levels
        self._window_pos = (self._window_pos + len(levels)) % len(self._window)
        self._window_filled = min(self._window_filled + len(levels), len(self._window))

    def _gate(self, levels: np.ndarray) -> list[SoundEvent]:
        reference = self.reference_db
        frame_s = self.frame_length / self.samplerate
        on, off = 1.0, self.off_db / self.on_db  # in saliency units (excess / on_db)
        events = []
        for level in levels:
            t = self.t0 + (self._frame + 1) * frame_s
            saliency = self.hearing.push(t, float(level) - reference)
            if self._onset is None:
                if saliency >= on:
                    # The event began where the level first rose past off_db (hysteresis on
                    # the way up as well as down), not where it crossed on_db.
                    self._onset = self._frame - self._above_off
                    self._last_loud = self._frame
                self._above_off = min(self._above_off + 1, self._lead) if saliency >= off else 0
            elif saliency >= off:
                self._last_loud = self._frame
                if self._frame + 1 - self._onset >= self._max_frames:
                    events.extend(self._close())
            elif self._frame - self._last_loud > self._hold_frames:
                events.extend(self._close())
            self._frame += 1
        return events

    def _close(self) -> list[SoundEvent]:
        onset, end = self._onset, self._last_loud + 1
        self._onset, self._above_off = None, 0
        if end - onset < self._min_frames:
            self.rejected += 1
            return []
        a = onset * self.frame_length - self._audio_at
        b = end * self.frame_length - self._audio_at
        samples = self._audio[max(a, 0) : b].copy()
        frame_s = self.frame_length / self.samplerate
        level = frame_levels_db(samples, self.frame_length).max(initial=SILENCE_DB)
        return [
            SoundEvent(
                start=self.t0 + onset * frame_s,
                end=self.t0 + end * frame_s,
                samples=samples,
                samplerate=self.samplerate,
                level_db=float(level),
            )
        ]

    def _trim(self) -> None:
        """Keep only samples a future event may still need (the current event + onset run)."""
        keep_frame = self._onset if self._onset is not None else self._frame - self._above_off
        drop = keep_frame * self.frame_length - self._audio_at
        if drop > 0:
            self._audio = self._audio[drop:]
            self._audio_at += drop


def segment(samples: np.ndarray, samplerate: int, **options: object) -> list[SoundEvent]:
    """Batch segmentation of a whole signal (the same gate as :class:`Segmenter`).

    >>> events = segment(signal, 22050, on_db=12, off_db=6)
    """
    segmenter = Segmenter(samplerate, **options)
    return segmenter.feed(samples) + segmenter.flush()
