"""``creatures run``: an installation live, on the wall clock, with real devices.

The behaviour tick is fixed in elapsed seconds (machine-independent time); if the machine
falls behind by more than a second the run skips ahead rather than racing to catch up, and
counts it. Devices are optional and resilient: a named MIDI port that is absent is reported
once (with how to list devices) and reopened when it appears; a missing audio device falls
back to silence with the reason printed. Learned state is saved every ``save_every`` seconds
and on exit (Ctrl-C or SIGTERM: every note off, state saved) and restored on the next start.
"""

from __future__ import annotations

import signal
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import soxr

from audio.device import AudioDeviceUnavailable, device_rate
from audio.output import SilentOutput, open_output
from audio.sources import LiveInput
from creatures.clock import WallClock
from creatures.events import EventLog
from creatures.runtime.bodies import BodyFrames
from creatures.runtime.schema import LoadedInstallation
from creatures.runtime.session import Session
from midi.notes import NoteEvent, is_note_off
from midi.osc import OscListener, OscSender
from midi.ports import MidoInputs, MidoOutputs, ResilientPort
from midi.sinks import MemorySink, PortSink

HELP = "list devices with `creatures devices`"
HEARD_LENGTH = 0.25
"""Seconds assumed for a live MIDI note heard at its note-on (its real length is unknown)."""


@dataclass
class LiveSummary:
    seconds: float = 0.0
    ticks: int = 0
    late: int = 0
    notes_played: int = 0
    failed_saves: int = 0
    restored: list[str] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)
    sound: str = ""  # where the mix went: "live at 44100 Hz (resampled from 22050 Hz)" or "silent: why"


class _Inputs:
    """Live note inputs (a MIDI port, an OSC listener) feeding the colony's note bus."""

    def __init__(self, inst: LoadedInstallation, session: Session, clock: WallClock, say: Callable[[str], None]) -> None:
        settings = inst.settings
        self.session = session
        self.midi = None
        if settings.midi.input_port:
            self.midi = ResilientPort(settings.midi.input_port, MidoInputs(), clock,
                                      report=lambda m: say(f"MIDI input: {m}; {HELP}"))
        self.osc = None
        self.sender = None
        if settings.osc.port is not None:
            self.osc = OscListener(clock, host=settings.osc.host, port=settings.osc.port)
            self.sender = OscSender(settings.title.replace(" ", "_")[:64] or "colony")
            for peer in settings.osc.peers:
                host, _, port = peer.rpartition(":")
                self.sender.add_peer(peer, (host, int(port)))
            session.world.listeners.append(lambda who, note: self.sender.note(note))

    def poll(self, t: float) -> None:
        world = self.session.world
        if self.midi is not None:
            for msg in self.midi.pending():
                # A player expects creatures to react when a key goes down, not when it is
                # released: notes are heard at note-on, with a nominal length (the real one
                # is not known yet).
                if msg.type == "note_on" and not is_note_off(msg):
                    world.inject(NoteEvent(t, msg.note, msg.velocity, msg.channel, HEARD_LENGTH), via="midi")
        if self.osc is not None:
            for heard in self.osc.poll():
                if heard.note is not None:
                    world.inject(heard.note, heard.creature)

    def close(self) -> None:
        if self.midi is not None:
            self.midi.close()
        if self.osc is not None:
            self.osc.close()


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
    clock = WallClock()
    log = EventLog(log_path, keep_in_memory=0) if log_path else EventLog(keep_in_memory=1000)

    sink: PortSink | MemorySink = MemorySink()
    if settings.midi.output_port:
        port = ResilientPort(settings.midi.output_port, MidoOutputs(), clock,
                             report=lambda m: say(f"MIDI output: {m}; {HELP}"))
        sink = PortSink(port)
    transcribe = settings.audio.transcribe
    session = Session(inst, clock, log, sink,
                      transcribe=transcribe if transcribe is not None else not settings.midi.input_port)
    state_dir = state or inst.resolve(settings.state)
    if state_dir is not None:
        summary.restored = session.load_state(state_dir)
    inputs = _Inputs(inst, session, clock, say)
    sr, tick = settings.audio.sample_rate, settings.tick
    # Creatures synthesise at the config's rate; the device plays at its own (JACK will not
    # change it), so the mix is resampled on the way out when they differ.
    rate = device_rate(settings.audio.output_device, kind="output") or sr
    output = open_output(rate, 2, device=settings.audio.output_device, blocksize=settings.audio.block)
    to_device = soxr.ResampleStream(sr, rate, 2, dtype="float32") if rate != sr else None
    summary.sound = (f"silent: {output.reason}" if isinstance(output, SilentOutput) else
                     f"live at {rate} Hz" + (f" (resampled from {sr} Hz)" if to_device is not None else ""))
    if isinstance(output, SilentOutput):
        say(f"audio output {settings.audio.output_device or '(default)'} unavailable, running silent: "
            f"{output.reason}")
    microphone = None
    if settings.audio.input_device is not None:
        try:
            microphone = LiveInput(settings.audio.input_device, samplerate=sr)
            microphone.start()
        except AudioDeviceUnavailable as exc:
            say(f"audio input {settings.audio.input_device!r} unavailable, not listening: {exc}")
            microphone = None
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
        bodies = BodyFrames(settings.output, pictures, clock, summary.messages)
        for message in summary.messages:
            say(message)
    say(f"{len(session.creatures)} creature(s) running; Ctrl-C or SIGTERM stops cleanly")
    start = clock.now()  # setting up took time; the run's ticks count from here
    next_tick, next_save, frames_done = start + tick, start + settings.save_every, int(round(start * sr))
    try:
        while not stopping and (duration is None or next_tick - start <= duration):
            wait = next_tick - clock.now()
            if wait > 0:
                time.sleep(wait)
            elif wait < -1.0:  # far behind (a stall): skip ahead instead of racing
                summary.late += 1
                next_tick = clock.now()
            frames = int(round(next_tick * sr)) - frames_done
            frames_done += frames
            inputs.poll(next_tick)
            heard = microphone.read() if microphone is not None else None
            mix = session.step(next_tick, frames, heard)
            output.write(mix if to_device is None else to_device.resample_chunk(mix.astype(np.float32)))
            if bodies is not None:
                bodies.draw(session.creatures)
            if state_dir is not None and next_tick >= next_save:
                _save(session, state_dir, summary, say)
                next_save += settings.save_every
            next_tick += tick
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)
        session.close()
        if state_dir is not None:
            _save(session, state_dir, summary, say)
        if microphone is not None:
            microphone.stop()
        output.close()
        if bodies is not None:
            bodies.close()
        inputs.close()
        log.close()
    summary.seconds = clock.now() - start
    summary.ticks = session.ticks
    summary.notes_played = session.world.notes_played
    return summary
