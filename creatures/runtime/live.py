"""``creatures run``: an installation live, on the wall clock, with real devices.

Behaviour ticks fall on a fixed grid of elapsed seconds (machine-independent time), and
between ticks notes are heard within about a millisecond of arriving
(:mod:`creatures.runtime.ticking`); if the machine falls behind by more than a second the run
skips ahead rather than racing to catch up, and counts it. Devices are optional and
resilient: a named MIDI port that is absent is reported once (with how to list devices) and
reopened when it appears; a missing audio device falls back to silence with the reason
printed. Audio underruns (the loudspeaker played silence: the mix came late) and microphone
overruns (input dropped: the loop read too slowly) are counted, logged when they change and
reported at the end. With ``[osc] port`` set the colony speaks and listens on the network
(:mod:`creatures.runtime.network`). Learned state is saved every ``save_every`` seconds and on
exit (Ctrl-C or SIGTERM: every note off, state saved) and restored on the next start.
"""

from __future__ import annotations

import signal
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from audio.resilient import ResilientInput, ResilientOutput
from creatures.clock import Clock, SimulatedClock, WallClock
from creatures.events import EventLog
from creatures.runtime.bodies import BodyFrames
from creatures.runtime.network import Network
from creatures.runtime.schema import LoadedInstallation
from creatures.runtime.session import Session
from creatures.runtime.ticking import TickLoop, setup_kept
from midi.notes import NoteEvent, is_note_off
from midi.ports import MidoInputs, MidoOutputs, PortFactory, ResilientPort
from midi.sinks import MemorySink, PortSink

HELP = "list devices with `creatures devices`"
HEARD_LENGTH = 0.25
"""Seconds assumed for a live MIDI note heard at its note-on (its real length is unknown)."""

HOUSEKEEPING_EVERY = 1.0
"""Seconds between flushes of the events log and checks of the audio counters."""


@dataclass
class LiveSummary:
    seconds: float = 0.0
    ticks: int = 0
    late: int = 0
    notes_played: int = 0
    heard_between_ticks: int = 0  # notes heard (and answerable) at once, not at the next tick
    underruns: int = 0  # audio output callbacks that found no sound ready and played silence
    overruns: int = 0  # microphone blocks lost: the loop read too slowly, or the driver overflowed
    failed_saves: int = 0
    restored: list[str] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)
    sound: str = ""  # where the mix went: "live at 44100 Hz (resampled from 22050 Hz)" or "silent: why"
    network: dict[str, object] | None = None  # the OSC counters (Network.counts) when [osc] port is set


class LiveInputs:
    """Live note inputs feeding the colony's note bus: a MIDI port and the OSC network.

    ``ports`` is where the configured MIDI input is looked for (mido's backend unless given;
    tests and the benchmark pass :class:`midi.ports.MemoryPorts`).
    """

    def __init__(self, inst: LoadedInstallation, session: Session, clock: Clock, say: Callable[[str], None], *,
                 ports: PortFactory | None = None) -> None:
        settings = inst.settings
        self.world = session.world
        self.midi = None
        if settings.midi.input_port:
            self.midi = ResilientPort(settings.midi.input_port, ports or MidoInputs(), clock,
                                      report=lambda m: say(f"MIDI input: {m}; {HELP}"))
        self.network = None
        if settings.osc.port is not None:
            self.network = Network(settings.osc, session.world, clock, say,
                                   where=lambda key, message: inst.error(("osc", key), message))

    def poll(self, t: float) -> int:
        """Notes that arrived join the note bus at time ``t``; returns how many."""
        heard = 0
        if self.midi is not None:
            for msg in self.midi.pending():
                # A player expects creatures to react when a key goes down, not when it is
                # released: notes are heard at note-on, with a nominal length (the real one
                # is not known yet).
                if msg.type == "note_on" and not is_note_off(msg):
                    self.world.inject(NoteEvent(t, msg.note, msg.velocity, msg.channel, HEARD_LENGTH), via="midi")
                    heard += 1
        if self.network is not None:
            heard += self.network.poll(t)
        return heard

    def wait(self, timeout: float) -> None:
        """Sleep up to ``timeout`` s; an OSC packet wakes the loop at once (RtMidi has no handle
        to wait on, so MIDI is looked at when the sleep ends)."""
        if self.network is not None:
            self.network.wait(timeout)
        else:
            time.sleep(timeout)

    def close(self) -> None:
        if self.midi is not None:
            self.midi.close()
        if self.network is not None:
            self.network.close()


class _Counters:
    """Audio underruns and microphone overruns: read, and logged whenever they change."""

    def __init__(self, session: Session, output: ResilientOutput, microphone: ResilientInput | None) -> None:
        self.session = session
        self.output = output
        self.microphone = microphone
        self.last = (0, 0)

    def now(self) -> tuple[int, int]:
        underruns = self.output.underruns
        mic = self.microphone
        return underruns, (mic.overruns + mic.driver_overflows) if mic is not None else 0

    def log_change(self, *, always: bool = False) -> None:
        counts = self.now()
        if always or counts != self.last:
            self.last = counts
            self.session.world.emit("xruns", underruns=counts[0], overruns=counts[1])


def _save(session: Session, state_dir: Path, summary: LiveSummary, say: Callable[[str], None]) -> None:
    """Save state; a full or read-only disk is reported and the run goes on (the previous
    files stay intact, persist.atomic_write) rather than silencing a gallery."""
    try:
        session.save_state(state_dir)
    except OSError as exc:
        summary.failed_saves += 1
        say(f"could not save creature state ({exc}); the previous state is kept, will try again")


def run_live(
    inst: LoadedInstallation,
    *,
    duration: float | None = None,
    state: Path | None = None,
    log_path: Path | None = None,
    pictures: Path | None = None,
    say: Callable[[str], None] = print,
) -> LiveSummary:
    """Run ``inst`` live until Ctrl-C/SIGTERM (or ``duration`` wall seconds); with
    ``pictures`` the bodies are drawn into that directory (PNGs, and a video if the config asks) at the
    config's frame rate."""
    settings = inst.settings
    summary = LiveSummary()
    wall = WallClock()
    clock = SimulatedClock(wall.now())  # the creatures' time, moved by the loop (ticking.py)
    log = EventLog(log_path, keep_in_memory=0) if log_path else EventLog(keep_in_memory=1000)

    sink: PortSink | MemorySink = MemorySink()
    if settings.midi.output_port:
        port = ResilientPort(settings.midi.output_port, MidoOutputs(), wall,
                             report=lambda m: say(f"MIDI output: {m}; {HELP}"))
        sink = PortSink(port)
    transcribe = settings.audio.transcribe
    session = Session(inst, clock, log, sink,
                      transcribe=transcribe if transcribe is not None else not settings.midi.input_port)
    state_dir = state or inst.resolve(settings.state)
    if state_dir is not None:
        summary.restored = session.load_state(state_dir)
    inputs = LiveInputs(inst, session, clock, say)
    sr = settings.audio.sample_rate
    # Creatures synthesise at the config's rate; the device plays at its own (JACK will not
    # change it), so the mix is resampled on the way out. A device that is absent, or vanishes
    # mid-run, is reported, played to as silence, and reopened when it is back (audio/resilient.py).
    output = ResilientOutput(sr, 2, clock=wall, device=settings.audio.output_device,
                             blocksize=settings.audio.block, report=say)
    summary.sound = output.describe()
    microphone = None
    if settings.audio.input_device is not None:
        device = None if settings.audio.input_device == "default" else settings.audio.input_device
        microphone = ResilientInput(device, clock=wall, samplerate=sr, report=say)
    counters = _Counters(session, output, microphone)
    stopping = False

    def stop(*_: object) -> None:
        nonlocal stopping
        stopping = True

    previous = signal.signal(signal.SIGTERM, stop)
    session.world.emit("run", title=settings.title, mode="live", seed=settings.seed,
                       creatures=[c.name for c in session.creatures], restored=summary.restored)
    bodies = None
    if pictures is not None:
        pictures.mkdir(parents=True, exist_ok=True)
        bodies = BodyFrames(settings.output, pictures, wall, summary.messages)
        for message in summary.messages:
            say(message)
    say(f"{len(session.creatures)} creature(s) running; Ctrl-C or SIGTERM stops cleanly")
    loop = TickLoop(session, inputs, wall, clock, settings.tick)
    with setup_kept():
        start = wall.now()  # setting up took time; the run's ticks count from here
        next_save, next_housekeeping, frames_done = start + settings.save_every, start, int(round(start * sr))

        def tick(t: float) -> None:
            nonlocal next_save, next_housekeeping, frames_done
            frames = int(round(t * sr)) - frames_done
            frames_done += frames
            heard = microphone.read() if microphone is not None else None
            mix = session.step(t, frames, heard)
            output.write(mix)
            if inputs.network is not None:
                inputs.network.publish(t)
            if bodies is not None:
                bodies.draw(session.creatures)
            if state_dir is not None and t >= next_save:
                _save(session, state_dir, summary, say)
                next_save += settings.save_every
            if t >= next_housekeeping:  # a tail -f of the log shows the present; xruns are seen
                next_housekeeping = t + HOUSEKEEPING_EVERY
                counters.log_change()
                log.flush()

        try:
            loop.run(tick, until=lambda t: stopping or (duration is not None and t - start > duration))
        except KeyboardInterrupt:
            pass
        finally:
            signal.signal(signal.SIGTERM, previous)
            counters.log_change(always=True)
            summary.underruns, summary.overruns = counters.now()
            session.close()
            if state_dir is not None:
                _save(session, state_dir, summary, say)
            if microphone is not None:
                microphone.stop()
            output.close()
            if bodies is not None:
                bodies.close()
            inputs.close()
            if inputs.network is not None:
                summary.network = inputs.network.counts()
            log.close()
    summary.seconds = wall.now() - start
    summary.ticks = session.ticks
    summary.late = loop.late
    summary.heard_between_ticks = loop.heard_between
    summary.notes_played = session.world.notes_played
    return summary
