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
exit (Ctrl-C, SIGTERM or SIGHUP: every note off, state saved) and restored on the next start. The
loudspeaker keeps a lead of spare sound that follows the device's clock (:mod:`audio.lead`),
and with ``--out`` the run's ``out.mid`` is published when it stops
(:mod:`creatures.runtime.live_score`).

Nothing that can block runs on the creature's thread: looking for ports and devices, checking
they are still there, reopening them and flushing the events log are jobs of a
:class:`~creatures.supervisor.Supervisor` thread (issue 14: a port listing of ~2.5 s once a
second had cost four ticks in five). What the loop still cannot keep is counted: ticks that
began more than :data:`~creatures.runtime.ticking.LATE_TICK` late and note-ons that reached
the MIDI port more than :data:`~midi.sinks.LATE_NOTE` late, logged each second (``timing``)
and in the summary. With ``[audio] output = false`` (the sound is an external synth's) no
audio device is opened at all.
"""

from __future__ import annotations

import signal
import threading
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable

import mido
import numpy as np

from audio import string_bank
from audio.resilient import ResilientInput, ResilientOutput, Watched
from creatures import lock, stop as stops
from creatures.authored.migrate import keep_originals
from creatures.clock import Clock, SimulatedClock, WallClock
from creatures.events import EventLog
from creatures.paths import directory, regular_file, writable_directory
from creatures.persist import StateFileError
from creatures.runtime.bodies import FramesBeside
from creatures.runtime.input_sources import Rehearsal, SerialSource, open_sources
from creatures.runtime.live_score import KEPT, LiveScore, RecordingSink
from creatures.runtime.network import Network, open_listener
from creatures.runtime.shared_room import check_share_port, open_shared_room
from creatures.runtime.outlets import Outlets, check_apart, check_ports
from creatures.runtime.schema import LoadedInstallation
from creatures.runtime.microphone_notes import MicrophoneNotes
from creatures.runtime.session import Session, write_snapshot
from creatures.runtime.opening import OpeningHours, Schedule
from creatures.runtime.trainer_spec import LIVE as TRAINER_LIVE
from creatures.runtime.sd_notify import Notifier
from creatures.runtime.snapshots import Snapshotter, refuse_to_change
from creatures.runtime import kernels
from creatures.runtime.ticking import TickLoop, TickTiming, gil_handover, realtime, setup_kept
from creatures.supervisor import Supervisor
from creatures.view.poses import PoseLog
from midi.gate import MidiGate
from midi.notes import NoteEvent
from midi.ports import MidoInputs, MidoOutputs, PortFactory, ResilientPort
from midi.sinks import MemorySink, PortSink

HELP = "list devices with `creatures devices`"

REHEARSAL = 1.0
"""Simulated seconds a throwaway copy of the colony plays before the show (:func:`rehearse`)."""

AUDIO_LEAD = 0.03
"""Seconds of spare sound kept ahead of the loudspeaker's next callback (audio/lead.py): a
tick's mix written up to this late still plays whole. The sound is heard about this much, a
device block and the resampler's delay (11 ms at 22050 → 44100 Hz) after its tick."""

AUDIO_BUFFER = 1.0
"""Seconds the loudspeaker's ring holds: room for a device stall (JACK's dummy server, loaded,
once called back not for 423 ms) to be left out as a skip (audio/lead.py), not lost block by
block as the ring overflows. The latency is the lead's, not this."""

HOUSEKEEPING_EVERY = 1.0
"""Seconds between flushes of the events log, checks of the audio counters and timing records."""


def logged(log: EventLog, clock: Clock, say: Callable[[str], None]) -> Callable[[str], None]:
    """A device's report (missing, lost, back, wedged) said with ``say`` and kept in the events
    log as a ``device`` event, so a weekend's log shows when the synth went and came back. It
    comes from the supervisor's thread; the log takes an emit from any thread (a lock), and the
    creatures' clock is read, not moved."""
    def report(message: str) -> None:
        say(message)
        log.emit(clock.now(), "device", message=message)
    return report


def _sound_at_end(output: ResilientOutput, began: str) -> str:
    """Where the sound went at the end of the run (before the loudspeaker is closed): what the
    summary said when the run began, unless the device was lost since, or came back."""
    if output.connected:
        return f"{output.describe()} once it came back" if output.reopened else began
    return f"lost mid-run ({output.wedged or output.reason})" if output.faults else began


@dataclass
class LiveSummary:
    seconds: float = 0.0
    ticks: int = 0
    late: int = 0  # ticks that began more than ticking.LATE_TICK after their grid time
    skipped: int = 0  # times the loop fell a second behind and skipped ahead
    worst_lateness: float = 0.0  # seconds, the latest a tick began
    lateness_p99: float = 0.0  # seconds
    notes_played: int = 0
    sounds_made: int = 0  # sounds sung and words read (creatures that play no notes)
    late_notes: int = 0  # note-ons that reached the MIDI port more than sinks.LATE_NOTE late
    midi_dropped: int | None = None  # MIDI messages that found no output port (None: no port configured)
    frames_dropped: int = 0  # frames the drawing process was too busy to take
    frames_skipped: int = 0  # frames of clock gaps (a suspended machine) never drawn (FrameClock.skipped)
    view_dropped: int = 0  # live view snapshots its thread was too slow to take
    heard_between_ticks: int = 0  # notes heard (and answerable) at once, not at the next tick
    underruns: int = 0  # audio output callbacks that found no sound ready and played silence
    audio_gaps: int = 0  # silences the output put in when its spare ran out (each start, any stall)
    audio_skips: int = 0  # times the output left sound out: its spare was far too large (a device stall)
    overruns: int = 0  # microphone blocks lost: the loop read too slowly, or the driver overflowed
    failed_saves: int = 0
    saved_at: float | None = None  # seconds into the run of the last save that succeeded
    unsaved: str | None = None  # the final save failed: what was not kept, in words
    afresh: str | None = None  # the run stopped to be started afresh (keeper.AFRESH): why, in words
    events_lost: int = 0  # events the log could not write (a full disk): counted, the run went on
    log_loss: str | None = None  # the same in words, naming the log and the last failure
    restored: list[str] = field(default_factory=list)
    inputs: dict[str, int] = field(default_factory=dict)  # outside messages mapped / unmapped / malformed
    messages: list[str] = field(default_factory=list)
    sound: str = ""  # where the mix went: "live at 44100 Hz (resampled from 22050 Hz)" or "silent: why"
    network: dict[str, object] | None = None  # the OSC counters (Network.counts) when [osc] port is set
    room_share: dict[str, object] | None = None  # the shared room's counters (RoomShare.counts) with [room.share]
    outlets: dict[str, object] = field(default_factory=dict)  # body stream and console counters (Outlets.counts)


class LiveInputs:
    """Live inputs feeding the colony: a MIDI port, the OSC network, serial devices and
    rehearsal files, every message through the session's input map (:mod:`creatures.runtime.input_map`),
    and the notes in the microphone (:attr:`microphone`, set when the run transcribes one).

    ``ports`` is where the configured MIDI input is looked for (mido's backend unless given;
    tests and the benchmark pass :class:`midi.ports.MemoryPorts`).
    """

    def __init__(self, inst: LoadedInstallation, session: Session, clock: Clock, say: Callable[[str], None], *,
                 ports: PortFactory | None = None, supervisor: Supervisor | None = None,
                 epoch: float | None = None) -> None:
        """``supervisor``: where the MIDI port's presence checks run (else on the caller's
        thread); ``epoch``: Unix time of clock time 0, to time-tag the notes sent over OSC."""
        settings = inst.settings
        self.router = session.inputs
        self.midi = None
        self.gate = MidiGate(settings.midi.max_rate)  # a flood from the port is cut, as OSC's is (midi/gate.py)
        if settings.midi.input_port:
            self.midi = ResilientPort(settings.midi.input_port, ports or MidoInputs(), clock,
                                      report=logged(session.world.log, clock, lambda m: say(f"MIDI input: {m}; {HELP}")),
                                      supervisor=supervisor)
        self.network = None
        if settings.osc.port is not None:
            self.network = Network(settings.osc, session.world, clock, say, elsewhere=self.router, epoch=epoch,
                                   where=lambda key, message: inst.error(("osc", key), message))
        # a serial device's going and coming back is kept in the events log as the MIDI port's is
        self.sources = open_sources(inst, self.router, clock, logged(session.world.log, clock, say), live=True)
        self.microphone: MicrophoneNotes | None = None  # notes in the microphone, heard between ticks too
        reached = "only the config's serial devices and rehearsal files" if self.sources else "nothing"
        for routes, source, key in ((self.router.osc_routes, self.network, "[osc] port"),
                                    (self.router.midi_routes, self.midi, "[midi] input_port")):
            if routes and source is None:
                say(f"[[input]] maps {'OSC' if key[1] == 'o' else 'MIDI'} messages but {key} is not set: "
                    f"{reached} will reach them")

    def poll(self, t: float) -> int:
        """What arrived is heard at time ``t``; returns how many notes joined the note bus."""
        heard = self.microphone.poll(t) if self.microphone is not None else 0
        if self.midi is not None:
            heard += self._midi(self.midi.pending(), t)
        if self.network is not None:
            heard += self.network.poll(t)
        for source in self.sources:
            heard += source.poll(t)
        return heard

    def _midi(self, messages: list[mido.Message], t: float) -> int:
        """The port's messages within ``[midi] max_rate`` (:mod:`midi.gate`) through the input
        map; the rest counted throttled, all at once (a flood's drops cost the thread little)."""
        heard = dropped = 0
        last = ""  # the type of the last message dropped
        for msg in messages:
            if self.gate.admit(msg, t):
                heard += self.router.midi(msg, t)
            else:
                dropped, last = dropped + 1, msg.type
        if dropped:
            self.router.miss("throttled", "midi", last, t, f"over [midi] max_rate of {self.gate.max_rate:g} "
                                                               "messages a second", dropped)
        return heard

    def tally(self) -> None:
        """Count, with the input map's counters, the OSC packets the listener refused (not OSC,
        too large, or not fitting ``/creature/…``), and what the MIDI input lost before a message
        was whole (bytes of no message; polls that found its queue full, where messages may have
        been lost): nothing that arrived goes uncounted."""
        if self.network is not None:
            ear = self.network.listener
            self.router.counts["refused osc"] = ear.malformed + ear.oversize
        if self.midi is not None:
            for key, n in (("refused midi bytes", self.midi.malformed_bytes), ("full midi queue", self.midi.full_queues)):
                if n:
                    self.router.counts[key] = n

    def unreached(self, t: float, say: Callable[[str], None]) -> None:
        """Say, and log (``unplayed``), the rows of each rehearsal file the run, stopping at
        ``t``, never reached (:meth:`~creatures.runtime.input_sources.Rehearsal.unreached`)."""
        for source in self.sources:
            if isinstance(source, Rehearsal) and (said := source.unreached(t)) is not None:
                say(said)
                self.router.world.emit("unplayed", file=source.file, rows=len(source.rows) - source.next,
                                       of=len(source.rows), said=said)

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
        for source in self.sources:
            if isinstance(source, SerialSource):
                source.close()


class _Counters:
    """Audio underruns, the output's gaps and skips, and microphone overruns: read, and logged
    whenever they change. The mix clipping is said the first time, while the run plays: an
    installation too loud for its speakers was said to be so only when it stopped, weeks on."""

    def __init__(self, session: Session, output: ResilientOutput | None, microphone: ResilientInput | None,
                 say: Callable[[str], None]) -> None:
        self.session = session
        self.output = output
        self.microphone = microphone
        self.say = say
        self.last = (0, 0, 0, 0)
        self.clipped_said = False

    def now(self) -> tuple[int, int, int, int]:
        """Underruns, overruns, and the output's gaps and skips (audio/lead.py)."""
        out, mic = self.output, self.microphone
        underruns, gaps, skips = (out.underruns, out.gaps, out.skips) if out is not None else (0, 0, 0)
        return underruns, (mic.overruns + mic.driver_overflows) if mic is not None else 0, gaps, skips

    def log_change(self, *, always: bool = False) -> None:
        counts = self.now()
        if always or counts != self.last:
            self.last = counts
            self.session.world.emit("xruns", underruns=counts[0], overruns=counts[1], gaps=counts[2], skips=counts[3])
        if not always and not self.clipped_said and (clipped := self.session.clipping()) is not None:
            self.clipped_said = True  # (at the end, the total alone is said: session.clipping)
            self.say(f"{clipped} (counted on; the total is said when the run stops)")


class _Timing:
    """Late ticks and late notes, logged once a :data:`HOUSEKEEPING_EVERY` (``timing``) when
    any came since the last record, and at the end."""

    def __init__(self, session: Session, timing: TickTiming, sink: PortSink | MemorySink) -> None:
        self.session, self.timing, self.sink = session, timing, sink
        self.last = (0, 0)

    def log_change(self, *, always: bool = False) -> None:
        counts = (self.timing.late, getattr(self.sink, "late", 0))
        if always or counts != self.last:
            self.last = counts
            self.session.world.emit("timing", ticks=self.timing.ticks, late_ticks=counts[0],
                                    worst_ms=round(self.timing.worst * 1e3, 3), late_notes=counts[1])


def rehearse(inst: LoadedInstallation) -> None:
    """A throwaway copy of the colony plays :data:`REHEARSAL` simulated seconds, hearing a few
    notes, before the show, so what loads at first use is loaded before the first real tick:
    numba's cached kernels load when first called (measured: exchange's first move took
    100 ms, making the live run's first five ticks late). The real creatures are untouched.
    Then every kernel takes what its cache holds (:mod:`creatures.runtime.kernels`): the
    paths one second does not take."""
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(keep_in_memory=0), MemorySink())
    for i, pitch in enumerate((60, 64, 67, 72)):
        session.world.inject(NoteEvent(0.1 + 0.15 * i, pitch, 90, 0, 0.2))
    tick, sr = inst.settings.tick, inst.settings.audio.sample_rate
    for step in range(1, int(REHEARSAL / tick) + 1):
        clock.advance_to(step * tick)
        session.step(clock.now(), int(round(tick * sr)), None)
    session.close()
    string_bank.prepare(sr)  # a band-limited note's kernels: a second of the colony may play none
    kernels.warm(kernels.project_modules())


def _save(session: Session, state_dir: Path, summary: LiveSummary, say: Callable[[str], None], at: float, *,
          final: bool = False) -> None:
    """Save state; a full or read-only disk is reported and the run goes on (the previous
    files stay intact, persist.atomic_write) rather than silencing a gallery. A failed final
    save is kept in ``summary.unsaved``: the command then exits non-zero saying what was lost."""
    _write_state(state_dir, session.snapshot(), summary, say, at, final=final)


def _write_state(state_dir: Path, snapshot: list[tuple[str, str]], summary: LiveSummary,
                 say: Callable[[str], None], at: float, *, final: bool = False) -> None:
    try:
        if lock.retake(state_dir):
            say(f"state folder {state_dir} was removed while the run used it: made again and locked again")
        write_snapshot(state_dir, snapshot)
    except (OSError, StateFileError) as exc:  # a full disk, another run took the folder while it was gone,
        # or a save a crash cut short whose list is damaged (creatures.state_set): said at each try
        summary.failed_saves += 1
        say(f"could not save creature state ({exc}); the previous state is kept"
            + ("" if final else ", will try again"))
        if not final:
            return
        since = "in this run" if summary.saved_at is None else f"after the save at {summary.saved_at:.1f} s"
        summary.unsaved = (f"the final save failed ({exc}): what the creatures learned {since} was not kept; "
                           f"{state_dir} holds the state before it")
    else:
        summary.saved_at = at


class _Saver:
    """Periodic saves: the colony's state is encoded on the creature's thread (one instant,
    ~0.1 ms), and written (an fsync per file: 25–40 ms measured) by a supervisor job, which
    reports a failed write as :func:`_save` does. The save on exit is :meth:`final`."""

    def __init__(self, supervisor: Supervisor, state_dir: Path, summary: LiveSummary,
                 say: Callable[[str], None], every: float, snapshots: Snapshotter | None = None) -> None:
        self.state_dir, self.summary, self.say, self.snapshots = state_dir, summary, say, snapshots
        self.pending: tuple[list[tuple[str, str]], float, datetime] | None = None
        self.job = supervisor.every(every, self._write, name="state save")
        self._writing = threading.Lock()
        self._closed = False

    def save(self, session: Session, at: float) -> None:
        """Encode the state now (``at`` seconds into the run) and have it written."""
        self.pending = (session.snapshot(), at, datetime.now(timezone.utc))
        self.job.wake()

    def final(self, session: Session, at: float) -> None:
        """The save on exit (:func:`_save`), after any periodic write still under way, and with
        none after it. The supervisor is given 5 s to end at exit; one stuck longer (a device
        check, a slow card's fsync) went on to write its older state over the final save."""
        with self._writing:
            self._closed = True
            self.pending = None
            _save(session, self.state_dir, self.summary, self.say, at, final=True)

    def _write(self) -> None:
        with self._writing:
            pending, self.pending = self.pending, None
            if pending is None or self._closed:
                return
            self._write_pending(*pending)

    def _write_pending(self, files: list[tuple[str, str]], at: float, when: datetime) -> None:
        _write_state(self.state_dir, files, self.summary, self.say, at)
        if self.snapshots is not None and self.summary.saved_at == at and self.snapshots.due(when):
            try:  # the dated copy of what was just saved; a full disk is said, the run goes on
                self.snapshots.take(files, when)
            except OSError as exc:
                self.say(f"could not take a snapshot of the creature state ({exc}); will try again")


def check_before_running(inst: LoadedInstallation, *, state: Path | None, log_path: Path | None,
                         pictures: Path | None, view: int | None = None) -> None:
    """What a live run is given, checked before anything runs or is made (``creatures run``
    calls it before it locks, and so makes, the state folder): the log a regular file or
    absent, the state a folder or absent and not a snapshot (history, never written), no two
    listeners on one port, the OSC, console, health, shared room and view ports free, and last
    the ``--frames`` folder made and written in. The first that fails raises, naming its option or config key."""
    if log_path is not None:
        regular_file(log_path, "--log")
    if state is not None:
        directory(state, "state folder")
        refuse_to_change(state, "run on")
    check_apart(inst, view)
    if inst.settings.osc.port is not None:  # bound and let go: a port in use is said now
        open_listener(inst.settings.osc, WallClock(), lambda key, message: inst.error(("osc", key), message)).close()
    check_ports(inst)
    check_share_port(inst)
    if view is not None:
        from creatures.view.server import port_problem

        problem = port_problem(view)
        if problem is not None:
            raise inst.error(("view", "port"), problem)
    if pictures is not None:
        writable_directory(pictures, "--frames")


def run_live(
    inst: LoadedInstallation,
    *,
    duration: float | None = None,
    state: Path | None = None,
    log_path: Path | None = None,
    pictures: Path | None = None,
    out: Path | None = None,
    view: int | None = None,
    say: Callable[[str], None] = print,
) -> LiveSummary:
    """Run ``inst`` live until Ctrl-C/SIGTERM (or ``duration`` wall seconds); with
    ``pictures`` the bodies are drawn into that directory (PNGs, and a video if the config asks) at the
    config's frame rate; with ``out`` the run's ``out.mid`` is published there when it stops
    (:mod:`creatures.runtime.live_score`); with ``view`` (a port) the live view is served there
    (:mod:`creatures.view`: its own thread; the tick only queues snapshots)."""
    settings = inst.settings
    summary = LiveSummary()
    state_dir = state or inst.resolve(settings.state, ("state",))
    check_before_running(inst, state=state_dir, log_path=log_path, pictures=pictures, view=view)
    score = None
    if out is not None and settings.output.midi:
        score = LiveScore(out)  # held for the run, and refused now if it cannot be written
    elif out is not None:
        say(f"[output] midi = false: no out.mid is written to {out}")
    if settings.input.trainer is not None:
        say(TRAINER_LIVE)
    rehearse(inst)
    wall = WallClock()
    clock = SimulatedClock(wall.now())  # the creatures' time, moved by the loop (ticking.py)
    epoch = time.time() - wall.now()
    # The supervisor flushes the log every HOUSEKEEPING_EVERY: the creature's thread never writes it.
    log = EventLog(regular_file(log_path, "--log"), keep_in_memory=0, report=say, flushed_elsewhere=True) \
        if log_path else EventLog(keep_in_memory=1000)
    supervisor = Supervisor()  # started with the loop; until then devices are looked at here

    sink: PortSink | MemorySink = MemorySink()
    port = None
    if settings.midi.output_port:
        port = ResilientPort(settings.midi.output_port, MidoOutputs(), wall,
                             report=logged(log, clock, lambda m: say(f"MIDI output: {m}; {HELP}")), supervisor=supervisor)
        sink = PortSink(port, wall)
    transcribe = settings.audio.transcribe
    recorded = RecordingSink(sink) if score is not None else None
    session = Session(inst, clock, log, recorded or sink,
                      transcribe=transcribe if transcribe is not None else not settings.midi.input_port, say=say)
    if score is not None:
        session.world.record(KEPT)  # out.mid's input track and heard tempo
    if state_dir is not None:
        summary.restored = session.load_state(state_dir)
        keep_originals(session.migrated, say)  # this run saves into the folder it read
    feed = server = None
    if view is not None:  # before any device opens: a port taken since the check fails with nothing to close
        from creatures.view.feed import Feed
        from creatures.view.server import LiveSource, ViewServer

        feed = Feed(settings.title, session.creatures, log, clock, settings.view.fps)
        server = ViewServer(LiveSource(feed, settings.view.fps), view).start()
    inputs = LiveInputs(inst, session, clock, say, supervisor=supervisor, epoch=epoch)
    shared = open_shared_room(inst, session, epoch, say)
    sr = settings.audio.sample_rate
    # Creatures synthesise at the config's rate; the device plays at its own (JACK will not
    # change it), so the mix is resampled on the way out. A device that is absent, or vanishes
    # mid-run, is reported, played to as silence, and reopened when it is back (audio/resilient.py).
    output = None
    summary.sound = "off ([audio] output = false)"
    if settings.audio.output:
        output = ResilientOutput(sr, session.channels, clock=wall, device=settings.audio.output_device,
                                 blocksize=settings.audio.block, report=logged(log, clock, say), supervisor=supervisor,
                                 lead=AUDIO_LEAD,
                                 buffer_seconds=AUDIO_BUFFER)
        summary.sound = output.describe()
    microphone = None
    if settings.audio.input_device is not None:
        device = None if settings.audio.input_device == "default" else settings.audio.input_device
        microphone = ResilientInput(device, clock=wall, samplerate=sr, report=logged(log, clock, say),
                                    supervisor=supervisor)
        if session.transcribe:
            inputs.microphone = MicrophoneNotes(microphone, session)
    counters = _Counters(session, output, microphone, say)
    if feed is not None:
        feed.hello["status"]["sound"] = summary.sound  # what the page's status line says of the loudspeaker
        say(f"view: open {server.url}")
    stopping = False

    def stop(signum: int, _: object) -> None:
        nonlocal stopping
        stopping = True
        stops.hung_up(signum)  # a closed terminal: stop as on SIGTERM, printing nowhere

    def wedged() -> bool:
        """A device that cannot come back in this process (audio/resilient.py) ends the run,
        saved, to be started afresh by its keeper (a new process opens the device when the
        server is back); the device watch has said why."""
        why = next((device.wedged for device in (output, microphone) if isinstance(device, Watched) and device.wedged),
                   "")
        if why and summary.afresh is None:
            summary.afresh = why
            session.world.emit("afresh", why=why)
        return bool(why)

    previous = {sig: signal.signal(sig, stop) for sig in (signal.SIGTERM, signal.SIGHUP)}
    session.begin(title=settings.title, mode="live", seed=settings.seed, restored=summary.restored,
                  config=str(inst.path), epoch=round(epoch, 6))  # Unix time of clock time 0
    # Poses into the events log as an offline run writes them, so `creatures view` and `creatures
    # render` replay a live run too (bounded by POSE_BUDGET): at log_fps the tick rounds each body's
    # joints into an event; the supervisor's thread writes the log, never the tick.
    poses = PoseLog(settings.view.log_fps, session.world, say) if log_path and settings.view.log_fps else None
    bodies = None
    if pictures is not None:
        bodies = FramesBeside(settings.output, pictures, wall, summary.messages)
        for message in summary.messages:
            say(message)
    say(f"{len(session.creatures)} creature(s) running; Ctrl-C or SIGTERM stops cleanly")  # SIGHUP too
    loop = TickLoop(session, inputs, wall, clock, settings.tick)
    timing = _Timing(session, loop.timing, sink)
    supervisor.every(HOUSEKEEPING_EVERY, log.flush, name="events log flush")  # a tail -f shows the present
    snap = settings.snapshots
    snapshots = Snapshotter(state_dir, every=snap.every, daily=snap.keep_daily, weekly=snap.keep_weekly) \
        if state_dir is not None and snap.every is not None else None
    saver = _Saver(supervisor, state_dir, summary, say, settings.save_every, snapshots) \
        if state_dir is not None else None

    held = {"console": False, "schedule": False}

    def holder(by: str) -> Callable[[bool], None]:
        """The console's pause, and the schedule's sleep: ticks skipped (silence plays), every
        note off; once neither holds it, the notes heard meanwhile are forgotten (the past,
        not a burst to answer)."""

        def pause(on: bool) -> None:
            was, held[by] = loop.paused, on
            loop.paused = any(held.values())
            if loop.paused and not was:
                session.scheduler.all_notes_off()
                session.world.emit("paused", by=by)
            elif was and not loop.paused:
                session.world.emit("resumed", by=by, forgotten=session.world.forget(loop.time.now()))

        return pause

    pause = holder("console")
    hours = settings.schedule
    schedule = None if hours.opens is None else Schedule(
        OpeningHours(hours.days, hours.opens, hours.closes, hours.timezone), holder("schedule"),
        lambda: datetime.now(timezone.utc))
    notifier = Notifier()
    beats = 0  # ticks of the loop, asleep or not: what the watchdog sees advance
    if notifier.interval is not None:
        supervisor.every(notifier.interval, notifier.pinger(lambda: beats), name="systemd watchdog")

    def save_now(t: float) -> str:  # the console's, so only once the loop runs: `start` is set
        saver.save(session, t - start)
        return str(state_dir)

    def status() -> dict[str, object]:
        underruns, overruns, gaps, skips = counters.now()
        return {"state": "paused" if loop.paused else "running", "title": settings.title, "ticks": session.ticks,
                "late_ticks": loop.timing.late, "skipped": loop.skipped, "underruns": underruns,
                "overruns": overruns, "audio_gaps": gaps, "audio_skips": skips, "notes_played": session.world.notes_played,
                "creatures": [c.name for c in session.creatures], **devices(), **outlets.counts()}

    def devices() -> dict[str, object]:
        """Whether the synth's port and the loudspeaker are there now: a watchdog reading only
        ``notes_played`` would not see that every note since the synth went away was dropped."""
        parts: dict[str, object] = {}
        if port is not None:
            parts["midi_output"] = {"connected": port.connected, "lost": port.faults, "dropped": port.dropped}
        if isinstance(output, Watched):  # a device kept across faults (audio/resilient.py)
            parts["audio_output"] = {"connected": output.connected, "lost": output.faults}
        return parts

    outlets = Outlets(inst, session, loop, supervisor, pause=pause, save=save_now if saver is not None else None,
                      status=status)
    supervisor.start()  # before the loop's thread turns real-time: the supervisor keeps ordinary scheduling
    with setup_kept() as loop.collect, realtime(settings.realtime, say), gil_handover():
        start = wall.now()  # setting up took time; the run's ticks count from here
        outlets.begin(start)
        next_save, next_housekeeping, frames_done = start + settings.save_every, start, int(round(start * sr))

        def tick(t: float) -> None:
            nonlocal next_save, next_housekeeping, frames_done, beats
            beats += 1
            frames = int(round(t * sr)) - frames_done
            frames_done += frames
            if inputs.microphone is not None:  # read at every look: its notes are heard already
                heard = inputs.microphone.take(t)
            else:
                heard = microphone.read() if microphone is not None else None
            mix = None if loop.paused else session.step(t, frames, heard, audio=output is not None,
                                                        transcribed=inputs.microphone is not None)
            if loop.paused and session.stage is not None:
                session.stage.keep_sharing(t)  # still in the shared room, standing
            if output is not None:
                output.write(mix if mix is not None else np.zeros((frames, 2), np.float32))
            if inputs.network is not None:
                inputs.network.publish(t)
            if bodies is not None:
                bodies.draw(session.creatures)
            if feed is not None:
                feed.offer()
            if poses is not None:
                poses.write()
            if state_dir is not None and t >= next_save:
                saver.save(session, t - start)
                next_save += settings.save_every
            if t >= next_housekeeping:  # xruns and late ticks are seen while running
                next_housekeeping = t + HOUSEKEEPING_EVERY
                counters.log_change()
                timing.log_change()
                outlets.publish()
                if schedule is not None:
                    schedule.poll()

        try:
            # The first tick builds what creatures build on first use (their first course, the
            # motor graph's log record: ~130 ms for exchange's three); the grid starts after it.
            clock.advance_to(max(start, clock.now()))
            inputs.poll(start)
            if schedule is not None:
                schedule.poll()  # closed at start: asleep from the first tick
            if session.stage is not None:  # the crowd stands through setting up, as a clock gap would have it
                session.stage.begin(start)
            tick(start)
            notifier.ready(f"{len(session.creatures)} creature(s) running")
            loop.run(tick, until=lambda t: stopping or stops.requested is not None  # a Ctrl-C a finaliser swallowed
                     or (duration is not None and t - start > duration) or wedged())
        except KeyboardInterrupt:
            pass
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            # A second stop (SIGTERM twice from a supervisor, a Ctrl-C after it) is said once
            # the run has stopped, not raised in the middle of its final save (creatures/stop.py).
            with stops.finishing() as again:
                notifier.stopping()
                supervisor.stop()  # before what it watches closes
                outlets.close()
                summary.outlets = outlets.counts()
                for what, counts in summary.outlets.items():  # "stream" and "console" events: what each did
                    session.world.emit(what, **counts)
                counters.log_change(always=True)
                timing.log_change(always=True)
                summary.underruns, summary.overruns, summary.audio_gaps, summary.audio_skips = counters.now()
                inputs.tally()
                inputs.unreached(clock.now(), say)
                if port is not None:  # what never reached the synth is said, not lost in silence
                    summary.midi_dropped = port.dropped
                    session.world.emit("midi output", port=settings.midi.output_port, dropped=port.dropped)
                session.close()
                if (clipped := session.clipping()) is not None:  # sounded only if a loudspeaker played it
                    say(clipped)
                if score is not None and recorded is not None:  # written beside the final save
                    score.finish(session.world, recorded, start, say)
                if saver is not None:
                    saver.final(session, wall.now() - start)
                if microphone is not None:
                    microphone.stop()
                if isinstance(output, Watched):  # said when the run began: where the sound went at the end
                    summary.sound = _sound_at_end(output, summary.sound)
                if output is not None:
                    output.close()
                if bodies is not None:
                    bodies.close()
                    summary.frames_dropped, summary.frames_skipped = bodies.dropped, bodies.clock.skipped
                if server is not None:
                    server.close()
                    feed.close()
                    summary.view_dropped = feed.dropped
                inputs.close()
                if inputs.network is not None:
                    summary.network = inputs.network.counts()
                if shared is not None:
                    summary.room_share = shared.counts()
                    session.world.emit("room share", **summary.room_share)
                    shared.close()
                log.close()
                if score is not None:
                    score.wait()
            for signum in again:
                say(f"{stops.named(signum)} while the run was ending: it ended after its final save, as it was")
    summary.seconds = wall.now() - start
    summary.ticks = session.ticks
    summary.late, summary.skipped = loop.timing.late, loop.skipped
    summary.worst_lateness, summary.lateness_p99 = loop.timing.worst, loop.timing.percentile(99)
    summary.late_notes = getattr(sink, "late", 0)
    summary.heard_between_ticks = loop.heard_between
    summary.notes_played, summary.sounds_made = session.world.notes_played, session.world.sounds_made
    summary.inputs = session.inputs.summary()
    summary.events_lost, summary.log_loss = log.lost, log.loss
    return summary
