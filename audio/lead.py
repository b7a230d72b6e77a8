"""How much sound waits ahead of the loudspeaker, kept where a late write cannot starve it.

A live run writes one tick's mix per tick, paced by the wall clock; the device takes a block
per callback, paced by its own clock. What the device finds spare (the ring's fill less the
block it takes) is what absorbs everything between the two (measured on JACK's dummy server,
bench live, issue 14):

* the streaming resampler hands its output on in chunks (soxr HQ, 22050 → 44100 Hz: 1660
  frames a tick and 3320 every sixteenth, so up to 38 ms is held back at times);
* ticks and callbacks jitter by a few ms, and the one can fall just after the other;
* the start: the device calls back before the first tick's mix exists, and the first two
  writes carry no frames (the first tick is an instant, the resampler's first chunk is empty),
  so a fixed lead written once at the start was played out as silence before any sound came,
  and the run went on with no spare at all: 0–4 underruns a minute, each where a write came
  a millisecond after a callback at the bottom of the resampler's chunking;
* the device's clock against the wall clock: none on an idle dummy server (0.25 ms in 60 s),
  whose frame clock follows the system clock; but on a loaded machine it loses the cycles it
  ran late and never makes them up (19–110 ms in a 60 s run; a client alone on it lost 308 ms
  in 30 s, in stalls of 25–73 ms), so the ring fills; a real interface drifts ~10–100 ppm
  either way, a second every few hours. Drift was not what underran: it fills the ring.

So the spare is measured where it matters, in the device's callback (the lowest seen, in the
device's own frames, which counts the jitter and the drift alike), and :class:`Lead` keeps its
mean near ``target``: once a window it sets how much faster or slower than nominal the resampler
turns the mix into the device's frames (:attr:`Lead.stretch`, at most :data:`MOST_STRETCH`
off: a pitch change of 3.5 cents, which no listener hears on a held tone), and when the spare
falls below ``floor`` all the same (each start, a device reopened, a stall longer than the
lead) it puts silence ahead of the block at once, counted in :attr:`Lead.gaps`, so the lead
is whole again at once rather than eased back over seconds; when the spare is far above the
target (the device stalled while the mix kept coming) the surplus is left out at once
(:data:`SKIP_ABOVE`).

The live output's floor is 0 (:data:`audio.resilient.GAP_FLOOR`): silence goes in only where
the device already ran dry. A floor above it put a gap where no sound was missing: on an idle
machine the lowest spare before a write already spreads 15 ms below its mean (the device's
callback falls anywhere in the tick, and JACK's dummy server jitters), and a floor at a third
of a 30 ms lead left 3 ms of that margin, so a CI machine's busier scheduling put one
self-made gap in each of two 30 s runs (stop 28), where the device still held 5–10 ms of sound.
The resampler is soxr's variable-rate one, which also hands on every chunk whole (the steady
one, above, is what chunked).

Why the sound follows the device rather than the loop following it: the ticks also send MIDI
(to a synth on its own clock), OSC time-tagged in Unix time, and hear notes stamped on the
wall clock, so the creatures' time must stay the wall clock's; pacing the mix by the device's
frames would put the voices and the notes apart by whatever the device drifted. Adapting the
resampler to the device is what JACK's own bridges between clocks do (alsa_in, zita-ajbridge).
"""

from __future__ import annotations

from dataclasses import dataclass

UNSEEN = 1 << 62
"""The lowest spare when no callback has reported one since the last look."""

MOST_STRETCH = 0.002
"""The largest change of the resampling ratio (2000 ppm): well beyond any sound card's drift,
and it gives a stall of 40 ms back in 20 s."""

SKIP_ABOVE = 4
"""A window whose mean spare passed this many targets leaves the surplus out at once (counted
in :attr:`Lead.skips`) instead of easing it away: measured at a run's start on a loaded
machine, JACK's dummy server called back once, then not for 423 ms while the ticks' mix came,
and at the greatest stretch 4000 frames of surplus took 45 s to ease away."""

GAIN = 0.5
"""Of the spare's error seen over a window, the part the next window corrects: below 1, so a
correction already under way when the window was measured is not made twice. Proportional
only (the ratio is set from this window's error, not added to): the spare is the sum of the
ratio's past, so adding would swing it. A steady drift keeps a small steady error:
drift × window / GAIN (100 ppm over 2 s at 44.1 kHz: 18 frames)."""


@dataclass
class Lead:
    """The spare sound kept ahead of a device, from the lowest spare it saw since the last block.

    Sizes are frames at the device's rate. Every ``window`` frames of blocks, :attr:`stretch`
    (output frames per nominal output frame) is set from the mean over that window of the
    lowest spare before each block: the mean, because one lowest jitters with the block's
    lateness (a ratio set from it would wobble the pitch), while the mean of the lowest
    moves only with the drift.
    """

    target: int
    floor: int
    window: int
    gaps: int = 0  # times silence went ahead of a block (the spare fell below the floor)
    silence: int = 0  # frames of silence put in
    skips: int = 0  # times sound was left out (the spare was far above the target)
    skipped: int = 0  # frames left out
    stretch: float = 1.0

    def __post_init__(self) -> None:
        if not 0 <= self.floor < self.target or self.window <= 0:
            raise ValueError(f"need 0 <= floor < target and window > 0, got {self}")
        self._sum = self._looks = self._seen = 0  # this window's lowest spares (summed, counted), frames
        self._excess = 0  # frames still to leave out, after a skip
        self._last = 0  # the latest lowest spare seen

    def correct(self, lowest: int, frames: int) -> int:
        """``lowest``: the lowest spare any callback saw since the last block (negative: it
        played silence; :data:`UNSEEN`: no callback came); ``frames``: this block's length.
        Returns the frames of silence to put before the block (> 0), or of the block's start
        to leave out (< 0), and may move :attr:`stretch`."""
        if lowest < self.floor:
            gap = self.target - lowest
            self.gaps += 1
            self.silence += gap
            self._sum = self._looks = self._seen = self._excess = 0  # the spare starts again from here
            return gap
        if self._excess:  # while it goes, the spare is not measured: it is falling by design
            return self._leave_out(frames)
        if lowest != UNSEEN:
            self._sum += lowest
            self._looks += 1
            self._last = lowest
        self._seen += frames
        if self._seen >= self.window:
            if self._looks:
                mean = self._sum / self._looks
                error = (mean - self.target) / self.window  # too much spare: stretch less
                self.stretch = min(1 + MOST_STRETCH, max(1 - MOST_STRETCH, 1 - GAIN * error))
                if mean > SKIP_ABOVE * self.target:  # what is too much is the spare now, not the window's
                    self._excess = max(0, self._last - self.target)
                    self.skips += 1
            self._sum = self._looks = self._seen = 0
            if self._excess:
                return self._leave_out(frames)
        return 0

    def _leave_out(self, frames: int) -> int:
        left_out = min(self._excess, frames)
        self._excess -= left_out
        self.skipped += left_out
        return -left_out
