"""``creatures offline``: an installation on the simulated clock, as fast as the CPU allows.

The same creatures as a live run, fed recorded (or generated) audio and MIDI, writing
``out.mid``, ``out.wav``, ``frames/`` (and ``out.mp4``), ``events.jsonl`` and ``report/``.
Time advances in behaviour ticks; audio is produced in blocks that exactly cover each tick
(frame counts come from elapsed time, so rounding never drifts), and frames fall due on their
own clock.

Every output is written into a hidden staging directory inside the output directory and
published only once the run has finished, all or none, replacing only what the previous run's
manifest lists (:mod:`creatures.runtime.outputs`): a run that fails — disk full, a crash,
Ctrl-C — leaves the previous run's outputs exactly as they were, a run that succeeds replaces
them all, so the files beside each other are always from one run, and nothing a run did not
write is ever replaced or removed. The directory is locked for the run (:mod:`creatures.lock`).
"""

from __future__ import annotations

import contextlib
import math
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from audio.output import WavOutput
from audio.sources import load_audio
from creatures import stop
from audio.transcribe import OFFLINE
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.bodies import BodyFrames
from creatures.runtime.body_stream import BodyStream
from creatures.runtime.input_sources import Rehearsal, Row, note_on, open_sources, unplayed
from creatures.runtime.inputs import phrase_notes, render_notes
from creatures.runtime.outputs import OutputDirectoryError, publishing
from creatures.runtime.schema import Installation, LoadedInstallation
from creatures.runtime.speech_input import spoken_poem
from creatures.runtime.trainer import Trainer
from creatures.runtime.stream_sinks import JsonLinesStreamSink
from creatures.runtime.session import Session
from creatures.runtime.shared_room import offline_note
from creatures.runtime.score import write_score
from creatures.view.poses import PoseLog
from midi.files import read_notes
from midi.notes import NoteEvent
from midi.sinks import MemorySink


@dataclass
class OfflineSummary:
    simulated: float
    wall: float
    notes_played: int
    files: dict[str, Path] = field(default_factory=dict)
    messages: list[str] = field(default_factory=list)
    events_lost: int = 0  # events the log could not write (a full disk): counted, never fatal
    sounds_made: int = 0  # sounds sung and words read (creatures that play no notes)

    @property
    def speed(self) -> float:
        """Simulated seconds per wall-clock second (× real time)."""
        return self.simulated / self.wall if self.wall > 0 else math.inf


def _planned(settings: Installation) -> set[str]:
    """The names a run of ``settings`` will publish (creatures' own files are checked when
    publishing): refused before running if anything else holds one."""
    output = settings.output
    wanted = {"events.jsonl": True, "state": True, "out.wav": output.wav, "out.mid": output.midi,
              "report": output.report, "frames": output.frames, "out.mp4": output.frames and output.video,
              "stream.jsonl": settings.stream.file}
    return {name for name, on in wanted.items() if on}


def _inputs(inst: LoadedInstallation, audio: Path | None, midi: Path | None, duration: float,
            rng: np.random.Generator, say: Callable[[str], None]) -> tuple[list[NoteEvent], np.ndarray | None]:
    """Notes and mono audio to feed: the given files, the config's files, or generated. A MIDI
    file the run will hear nothing of (no notes, or all past ``duration``) is said, not run
    through in silence as if the creatures had ignored it."""
    settings = inst.settings
    sr = settings.audio.sample_rate
    audio = audio or inst.resolve(settings.input.audio, ("input", "audio"))
    midi = midi or inst.resolve(settings.input.midi, ("input", "midi"))
    notes = read_notes(midi) if midi is not None else []
    samples = load_audio(audio, samplerate=sr, seconds=duration, say=say) if audio is not None else None  # only what is heard
    if midi is None and audio is None and settings.input.generate == "phrase":
        notes = phrase_notes(rng=rng)
        samples = render_notes(notes, sr, duration)
    elif midi is None and audio is None and settings.input.generate == "speech":
        samples = spoken_poem(duration, sr, rng)
    heard = [n for n in notes if n.time < duration]
    if midi is not None and not heard:
        say(f"{midi}: holds no notes; the creatures hear nothing from it" if not notes else
            f"{midi}: none of its {len(notes)} notes falls within the run's {duration:g} s (the first at "
            f"{min(n.time for n in notes):,.1f} s); give --duration to hear them")
    return heard, samples


def _refuse_replacing_inputs(inst: LoadedInstallation, out: Path, *, audio: Path | None, midi: Path | None) -> None:
    """Raise :class:`OutputDirectoryError` (before running) when an input file is one of the
    outputs this run publishes in ``out``, or lies in one: what the creatures played, fed back
    to them with the same ``--out`` (``--midi DIR/out.mid``), was read, then replaced by this
    run's own, and the take the artist fed was lost."""
    settings = inst.settings
    given = (("--audio", audio) if audio is not None else
             ("input.audio", inst.resolve(settings.input.audio, ("input", "audio"))),
             ("--midi", midi) if midi is not None else
             ("input.midi", inst.resolve(settings.input.midi, ("input", "midi"))))
    for what, path in given:
        if path is None:
            continue
        where = path.resolve()
        for name in sorted(_planned(settings)):
            own = (out / name).resolve()
            if where == own or own in where.parents:
                raise OutputDirectoryError(f"{what} {path} is this run's own {name} in {out}, which the run would "
                                           "replace: copy it out of there first, or give another --out")


def run_offline(
    inst: LoadedInstallation,
    out: Path,
    *,
    audio: Path | None = None,
    midi: Path | None = None,
    duration: float | None = None,
    progress: bool = False,
) -> OfflineSummary:
    """Run ``inst`` on the simulated clock for ``duration`` seconds, writing into ``out``.

    Raises :class:`OutputDirectoryError` (before running) when ``out`` cannot be written or
    holds something no run wrote where this one would publish, :class:`FolderLockedError`
    when another run uses it; any failure during the run leaves the previous outputs in
    ``out`` untouched.
    """
    settings = inst.settings
    duration = float(duration if duration is not None else settings.duration)
    _refuse_replacing_inputs(inst, out, audio=audio, midi=midi)  # before anything is held or made
    facts: dict[str, object] = {}
    with publishing(out, None, planned=_planned(settings), facts=facts) as staged:
        summary = _run(inst, staged, audio=audio, midi=midi, duration=duration, progress=progress)
        facts["events_lost"] = summary.events_lost
    summary.files = {name: out / path.relative_to(staged) for name, path in summary.files.items()}
    return summary


def _run(inst: LoadedInstallation, out: Path, *, audio: Path | None, midi: Path | None, duration: float,
         progress: bool) -> OfflineSummary:
    """The run itself, writing every output into ``out`` (the staging directory)."""
    settings = inst.settings
    wall0 = time.perf_counter()
    clock = SimulatedClock()
    sink = MemorySink()
    messages: list[str] = []
    log = EventLog(out / "events.jsonl", report=messages.append)
    session = Session(inst, clock, log, sink, say=messages.append)
    if (note := offline_note(inst)) is not None:
        messages.append(note)
    if settings.state is not None:  # an offline run is a reproducible take: it starts from nothing
        messages.append(f"state = {settings.state!r} is for live runs: offline, the creatures start fresh "
                        "and what they learn is saved into the output's state/ folder")
    session.world.recording = settings.output.midi  # out.mid's input track and heard tempo
    session.world.writes_outputs = True  # each creature's finish(out) below
    sources = open_sources(inst, session.inputs, clock, messages.append, live=False)  # rehearsal files
    for i, spec in enumerate(settings.input.map):
        if spec.file is not None and (cut := unplayed(spec.file, inst.rehearsals[i], duration)) is not None:
            messages.append(cut)
    session.begin(title=settings.title, mode="offline", duration=duration, seed=settings.seed, config=str(inst.path))
    poses = PoseLog(settings.view.log_fps, session.world, messages.append) if settings.view.log_fps else None
    notes, samples = _inputs(inst, audio, midi, duration, session.input_rng, messages.append)
    trainer = Trainer.of(inst, session)  # says cues into what is heard and clicks through the maps
    if trainer is not None:
        sources.append(trainer)
    mapped = [note_on(n) for n in notes]
    mapped = [m if any(r.matches_midi("note", m) for r in session.inputs.midi_routes) else None for m in mapped]
    if any(mapped):  # a recorded MIDI take goes through the [[input]] maps as a live one would (a click pad)
        sources.append(Rehearsal([Row(n.time, "midi", tuple(m.bytes())) for n, m in zip(notes, mapped) if m],
                                 0.0, session.inputs))
    for note, message in zip(notes, mapped):
        if message is None:  # heard, with its length as the file has it
            session.world.inject(note)
    transcribe = settings.audio.transcribe
    session.transcribe = (samples is not None or trainer is not None) and (transcribe if transcribe is not None
                                                                           else not notes)
    session.transcribe_look = OFFLINE  # nobody waits offline: the further look hears swells and chords better

    sr, tick = settings.audio.sample_rate, settings.tick
    wav = WavOutput(out / "out.wav", sr, session.channels) if settings.output.wav else None
    bodies = BodyFrames(settings.output, out, clock, messages) if settings.output.frames else None
    stream = None
    if settings.stream.file:  # every frame time taken, in place: time waits for the file offline
        stream = BodyStream(session.world, settings.stream.rate, threaded=False)
        stream.subscribe(JsonLinesStreamSink(out / "stream.jsonl"))
        stream.advance(0.0)  # frame 0: the bodies before the first tick
    steps = int(math.ceil(duration / tick - 1e-9))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=steps, unit="tick", desc=settings.title, leave=False, disable=None)
    try:
        for step in range(1, steps + 1):
            stop.check()  # a Ctrl-C or SIGTERM a finaliser swallowed (creatures/stop.py)
            t0, t = (step - 1) * tick, min(step * tick, duration)
            clock.advance_to(t)
            for source in sources:
                source.poll(t)
            a, b = int(round(t0 * sr)), int(round(t * sr))
            recorded = None if samples is None or a >= len(samples) else samples[a:min(b, len(samples))]
            if trainer is not None:
                recorded = trainer.heard(recorded, a, b)
            if stream is not None:  # frames between two ticks show the body the earlier one left
                stream.advance(t, before=True)
            mix = session.step(t, b - a, recorded, audio=wav is not None)
            if stream is not None:
                stream.advance(t)
            if trainer is not None:
                trainer.watch(t)
            if wav is not None:
                wav.write(mix)
            if bodies is not None:
                bodies.draw(session.creatures)
            if poses is not None:
                poses.write()
            if bar is not None:
                bar.update(1)
    except BaseException:
        if wav is not None:
            wav.abandon()
        raise
    finally:
        with contextlib.ExitStack() as closing:  # each is closed even when another fails (disk full)
            closing.callback(log.close)
            if bodies is not None:
                closing.callback(bodies.close)
            if stream is not None:
                closing.callback(stream.close)
            if bar is not None:
                closing.callback(bar.close)
            closing.callback(session.close)  # first: it logs the end and silences every note

    if trainer is not None:
        messages.append(trainer.said())
    files = {"events": out / "events.jsonl"}
    if wav is not None:
        wav.close()
        files["wav"] = out / "out.wav"
        if (clipped := session.clipping()) is not None:
            messages.append(f"out.wav: {clipped}")
    if settings.output.midi:
        write_score(out / "out.mid", session.world, sink.messages)
        files["midi"] = out / "out.mid"
    for creature in session.creatures:
        files.update(creature.finish(out))
    session.save_state(out / "state")  # what the creatures learned: `creatures inspect DIR` shows it
    files["state"] = out / "state"
    if stream is not None:
        files["stream"] = out / "stream.jsonl"
    if bodies is not None and bodies.renderer is not None and not bodies.painted:
        messages.append("no frames: no creature of this installation has a body to draw (`body = true` or a "
                        "[creature.body] gives one)")
        shutil.rmtree(out / "frames", ignore_errors=True)  # not published empty
    elif bodies is not None and bodies.renderer is not None:
        files["frames"] = out / "frames"
        if bodies.writer.video is not None:  # asked for, and an encoder found
            files["video"] = bodies.writer.video
    if log.loss:
        messages.append(log.loss)
    summary = OfflineSummary(duration, time.perf_counter() - wall0, session.world.notes_played, files, messages,
                             events_lost=log.lost, sounds_made=session.world.sounds_made)
    if settings.output.report:
        from creatures.runtime.report import write_report

        files["report"] = write_report(out / "events.jsonl", out / "report", title=settings.title)
    return summary
