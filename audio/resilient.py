"""Live audio that survives its device vanishing and returning.

An installation runs for weeks; a USB interface gets unplugged, a JACK server restarts. As
:class:`midi.ports.ResilientPort` does for MIDI, :class:`ResilientOutput` and
:class:`ResilientInput` report the loss once, keep the creature's loop running (nothing
escapes ``write``/``read``), look for the device again at a bounded rate measured in clock
time, reopen it when it is back and report that once. They count faults, reopens and what
was dropped while the device was gone.

A stream is taken as lost when PortAudio stops it (a failed device, or a callback that raised
``CallbackAbort``), when asking whether it is active raises, when no callback has come for
``stall_timeout`` seconds (a stream whose server died can stay "active"), or when the device
is no longer listed. A lost stream is let go on a thread of its own, given
:data:`LET_GO_TIMEOUT`: PortAudio stopping a stream whose JACK server died waits for a callback
that never comes, and PortAudio cannot open another stream in that process after it (its JACK
client died with the server), so such a stream is abandoned and the watch is *wedged*: it looks
for the device no more, says so, and the live run ends with :data:`creatures.runtime.keeper.AFRESH`
for its keeper to start it afresh (measured with a real JACK dummy server killed mid-run: the
stop never returned, and the process then hung at exit in ``Pa_Terminate``). Device access
goes through :class:`audio.device.AudioBackend`, so tests drive a fake device on a simulated
clock. The real-time callbacks stay those of
:class:`audio.output.LiveOutput` and :class:`audio.sources.LiveInput` (copy and count only).
Checks run on the creature's thread at a bounded rate, or, given a
:class:`~creatures.supervisor.Supervisor` (as a live run does), on the supervisor's thread:
re-listing devices and reopening a stream (PortAudio restarts to see new devices) can take
far longer than a tick.
"""

from __future__ import annotations

import logging
import threading
from typing import Callable, Generic, Protocol, TypeVar

import numpy as np
import soxr

from audio.device import AudioBackend, abandoned, device_rate, find_device, portaudio
from audio.lead import UNSEEN, Lead
from audio.output import AudioOutput, LiveOutput
from audio.sources import ANALYSIS_RATE, AudioSource, LiveInput
from creatures.clock import Clock
from creatures.supervisor import Supervisor

log = logging.getLogger(__name__)

LET_GO_TIMEOUT = 2.0
"""Seconds a lost stream is given to stop and close before it is abandoned (a sound card's
takes milliseconds; one whose JACK server died never returns)."""

SUPERVISED_CHECK = 0.25
"""Seconds between looks at a supervised stream (stopped? stalled?); listing stays at ``retry_interval``."""

LEAD_WINDOW = 2.0
"""Seconds of sound over which the lowest spares, averaged, set the resampling ratio
(audio/lead.py): 50 blocks at a 40 ms tick, enough for their jitter to average out."""

GAP_FLOOR = 0
"""Frames of spare below which silence goes ahead of a block (audio/lead.py): none, so a gap
is put in only where the device already played silence (an underrun), never where a late
write still found sound in the ring."""


class LiveStream(Protocol):
    """What a :class:`DeviceWatch` looks at: the device's callbacks and PortAudio's state."""

    callbacks: int

    @property
    def active(self) -> bool: ...


S = TypeVar("S", bound=LiveStream)


class DeviceWatch(Generic[S]):
    """One live stream kept open across device faults: when to look for the device again,
    what counts as lost, and telling each loss and each return once.

    ``start`` makes a started stream (or raises); ``stop`` lets one go. :meth:`poll` never
    raises: whatever a backend throws means the device is gone.
    """

    def __init__(self, what: str, kind: str, device: str | int | None, clock: Clock, *,
                 start: Callable[[], S], stop: Callable[[S], None], backend: AudioBackend | None,
                 retry_interval: float, stall_timeout: float, report: Callable[[str], None],
                 supervisor: Supervisor | None = None) -> None:
        if retry_interval <= 0 or stall_timeout <= 0:
            raise ValueError(f"retry_interval and stall_timeout must be > 0, got {retry_interval}, {stall_timeout}")
        self.what, self.kind, self.device, self.clock = what, kind, device, clock
        self.backend = backend
        self.retry_interval = retry_interval
        self.stall_timeout = stall_timeout
        self.report = report
        self.stream: S | None = None
        self.faults = 0  # times the device was lost
        self.reopened = 0  # times it came back (or first appeared after being missing)
        self.reason = ""  # why there is no stream, while there is none
        self.wedged = ""  # why no stream can open in this process any more (see the module docstring)
        self._start, self._stop = start, stop
        self._told_missing = False
        self._looked = False
        self._last_look = -float("inf")
        self._beats = 0
        self._last_beat = 0.0
        self._supervised = False
        self.check()  # before the run starts: the device is there from the first block
        if supervisor is not None:
            self._supervised = True
            self._job = supervisor.every(min(SUPERVISED_CHECK, retry_interval), self.check, name=what)

    def poll(self) -> S | None:
        """The open stream, or None while the device is gone; unsupervised, looks again when
        it is due (on the caller's thread)."""
        if self._supervised:
            return self.stream
        return self.check()

    def check(self) -> S | None:
        """Is the stream still well, or the device back? (Blocking: see the module docstring.)"""
        if self.wedged:
            return None
        now = self.clock.now()
        due = now - self._last_look >= self.retry_interval
        if due:
            self._last_look = now
        if self.stream is not None:
            why = self._trouble(self.stream, now, listing=due)
            if why is not None:
                self.lose(why)
        elif due:
            self._reopen(now)
        return self.stream

    def lose(self, why: str) -> None:
        """Count the fault, say so once, and let the stream go: in that order, since letting go
        may never return (PortAudio stopping a stream whose JACK server died waits for a
        callback that never comes), and the loss must be said all the same."""
        self.faults += 1
        self.reason = why
        self._told_missing = True
        self.report(f"{self.what} lost ({why}); will reopen it when it returns")
        self._let_go()

    def close(self) -> None:
        if self._supervised:
            self._job.cancel()
            self._supervised = False
        self._let_go()

    def _trouble(self, stream: S, now: float, *, listing: bool) -> str | None:
        try:
            if not stream.active:
                return "its stream stopped"
            if stream.callbacks != self._beats:
                self._beats, self._last_beat = stream.callbacks, now
            elif now - self._last_beat >= self.stall_timeout:
                return f"no callback for {now - self._last_beat:.1f} s"
            if listing:
                find_device(self.device, kind=self.kind, backend=self.backend or portaudio())
        except Exception as exc:  # any backend error means the device is gone
            return str(exc) or type(exc).__name__
        return None

    def _reopen(self, now: float) -> None:
        try:
            if self._looked:  # PortAudio lists the devices it saw when it started
                (self.backend or portaudio()).refresh()
            self._looked = True
            stream = self._start()
        except Exception as exc:
            self.reason = str(exc) or type(exc).__name__
            if not self._told_missing:
                self.report(f"{self.what} unavailable ({self.reason}); carrying on without it, "
                            f"looking again every {self.retry_interval:g} s")
                self._told_missing = True
            return
        self.stream = stream
        self._beats, self._last_beat = stream.callbacks, now
        self.reason = ""
        if self._told_missing:
            self.reopened += 1
            self.report(f"{self.what} is back")
        self._told_missing = False

    def _let_go(self) -> None:
        stream, self.stream = self.stream, None
        if stream is None:
            return
        closing = threading.Thread(target=self._stop_quietly, args=(stream,), name=f"closing {self.what}",
                                   daemon=True)
        closing.start()
        closing.join(LET_GO_TIMEOUT)
        if closing.is_alive():
            self.wedged = f"PortAudio did not let go of the lost {self.what} in {LET_GO_TIMEOUT:g} s (its JACK server died?)"
            self.report(f"{self.wedged}: no stream can open in this process any more")
            abandoned()

    def _stop_quietly(self, stream: S) -> None:
        try:
            self._stop(stream)
        except Exception as exc:
            log.debug("closing a lost %s failed: %s", self.what, exc)


def _named(kind: str, device: str | int | None) -> str:
    return f"audio {kind} {device if device is not None else '(default)'}"


class Watched(Generic[S]):
    """What a device kept by a :class:`DeviceWatch` tells of itself, the same for a loudspeaker
    and a microphone (the status line and the events log read these)."""

    watch: DeviceWatch[S]

    @property
    def connected(self) -> bool:
        return self.watch.stream is not None

    @property
    def faults(self) -> int:
        return self.watch.faults

    @property
    def reopened(self) -> int:
        return self.watch.reopened

    @property
    def reason(self) -> str:
        """Why there is no stream (no sound out, or none heard), while there is none."""
        return self.watch.reason

    @property
    def wedged(self) -> str:
        """Why the device cannot come back in this process (empty while it can)."""
        return self.watch.wedged


class ResilientOutput(AudioOutput, Watched[LiveOutput]):
    """The loudspeaker, kept across device faults; ``write`` never raises for the device.

    Blocks come at ``sample_rate`` and are resampled to the rate the device runs at each time
    it opens (JACK will not change its rate, and a device may come back at another one).
    While the device is gone blocks are dropped and counted in :attr:`dropped` (frames at
    ``sample_rate``). Writing never waits: the caller is paced by its clock, and a block that
    finds the ring full is dropped and counted in :attr:`overruns`.

    With ``lead`` (seconds) the spare sound the device finds at each callback is kept near
    that much (:class:`audio.lead.Lead`): a caller that writes a tick's audio once per tick,
    paced by its clock, would otherwise leave the ring near empty just before each write, and
    any lateness of a write (a busy machine wakes a loop a few ms late), the resampler's
    chunking or the device's clock drifting from the caller's would be an underrun. The
    price is that much latency. :attr:`gaps` counts the silences put in when the spare ran
    out all the same (each start, and any stall), :attr:`skips` the times sound was left out
    when it was far too large (the device stalled while the mix kept coming).
    """

    def __init__(self, sample_rate: int, channels: int = 2, *, clock: Clock, device: str | int | None = None,
                 blocksize: int = 512, buffer_seconds: float = 0.25, retry_interval: float = 2.0,
                 stall_timeout: float = 2.0, backend: AudioBackend | None = None,
                 report: Callable[[str], None] = log.warning, supervisor: Supervisor | None = None,
                 lead: float = 0.0) -> None:
        super().__init__(sample_rate, channels)
        self.device = device
        self.lead = lead
        self.keeper: Lead | None = None  # the open stream's (audio/lead.py), with a lead
        self._past_gaps = self._past_skips = 0  # of the streams let go
        self.blocksize = blocksize
        self.buffer_seconds = buffer_seconds
        self.backend = backend
        self.dropped = 0
        self.device_rate: int | None = None  # the rate of the open device
        self._resampler: soxr.ResampleStream | None = None
        self._past_underruns = self._past_overruns = 0  # of the streams let go
        self.watch: DeviceWatch[LiveOutput] = DeviceWatch(
            _named("output", device), "output", device, clock, start=self._open, stop=self._let_go,
            backend=backend, retry_interval=retry_interval, stall_timeout=stall_timeout, report=report,
            supervisor=supervisor)

    @property
    def underruns(self) -> int:
        """Callbacks that found nothing to play (padded with silence), over every stream."""
        live = self.watch.stream
        return self._past_underruns + (live.underruns if live is not None else 0)

    @property
    def gaps(self) -> int:
        """Silences put ahead of a block because the spare ran out, over every stream."""
        return self._past_gaps + (self.keeper.gaps if self.keeper is not None else 0)

    @property
    def skips(self) -> int:
        """Times sound was left out because the spare was far too large, over every stream."""
        return self._past_skips + (self.keeper.skips if self.keeper is not None else 0)

    @property
    def overruns(self) -> int:
        """Blocks dropped because the device had not played the ones before, over every stream."""
        live = self.watch.stream
        return self._past_overruns + (live.overruns if live is not None else 0)

    def describe(self) -> str:
        """Where the sound goes now: ``live at 44100 Hz (resampled from 22050 Hz)`` or ``silent: why``."""
        if self.device_rate is None:
            return f"silent: {self.reason}"
        resampled = f" (resampled from {self.sample_rate} Hz)" if self.device_rate != self.sample_rate else ""
        return f"live at {self.device_rate} Hz{resampled}"

    def _write(self, block: np.ndarray) -> None:
        live = self.watch.poll()
        if live is None:
            self.dropped += len(block)
            return
        # read once: a lost stream is let go on another thread, which drops them meanwhile
        resampler, keeper = self._resampler, self.keeper
        samples = np.asarray(block, dtype=np.float32)
        if resampler is not None:
            samples = resampler.resample_chunk(samples)
        if keeper is not None and resampler is not None:
            # a callback between the read and the reset loses its sample: one block's look, no more
            lowest, live.lowest_spare = live.lowest_spare, UNSEEN
            stretch = keeper.stretch
            change = keeper.correct(lowest // self.channels if lowest != UNSEEN else UNSEEN, len(samples))
            if change > 0:
                live.write(np.zeros((change, self.channels), dtype=np.float32))
            elif change < 0:
                samples = samples[-change:]
            if keeper.stretch != stretch:  # eased in over the next block
                resampler.set_io_ratio(self.sample_rate, live.sample_rate * keeper.stretch, len(block))
        live.write(samples)

    def _close(self) -> None:
        self.watch.close()

    def _open(self) -> LiveOutput:
        backend = self.backend or portaudio()
        rate = device_rate(self.device, kind="output", backend=backend) or self.sample_rate
        live = LiveOutput(rate, self.channels, blocksize=self.blocksize, device=self.device,
                          buffer_seconds=self.buffer_seconds, pace=False, backend=backend)
        self.device_rate = rate
        if self.lead > 0:  # the variable-rate resampler, which keeps the lead when the clocks drift
            target = int(self.lead * rate)
            self.keeper = Lead(target=target, floor=GAP_FLOOR, window=int(LEAD_WINDOW * rate))
            self._resampler = soxr.ResampleStream(self.sample_rate, rate, self.channels, dtype="float32", vr=True)
        else:
            self._resampler = (None if rate == self.sample_rate else
                               soxr.ResampleStream(self.sample_rate, rate, self.channels, dtype="float32"))
        return live

    def _let_go(self, live: LiveOutput) -> None:
        self._past_underruns += live.underruns
        self._past_overruns += live.overruns
        if self.keeper is not None:
            self._past_gaps += self.keeper.gaps
            self._past_skips += self.keeper.skips
            self.keeper = None
        self.device_rate = None
        self._resampler = None  # not kept alive by a stop that never returns (a wedge)
        live.close()


class ResilientInput(AudioSource, Watched[LiveInput]):
    """A microphone kept across device faults; ``read`` never raises for the device.

    Reads give what arrived since the last one (resampled to ``samplerate``, see
    :class:`audio.sources.LiveInput`), and an empty block while the device is gone: the
    creature hears nothing rather than invented silence. The counters of :attr:`live` carry
    on across reopens.
    """

    def __init__(self, device: str | int | None = None, *, clock: Clock, samplerate: int = ANALYSIS_RATE,
                 block_size: int = 0, buffer_seconds: float = 2.0, retry_interval: float = 2.0,
                 stall_timeout: float = 2.0, backend: AudioBackend | None = None,
                 report: Callable[[str], None] = log.warning, supervisor: Supervisor | None = None) -> None:
        self.samplerate = int(samplerate)
        self.live = LiveInput(device, samplerate=samplerate, block_size=block_size,
                              buffer_seconds=buffer_seconds, backend=backend)
        self.watch: DeviceWatch[LiveInput] = DeviceWatch(
            _named("input", device), "input", device, clock, start=self._start, stop=LiveInput.stop,
            backend=backend, retry_interval=retry_interval, stall_timeout=stall_timeout, report=report,
            supervisor=supervisor)
        self._nothing = np.zeros(0, dtype=np.float32)

    @property
    def overruns(self) -> int:
        """Blocks dropped because the creature did not read fast enough."""
        return self.live.overruns

    @property
    def driver_overflows(self) -> int:
        """Callbacks whose driver reported an input overflow."""
        return self.live.driver_overflows

    def read(self) -> np.ndarray:
        live = self.watch.poll()
        if live is None:
            return self._nothing
        return live.read()

    def stop(self) -> None:
        self.watch.close()

    def _start(self) -> LiveInput:
        self.live.start()
        return self.live
