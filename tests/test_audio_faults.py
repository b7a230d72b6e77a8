"""Audio devices vanishing and returning mid-run, on a fake sound card and a simulated clock.

:class:`FakeCard` stands where sounddevice stands (:class:`audio.device.AudioBackend`): one
card with a microphone and two loudspeaker channels, gone between ``gone[0]`` and ``gone[1]``
seconds. Like PortAudio it lists the devices it saw when its list was last re-read, and a
stream whose device died stays dead. How it dies is chosen: its streams stop (``stops``),
asking them anything raises (``errors``), or they stay "active" without callbacks
(``stalls``), and stopping one may then never return (``wedges``, until ``release`` is set:
PortAudio's on a JACK server that died). ``run(seconds)`` is the device's own time: it calls the
callbacks of every live stream for that many seconds of frames.
"""

from __future__ import annotations

import subprocess
import sys
import threading
import tracemalloc
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from audio import resilient
from audio.device import PortAudio, start_stream
from audio.output import LiveOutput
from audio.resilient import ResilientInput, ResilientOutput
from audio.sources import LiveInput
from creatures.clock import SimulatedClock
from creatures.runtime.live import _sound_at_end

RATE = 8000
TICK = 0.02
FRAMES = int(RATE * TICK)
BLOCK = 64


class FakePortAudioError(Exception):
    """Raised where sounddevice raises PortAudioError."""


class FakeStream:
    def __init__(self, card: FakeCard, kind: str, *, samplerate: int, channels: int, blocksize: int,
                 callback, **_: object) -> None:
        self.card, self.kind, self.channels, self.blocksize, self.callback = card, kind, channels, blocksize, callback
        self.rate = samplerate
        self.opened_at = card.clock.now()
        self.started = self.closed = self.dead = False
        self.blocks: list[np.ndarray] = []  # played (output) or delivered (input)
        self._due = 0.0

    @property
    def active(self) -> bool:
        self._notice()
        if self.dead and self.card.dies == "errors":
            raise FakePortAudioError("Unanticipated host error")
        if self.dead and self.card.dies == "stops":
            return False
        return self.started and not self.closed

    def start(self) -> None:
        if not self.card.present():
            raise FakePortAudioError("Device unavailable")
        self.started = True

    def stop(self) -> None:
        if self.dead and self.card.dies == "errors":
            raise FakePortAudioError("Unanticipated host error")
        if self.dead and self.card.dies == "wedges":
            self.card.release.wait()
        self.started = False

    def close(self) -> None:
        self.closed = True

    def run(self, seconds: float) -> None:
        self._notice()
        if self.dead or not self.started or self.closed:
            return
        self._due += seconds * self.rate
        while self._due >= self.blocksize:
            self._due -= self.blocksize
            if self.kind == "output":
                out = np.full((self.blocksize, self.channels), np.nan, dtype=np.float32)
                self.callback(out, self.blocksize, None, 0)
                self.blocks.append(out)
            else:
                sound = self.card.voice(self.blocksize)
                self.callback(sound[:, None], self.blocksize, None, 0)
                self.blocks.append(sound)

    def _notice(self) -> None:
        if not self.card.present():
            self.dead = True


class FakeCard:
    """A sound card that is unplugged at ``gone[0]`` and plugged back at ``gone[1]`` seconds."""

    PortAudioError = FakePortAudioError

    def __init__(self, clock: SimulatedClock, *, rate: int = RATE, gone: tuple[float, float] = (5.0, 10.0),
                 dies: str = "stops", relists: bool = True) -> None:
        self.clock, self.rate, self.gone, self.dies, self.relists = clock, rate, gone, dies, relists
        self.info = {"name": "Fake Card", "index": 0, "max_input_channels": 1, "max_output_channels": 2,
                     "default_samplerate": float(rate)}
        self.listed = True if not relists else self.present()
        self.refreshes = 0
        self.release = threading.Event()  # lets a wedged stream's stop return
        self.attempts = 0  # streams asked for
        self.streams: list[FakeStream] = []
        self._heard = 0

    def present(self) -> bool:
        return not self.gone[0] <= self.clock.now() < self.gone[1]

    def refresh(self) -> None:
        """Re-read the device list; ``relists=False`` is PortAudio kept from it by another open stream."""
        self.refreshes += 1
        if self.relists:
            self.listed = self.present()

    def query_devices(self, device: int | str | None = None, kind: str | None = None):
        if device is None and kind is None:
            return [self.info] if self.listed else []
        if not self.listed:
            raise FakePortAudioError(f"Error querying device {device}")
        return self.info

    def OutputStream(self, **settings) -> FakeStream:  # sounddevice's names
        return self._stream("output", settings)

    def InputStream(self, **settings) -> FakeStream:
        return self._stream("input", settings)

    def run(self, seconds: float) -> None:
        for stream in self.streams:
            stream.run(seconds)

    def voice(self, frames: int) -> np.ndarray:
        """What the microphone picks up next: a tone, sample after sample."""
        n = np.arange(self._heard, self._heard + frames)
        self._heard += frames
        return (0.5 * np.sin(0.05 * n)).astype(np.float32)

    def _stream(self, kind: str, settings: dict) -> FakeStream:
        self.attempts += 1
        if not self.present():
            raise FakePortAudioError("Device unavailable")
        if settings["samplerate"] != self.rate:
            raise FakePortAudioError(f"Invalid sample rate {settings['samplerate']}")
        stream = FakeStream(self, kind, **settings)
        self.streams.append(stream)
        return stream


def numbered(step: int) -> np.ndarray:
    """A stereo block whose every frame is different and none is silent."""
    n = np.arange((step - 1) * FRAMES, step * FRAMES)
    left = (n % 997 + 1) / 1000.0
    return np.stack([left, -left], axis=1)


def sounding(blocks: list[np.ndarray]) -> np.ndarray:
    """What a stream played, without the silence its callbacks padded underruns with."""
    played = np.concatenate(blocks)
    return played[np.any(played != 0.0, axis=1)]


def run_output(card: FakeCard, out: ResilientOutput, seconds: float) -> tuple[list[tuple[float, np.ndarray]], int]:
    """Write one block a tick as the live loop does; returns what was written (with its time)
    and how many frames were written while the card was unplugged."""
    written, while_gone = [], 0
    for step in range(1, int(round(seconds / TICK)) + 1):
        t = card.clock.advance_to(round(step * TICK, 6))
        block = numbered(step)
        out.write(block)  # never raises
        written.append((t, block))
        while_gone += 0 if card.present() else len(block)
        card.run(TICK)
    card.run(0.5)  # the device plays whatever is still queued
    return written, while_gone


@pytest.mark.parametrize("dies", ["stops", "errors"])
def test_output_survives_its_device_vanishing_and_returning(dies):
    clock = SimulatedClock()
    card = FakeCard(clock, dies=dies)
    reports: list[str] = []
    out = ResilientOutput(RATE, 2, clock=clock, blocksize=BLOCK, retry_interval=1.0, backend=card,
                          report=reports.append)
    assert out.describe() == f"live at {RATE} Hz"
    written, while_gone = run_output(card, out, 15.0)

    assert (out.faults, out.reopened) == (1, 1)
    assert len(reports) == 2 and "lost" in reports[0] and "is back" in reports[1]
    assert out.dropped == while_gone == 5 * RATE  # every block written while it was gone, and no other
    first, again = card.streams
    assert first.closed and again.opened_at == 10.0
    assert card.refreshes == 5  # looked for it once a second: at 6, 7, 8, 9 and 10 s
    # Before the fault the card played what was written, in order, up to what the ring held.
    before = np.concatenate([b for t, b in written if t < 5.0]).astype(np.float32)
    played = sounding(first.blocks)
    np.testing.assert_array_equal(played, before[: len(played)])
    assert len(before) - len(played) <= out.buffer_seconds * RATE
    # After the return every frame written reaches the card.
    after = np.concatenate([b for t, b in written if t >= again.opened_at]).astype(np.float32)
    np.testing.assert_array_equal(sounding(again.blocks), after)
    assert out.frames_written == len(before) + out.dropped + len(after)
    out.close()
    assert again.closed


def test_output_stream_left_active_without_callbacks_is_taken_as_lost():
    clock = SimulatedClock()
    card = FakeCard(clock, dies="stalls")
    reports: list[tuple[float, str]] = []
    out = ResilientOutput(RATE, 2, clock=clock, blocksize=BLOCK, retry_interval=1.0, stall_timeout=0.5,
                          backend=card, report=lambda message: reports.append((clock.now(), message)))
    written, _ = run_output(card, out, 15.0)

    assert (out.faults, out.reopened) == (1, 1)
    (lost_at, lost), (back_at, back) = reports
    assert "no callback for 0.5 s" in lost and 5.0 < lost_at <= 5.5 + TICK
    assert "is back" in back and 10.0 <= back_at <= 11.0
    assert out.overruns > 0  # what went into the stalled ring before the stall was seen
    after = np.concatenate([b for t, b in written if t >= back_at]).astype(np.float32)
    np.testing.assert_array_equal(sounding(card.streams[-1].blocks), after)


def test_a_stream_portaudio_never_lets_go_of_wedges_the_output_and_that_is_said(monkeypatch):
    """PortAudio stopping a stream whose JACK server died never returns, and nothing opens in
    that process after it: the stream is abandoned (so is ``Pa_Terminate`` at exit), the loss
    and the wedge are said, the device is not looked for again, and writing never waits."""
    monkeypatch.setattr(resilient, "LET_GO_TIMEOUT", 0.05)
    given_up: list[bool] = []
    monkeypatch.setattr(resilient, "abandoned", lambda: given_up.append(True))
    clock = SimulatedClock()
    card = FakeCard(clock, dies="wedges")
    reports: list[str] = []
    out = ResilientOutput(RATE, 2, clock=clock, blocksize=BLOCK, retry_interval=1.0, stall_timeout=0.5,
                          backend=card, report=reports.append)
    try:
        written, _ = run_output(card, out, 15.0)
        assert (out.faults, out.reopened) == (1, 0) and not out.connected and given_up == [True]
        lost, wedged = reports
        assert "lost (no callback for 0.5 s)" in lost
        assert wedged == f"{out.wedged}: no stream can open in this process any more"
        assert out.wedged == "PortAudio did not let go of the lost audio output (default) in 0.05 s (its JACK server died?)"
        assert card.attempts == 1 and card.refreshes == 0  # not looked for again, back at 10 s or not
        assert out.dropped == sum(len(b) for t, b in written if t >= 5.5)  # every block since, none waited for
        out.close()  # the abandoned stream is not waited for again
    finally:
        card.release.set()


def test_an_abandoned_stream_drops_sounddevices_exit_handler():
    """Its ``Pa_Terminate`` would wait for the abandoned stream as its stop did: the process
    could save, and never end."""
    script = ("import atexit, sys, types\n"
              "sd = types.ModuleType('sounddevice'); sd._exit_handler = lambda: print('Pa_Terminate')\n"
              "sys.modules['sounddevice'] = sd; atexit.register(sd._exit_handler)\n"
              "from audio.device import abandoned\n"
              "atexit.register(lambda: print('other handlers run'))\n"
              "abandoned() if sys.argv[1] == 'abandoned' else None\n")
    ends = {how: subprocess.run([sys.executable, "-c", script, how], capture_output=True, text=True, timeout=60,
                                cwd=Path(__file__).parent.parent).stdout.split()
            for how in ("abandoned", "kept")}
    assert ends == {"abandoned": ["other", "handlers", "run"], "kept": ["other", "handlers", "run", "Pa_Terminate"]}


@pytest.mark.parametrize("gone, said", [((5.0, 10.0), f"live at {RATE} Hz once it came back"),
                                        ((5.0, 1e9), "lost mid-run (no audio output devices found")])
def test_the_run_says_where_the_sound_went_at_the_end(gone, said):
    """The summary's sound was what the run began with ("live at …"), whatever happened since."""
    clock = SimulatedClock()
    card = FakeCard(clock, gone=gone)
    out = ResilientOutput(RATE, 2, clock=clock, blocksize=BLOCK, retry_interval=1.0, backend=card, report=print)
    run_output(card, out, 15.0)
    assert _sound_at_end(out, f"live at {RATE} Hz").startswith(said)
    out.close()


def test_output_reopens_when_the_device_list_cannot_be_reread():
    """PortAudio keeps listing a vanished device while another stream is open: opening it
    fails until it is back, once per retry interval, and is reported once."""
    clock = SimulatedClock()
    card = FakeCard(clock, relists=False)
    reports: list[str] = []
    out = ResilientOutput(RATE, 2, clock=clock, blocksize=BLOCK, retry_interval=1.0, backend=card,
                          report=reports.append)
    written, while_gone = run_output(card, out, 15.0)

    assert (out.faults, out.reopened) == (1, 1) and len(reports) == 2
    assert card.attempts == 1 + 5  # the first open, then 6, 7, 8, 9 s (refused) and 10 s
    assert out.dropped == while_gone
    after = np.concatenate([b for t, b in written if t >= 10.0]).astype(np.float32)
    np.testing.assert_array_equal(sounding(card.streams[-1].blocks), after)


def test_output_missing_at_start_plays_once_it_appears_at_its_own_rate():
    clock = SimulatedClock()
    card = FakeCard(clock, rate=2 * RATE, gone=(0.0, 3.0))
    reports: list[str] = []
    out = ResilientOutput(RATE, 2, clock=clock, blocksize=BLOCK, retry_interval=1.0, backend=card,
                          report=reports.append)
    assert not out.connected and out.describe() == "silent: " + out.reason
    assert "no audio output devices found" in out.reason
    tone = 0.3 * np.sin(2 * np.pi * 440.0 * np.arange(int(6.0 * RATE)) / RATE)
    while_gone = 0
    for step in range(1, int(round(6.0 / TICK)) + 1):
        clock.advance_to(round(step * TICK, 6))
        out.write(np.repeat(tone[(step - 1) * FRAMES : step * FRAMES, None], 2, axis=1))
        while_gone += 0 if card.present() else FRAMES
        card.run(TICK)

    assert (out.faults, out.reopened) == (0, 1)
    assert len(reports) == 2 and "audio output (default) unavailable" in reports[0] and "is back" in reports[1]
    assert out.describe() == f"live at {2 * RATE} Hz (resampled from {RATE} Hz)"
    assert out.dropped == while_gone == 3 * RATE - FRAMES  # written at 0.02 … 2.98 s
    played = np.concatenate(card.streams[-1].blocks)[:, 0]
    assert np.count_nonzero(played) >= 0.95 * 2 * 3 * RATE  # the last 3 s sounded, at twice the rate
    spectrum = np.abs(np.fft.rfft(played * np.hanning(len(played))))
    assert np.argmax(spectrum) * 2 * RATE / len(played) == pytest.approx(440.0, abs=2.0)


def test_input_survives_its_device_vanishing_and_returning():
    clock = SimulatedClock()
    card = FakeCard(clock)
    reports: list[str] = []
    mic = ResilientInput(clock=clock, samplerate=RATE, block_size=BLOCK, retry_interval=1.0, backend=card,
                         report=reports.append)
    heard: list[tuple[float, np.ndarray]] = []
    for step in range(1, 751):
        t = clock.advance_to(round(step * TICK, 6))
        card.run(TICK)
        block = mic.read()  # never raises
        assert block.dtype == np.float32 and np.isfinite(block).all()
        heard.append((t, block))

    assert (mic.faults, mic.reopened) == (1, 1)
    assert len(reports) == 2 and "audio input (default) lost" in reports[0] and "is back" in reports[1]
    first, again = card.streams
    assert again.opened_at == 10.0
    assert all(len(b) == 0 for t, b in heard if 5.0 <= t <= 10.0)  # nothing heard while it was gone
    assert all(len(b) > 0 for t, b in heard if t > 10.0)  # and sound every tick once it is back
    np.testing.assert_array_equal(np.concatenate([b for t, b in heard if t < 5.0]), np.concatenate(first.blocks))
    np.testing.assert_array_equal(np.concatenate([b for t, b in heard if t > 10.0]), np.concatenate(again.blocks))
    assert mic.overruns == 0 and mic.driver_overflows == 0
    mic.stop()
    assert again.closed


def test_callbacks_allocate_no_buffers():
    """The real-time callbacks only copy: a buffer made per call would show in the peak
    (numpy reports its buffers to tracemalloc); the views they take are a few hundred bytes."""
    card, block = FakeCard(SimulatedClock()), 1024
    out = LiveOutput(RATE, 2, blocksize=block, pace=False, backend=card)
    mic = LiveInput(samplerate=RATE, block_size=block, buffer_seconds=1.0, backend=card)
    mic.start()
    out.write(np.full((RATE // 4, 2), 0.1))  # two callbacks' worth, then underruns
    outdata, indata = np.zeros((block, 2), np.float32), np.ones((block, 1), np.float32)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for _ in range(50):  # through the rings' wrap, underruns (output) and overruns (input)
            out._callback(outdata, block, None, None)
            mic.callback(indata, block, None, None)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert out.underruns > 0 and mic.overruns > 0
    assert peak - before < block  # a quarter of one mono float32 block


def test_portaudio_rereads_its_device_list_only_while_no_stream_is_open():
    """Re-initialising PortAudio closes every stream, so it waits for none to be open."""

    class Stream:
        def __init__(self, fails: bool) -> None:
            self.fails, self.closed = fails, False

        def start(self) -> None:
            if self.fails:
                raise FakePortAudioError("Device unavailable")

        def close(self) -> None:
            self.closed = True

    calls: list[str] = []
    sd = SimpleNamespace(PortAudioError=FakePortAudioError, OutputStream=lambda **_: Stream(False),
                         InputStream=lambda **_: Stream(True), _terminate=lambda: calls.append("terminate"),
                         _initialize=lambda: calls.append("initialize"))
    backend = PortAudio(sd)

    with pytest.raises(FakePortAudioError):
        start_stream(backend, "input")  # would not start: closed again, so it blocks nothing
    playing = start_stream(backend, "output")
    backend.refresh()
    assert calls == []
    playing.close()
    backend.refresh()
    assert calls == ["terminate", "initialize"]


def test_a_live_run_says_the_mix_clipped_when_it_first_does_not_only_when_it_stops():
    """An installation too loud for its speakers was said to clip only at the run's end,
    weeks on: the first clipped block is said at the next housekeeping, once."""
    import installations
    from creatures.events import EventLog
    from creatures.runtime.live import _Counters
    from creatures.runtime.schema import load_installation
    from creatures.runtime.session import Session
    from midi.sinks import MemorySink

    session = Session(load_installation(installations.path("exchange")), SimulatedClock(), EventLog(), MemorySink())
    said: list[str] = []
    counters = _Counters(session, None, None, said.append)
    quiet, loud = (np.full((len(session.creatures), 64), level) for level in (0.1, 4.0))
    session.mixer.mix(quiet)
    counters.log_change()
    assert said == []
    for _ in range(3):
        session.mixer.mix(loud)
        counters.log_change()
    assert len(said) == 1 and said[0].startswith("the mix clipped: 128 samples")  # the first block's, both channels
