"""What a live run and an offline run share: the creatures, their world, the mix, the tick.

A tick at clock time ``t`` delivers the notes that started, feeds the ears (recorded or live
input, plus the room when creatures hear each other through the air), lets every creature
perceive, decide and move, sends the notes that fell due, and renders exactly the audio
frames between the previous tick and this one (frame counts come from elapsed time, so
rounding never drifts). Only where time comes from and where the outputs go differ between
``creatures offline`` and ``creatures run``.
"""

from __future__ import annotations

import difflib
import itertools
import json
import math
import os
from pathlib import Path
from typing import Any, Callable

import numpy as np

from audio.mixer import Mixer
from audio.transcribe import Transcriber
from creatures.clock import Clock, clock_gap
from creatures.config import nearest
from creatures.events import EventLog
from creatures.authored.migrate import from_retired
from creatures.kinds import KINDS
from creatures.behaviour.unplaced import Unmatched
from creatures.persist import StateFileError, json_text, load_json
from creatures.state_set import files, settle, write_set
from creatures.runtime.cc_sources import Reader, parse, reader
from creatures.runtime.input_map import InputRouter
from creatures.runtime.pulse import HeardPulse
from creatures.runtime.schema import LoadedInstallation
from creatures.runtime.world import INPUT, World
from creatures.room.air import RoomAir
from creatures.room.stage import Stage
from midi.channel_setup import CcStream, channel_setup
from midi.scheduler import NoteScheduler
from midi.sinks import NoteSink

STATE_KIND = "creature-music creature state"
COLONY_KIND = "creature-music colony state"
COLONY_FILE = "colony.state.json"
"""What the colony learned together (the pulse it hears), saved beside the creatures' files;
the dots keep it from ever being a creature's file (names have none)."""


RESTORE_ERRORS = (KeyError, TypeError, ValueError, IndexError, AttributeError, ArithmeticError, RecursionError)
"""What taking back a damaged file can raise (ArithmeticError: e.g. a ratio with denominator
0; RecursionError: a tree nested deeper than any creature grows); each names the file."""


class Session:
    """The creatures of one installation on one clock, ticking together."""

    def __init__(self, inst: LoadedInstallation, clock: Clock, log: EventLog, sink: NoteSink, *,
                 transcribe: bool = False, say: Callable[[str], None] = lambda message: None) -> None:
        """``transcribe``: the input audio's pitched notes are heard as notes (audio-only runs);
        ``say`` reports to the person running it (e.g. the first unmapped input)."""
        settings = inst.settings
        self.say = say
        self.inst = inst
        self.migrated: list[tuple[Path, str]] = []
        """State files :meth:`load_state` took in from a retired kind, with that kind: a run
        that saves into their folder keeps them first (:func:`creatures.authored.migrate.keep_originals`)."""
        self.clock = clock
        self.log = log
        self.scheduler = NoteScheduler(sink, clock)
        self.world = World(clock, log, self.scheduler, HeardPulse(settings.pulse.prior, settings.pulse.readings))
        for note in inst.notes:  # what loading found that may be a mistake: said now, logged by begin()
            say(note)
        # The [[input]] maps; their sensors exist before the creatures, which may model them.
        self.inputs = InputRouter(inst.routes, self.world, say)
        seeds = np.random.SeedSequence(settings.seed).spawn(len(inst.specs) + 1)
        self.input_rng = np.random.default_rng(seeds[-1])
        for spec, seed in zip(inst.specs, seeds):
            self.world.add(KINDS[spec.kind](spec, self.world, np.random.default_rng(seed)))
        self.creatures = self.world.creatures
        self.sample_rate = settings.audio.sample_rate
        block = int(math.ceil(settings.tick * self.sample_rate)) + 1
        self.stage: Stage | None = None
        if settings.room is not None:
            self.stage = Stage(settings.room, self.creatures, np.random.default_rng(seeds[-1].spawn(1)[0]),
                               self.world.sensors)
            self.world.room = self.stage
        self.channels = 2 if self.stage is None else self.stage.channels
        """Output channels of the mix (out.wav, live): 2, or the room's ring of speakers."""
        self.mixer = Mixer(len(self.creatures), block_size=block, channels=self.channels)
        for i, creature in enumerate(self.creatures):
            self.mixer.set(i, gain=creature.spec.gain, pan=creature.spec.pan)
        self._voices = np.zeros((len(self.creatures), block))
        self._room = np.zeros(0)
        self.air = settings.audio.air
        self.room_air: RoomAir | None = None
        """Sound across the room (a ``[room]``): each listening ear hears the input and the
        voices by distance, late by distance/343 s, not the same mix as every other ear."""
        if self.stage is not None:
            room = settings.room
            self.room_air = RoomAir(self.stage.law, delay=room.hearing.delay, sample_rate=self.sample_rate,
                                    voices=len(self.creatures), diagonal=math.hypot(room.width, room.depth),
                                    longest_block=block)
        self.transcribe = transcribe
        self.transcribe_look = settings.audio.look  # live or quick (about 35 and 23 ms past a struck attack's hop; docs/hearing.md); offline looks further
        self._transcriber: Transcriber | None = None
        self.ticks = 0
        self._set_up: list[tuple[object, tuple]] = [(None, ()) for _ in self.creatures]  # (spec, setup sent)
        self._set_up_changed(self.clock.now())  # each channel in its creature's voice before its first note
        self._cc = self._cc_streams()

    def begin(self, **run: object) -> None:
        """The events log's first records: ``run`` (``run``'s fields and the creatures' names),
        then each ``config`` note loading found (kept with the run). A log begins with its run:
        the notes, logged while the session was made, came before it (void's dancers' hip note)."""
        self.world.emit("run", **run, creatures=[c.name for c in self.creatures])
        for note in self.inst.notes:
            self.world.emit("config", note=note)

    def step(self, t: float, frames: int, recorded: np.ndarray | None, *, audio: bool = True,
             transcribed: bool = False) -> np.ndarray | None:
        """One behaviour tick at clock time ``t`` covering ``frames`` audio frames.

        ``recorded`` is what the microphone (or file) gave for those frames; ``transcribed``:
        its notes were heard already, as it arrived (:mod:`creatures.runtime.microphone_notes`).
        Returns the stereo mix ``(frames, 2)`` (a view, valid until the next step), or None when
        ``audio`` is off and no creature hears the room.
        """
        if self.transcribe and recorded is not None and not transcribed:
            self.hear_notes(t, recorded)
        if self.stage is not None:
            for i, note in self.stage.tick(t, self._percept, self.world.emit):
                self.world.play(self.creatures[i], note)  # a note object it stepped onto
            gains = np.fromiter((creature.spec.gain for creature in self.creatures), float, len(self.creatures))
            self.mixer.place_all(gains[:, None] * self.stage.speaker_gains())  # spec.gain: the console may set it
        self.world.deliver(t)
        if self.room_air is not None:
            self._listen_in_room(t, recorded, frames, gains)
        else:
            heard = self._ears(recorded, frames)
            # hears_input = false: asked each tick, since the console or a zone may set it in a run
            deaf = recorded is not None and not all(creature.spec.hears_input for creature in self.creatures)
            room = self._ears(None, frames) if deaf else heard
            for creature in self.creatures:
                block = heard if creature.spec.hears_input else room
                if block is not None:
                    creature.listen(t, block, self.sample_rate)
        deciding = None if self.stage is None else self.stage.deciding(self.ticks, self.inst.settings.tick)
        # far creatures of a room with level of detail decide less often; a kind ticks each run
        # of its creatures together (an authored crowd shares its selection's arrays)
        for kind, run in itertools.groupby(self.creatures if deciding is None else [self.creatures[i] for i in deciding],
                                           key=type):
            kind.tick_many(list(run), t)
        self._set_up_changed(t)  # a console's or a zone's set of program, volume, pan …, this tick
        for read, stream in self._cc:
            msg = stream.due(t, read(t))
            if msg is not None:
                self.scheduler.send_at(t, msg)
        self.scheduler.pump()
        self.ticks += 1
        if not (audio or self.air):
            return None
        voices = self._voices[:, :frames]
        for i, creature in enumerate(self.creatures):
            creature.sound(voices[i], self.sample_rate)
            if self.stage is None and (pan := creature.pan()) != self.mixer.pans[i]:  # a skill's voice.pan
                self.mixer.set(i, pan=pan)
        if self.room_air is not None and self.air:
            self.room_air.hear_voices(voices)
        elif self.air:
            self._room = voices.T @ self.mixer.gains
        return self.mixer.mix(voices)

    def _percept(self, i: int, name: str) -> float:
        """Creature ``i``'s percept ``name`` now (a steer table's ``when``; the config loader
        checked the creature has it)."""
        return float(self.creatures[i].percept(name).evaluate(self.clock.now()))

    def _set_up_changed(self, t: float) -> None:
        """Send the channel setup (midi/channel_setup.py) of every creature whose spec changed
        what it says: its ``channel``, ``pan`` and own ``program``/``bank``/``volume``/
        ``bend_range`` (else ``[midi]``'s). A console ``set ada program 40`` or a zone's ``spec = { program = 40 }``
        was taken and the synth kept the old instrument: the setup was sent once, at the start.
        A spec is replaced whole when a key changes, so an unchanged one costs one identity test."""
        midi = self.inst.settings.midi
        for i, creature in enumerate(self.creatures):
            spec = creature.spec
            if spec is self._set_up[i][0]:
                continue
            chosen = {key: getattr(spec, key) if getattr(spec, key) is not None else getattr(midi, key)
                      for key in ("program", "bank", "volume", "bend_range")}
            said = (spec.channel, spec.pan, *chosen.values())
            if said != self._set_up[i][1]:
                for msg in channel_setup(spec.channel, pan=spec.pan, **chosen):
                    self.scheduler.send_at(t, msg)
            self._set_up[i] = (spec, said)

    def _cc_streams(self) -> list[tuple[Reader, CcStream]]:
        """``[[output.cc]]``: each stream's per-tick reading (a drive or a body feature, which
        the config loader checked against the creature's kind) and its scaling."""
        by_name = {c.name: c for c in self.creatures}
        streams = []
        for cc in self.inst.settings.output.cc:
            creature = by_name[parse(cc.source)[0]]
            streams.append((reader(creature, cc.source), CcStream(creature.spec.channel, cc.controller, *cc.range, cc.rate)))
        return streams

    def hear_notes(self, t: float, recorded: np.ndarray) -> int:
        """Notes of the input audio that ends at ``t`` join the note bus as they are recognised
        (dated on the clock across a clock gap: ``Transcriber.skip``); how many."""
        start = t - len(recorded) / self.sample_rate  # the block's first sample sounded this long before t
        if self._transcriber is None:
            self._transcriber = Transcriber(self.sample_rate, t0=start, look=self.transcribe_look)
        if jump := clock_gap(self._transcriber.fed_until, start):
            self._transcriber.skip(jump)
        notes = self._transcriber.feed(recorded)
        for note in notes:
            self.world.inject(note, via="audio")
        return len(notes)

    def _listen_in_room(self, t: float, recorded: np.ndarray | None, frames: int, gains: np.ndarray) -> None:
        """Each creature that listens hears its own block of the room's sound (RoomAir);
        ``gains``: each creature's own level this tick."""
        self.room_air.hear_input(recorded, frames)
        if recorded is None and not self.air:
            return  # nothing sounds in the room's air: no ear is fed, as without a room
        listeners = np.array([i for i, creature in enumerate(self.creatures) if creature.hears_audio], dtype=np.intp)
        hears_input = np.array([recorded is not None and self.creatures[i].spec.hears_input for i in listeners], float)
        blocks = self.room_air.ears(listeners, self.stage.v.pos, gains, self.stage.source_at(INPUT),
                                    hears_input, frames, voices=self.air)
        for i, block in zip(listeners.tolist(), blocks):
            self.creatures[i].listen(t, block, self.sample_rate)

    def _ears(self, recorded: np.ndarray | None, frames: int) -> np.ndarray | None:
        """The input, plus the room's sound (every voice of the previous tick) with air on."""
        if not self.air or not len(self._room):
            return recorded
        heard = np.zeros(frames, dtype=np.float32)
        if recorded is not None:
            heard[: len(recorded)] += recorded[:frames]
        n = min(len(self._room), frames)
        heard[:n] += self._room[:n]
        return heard

    def close(self) -> None:
        """Silence every sounding note and log what the input map counted and has not yet said,
        the input counters, the mix's clipping (if any) and the end of the run."""
        self.scheduler.all_notes_off()
        if restruck := self.scheduler.restruck:
            self.world.emit("restruck", notes=restruck)
            self.say(f"{restruck} {'note' if restruck == 1 else 'notes'} started on a key (channel and pitch) still "
                     "sounding: MIDI has one key per pitch and channel, so each re-struck it, ending the earlier note there (the key sounded on "
                     "to the later end, or to the new note's if the earlier was held; the events log keeps the "
                     "notes as played)")
        self.inputs.flush(self.clock.now())
        self.world.emit("inputs", **self.inputs.summary())
        if self.mixer.clipped:
            self.world.emit("clipped", samples=self.mixer.clipped, peak=round(self.mixer.peak, 3))
        self.world.emit("end", ticks=self.ticks, notes=self.world.notes_played)

    def clipping(self) -> str | None:
        """What the mix lost past full scale, said as the artist can act on it; None when nothing."""
        if not self.mixer.clipped:
            return None
        over = 20.0 * math.log10(self.mixer.peak)
        return (f"the mix clipped: {self.mixer.clipped} samples beyond full scale (peak {self.mixer.peak:.2f}, "
                f"{over:+.1f} dB): lower the creatures' gain or voice.gain")

    # -- state that lasts across restarts ---------------------------------------------------
    def save_state(self, directory: Path) -> None:
        """Each creature's learned state, one atomic JSON file per creature, then the colony's
        (:data:`COLONY_FILE`): a pulse learnt over weeks of listening is kept like the rest."""
        write_snapshot(directory, self.snapshot())

    def snapshot(self) -> list[tuple[str, str]]:
        """What :meth:`save_state` writes, as ``(file name, JSON text)``, encoded now (a
        consistent instant of the colony); :func:`write_snapshot` does the slow part."""
        files = [(f"{creature.name}.json", json_text({"kind": creature.spec.kind, "state": creature.state(),
                                                      **self._motion(creature), **self._place(creature)},
                                                     kind=STATE_KIND))
                 for creature in self.creatures]
        return files + [(COLONY_FILE, json_text(self.world.pulse.to_dict(), kind=COLONY_KIND))]

    def _motion(self, creature: object) -> dict[str, Any]:
        """The path its body took this run, beside its learned state (not learned: never
        restored; ``creatures export-motion STATE_DIR`` reads it, with the config that ran)."""
        trail = getattr(creature, "trail", None)
        if trail is None:
            return {}
        return {"motion": {**trail.path_state(), "config": str(self.inst.path)}}

    def _place(self, creature: Any) -> dict[str, Any]:
        """Where it stands in the room (none without one): restored, so a restarted process's
        creatures walk on from where they were (``Stage.placement``)."""
        return {} if self.stage is None else {"place": self.stage.placement(creature.name)}

    def load_state(self, directory: Path) -> list[str]:
        """Restore creatures from ``directory`` where a file exists; returns who was restored.

        A file saved by a retired class-based kind is taken into the authored creature that
        replaced it (:mod:`creatures.authored.migrate`) and listed in :attr:`migrated`; a file
        of another kind, or one whose content the kind cannot take back, raises
        :class:`StateFileError` naming it (never a silent mix).
        """
        try:
            settle(directory)
        except OSError as exc:  # a read-only folder, which lock.hold lets a run start on: read it as it lies
            self.say(f"{directory}: could not finish the save a crash interrupted ({exc.strerror or exc}); its "
                     "files are read where they lie")
        saved = files(directory)
        restored = []
        for creature in self.creatures:
            path = saved.get(f"{creature.name}.json")
            if path is None:
                continue
            data = load_json(path, kind=STATE_KIND)
            if path.is_symlink():  # a state set is renamed into place whole: a save puts a file where the link is
                self.say(f"{path}: read through its link to {os.readlink(path)}; a save writes {path.name} here as a "
                         "file of the state folder's set and leaves that file as it is")
            state = data.get("state", {})
            if not isinstance(state, dict):
                raise StateFileError(f"{path}: 'state' must be a table, found {type(state).__name__}")
            migrated = data.get("kind") != creature.spec.kind
            if migrated:  # a retired class's state, or refused naming both
                state = from_retired(path, data.get("kind"), state, creature)
            try:
                creature.restore(state)
                if self.stage is not None and "place" in data:
                    self.stage.put(creature.name, data["place"])
                # A state that loads is one that saves: what was taken back must write out again.
                json.dumps(creature.state(), allow_nan=False)
            except RESTORE_ERRORS as exc:
                # A kind's restore reads plain dicts; whatever a damaged file makes it trip
                # on is reported as that file's fault (creatures.behaviour.creature does the same).
                # Each kind checks bounds with creatures.bounds, whose messages name the key.
                raise StateFileError(f"{path}: malformed {creature.spec.kind} state ({type(exc).__name__}: {exc})") from None
            if migrated:
                self.migrated.append((path, data["kind"]))
            restored.append(creature.name)
            self._report_unplaced(path, creature)
        self._report_strangers(directory, saved)
        self._load_colony(saved.get(COLONY_FILE))
        return restored

    def _report_strangers(self, directory: Path, saved: dict[str, Path]) -> None:
        """Say which saved creatures no creature of the config takes (one renamed or removed):
        their files are left as they are, and taken back if a creature of that name returns."""
        names = {creature.name for creature in self.creatures}
        stems = (Path(name).stem for name in saved)  # a creature's NAME.json, no colony.state.json
        strangers = sorted(stem for stem in stems if "." not in stem and stem not in names)
        if strangers:
            self.say(f"{directory}: saved state of {', '.join(strangers)} matches no creature in "
                     f"{self.inst.path.name} (renamed or removed?); left as it is, and taken back if a creature "
                     "of that name returns")

    def _report_unplaced(self, path: Path, creature: Any) -> None:
        """Say which saved drive levels, tuple values, proximity tables, percept learning and
        expectations, adverb models, shaping and parts' state no drive, group, percept or tuple
        of the config takes (one renamed or removed), the nearest named: they are kept in the
        state, not lost, but the creature starts those parts afresh."""
        motivation = getattr(creature, "motivation", None)
        for kept in (getattr(motivation, "unplaced", None), creature.unplaced_parts):
            for part in kept.said() if kept is not None else ():
                self.say(f"{path}: {_unmatched(part, f'{creature.name} in {self.inst.path.name}')}")

    def _load_colony(self, path: Path | None) -> None:
        """The colony's heard pulse, if a file was saved (older state directories have none)."""
        if path is None:
            return
        data = load_json(path, kind=COLONY_KIND)
        try:
            self.world.pulse.restore(data)
        except RESTORE_ERRORS as exc:
            raise StateFileError(f"{path}: malformed colony state ({type(exc).__name__}: {exc})") from None


def _unmatched(part: Unmatched, where: str) -> str:
    """What a load says of the saved entries one section keeps (``where``: the creature and its
    config), in one line however many."""
    one = len(part.names) == 1
    return (f"the saved {part.what} of {part.of}{'' if one else 's'} {_names(part.names)}{part.within} "
            f"{'matches' if one else 'match'} no {part.no} of {where}{_nearest_each(part.names, part.among, part.no + 's')}; "
            f"kept in the state file, {'and taken back if one of that name' if one else 'each taken back if one of its name'} "
            "returns")


def _names(names: tuple[str, ...]) -> str:
    """``'a'``, ``'a' and 'b'``, ``'a', 'b' and 'c'``."""
    quoted = [repr(name) for name in names]
    return quoted[0] if len(quoted) == 1 else f"{', '.join(quoted[:-1])} and {quoted[-1]}"


def _nearest_each(names: tuple[str, ...], among: tuple[str, ...], what: str) -> str:
    """:func:`creatures.config.nearest` for one name; for several, the near ones each named
    (`` (did you mean 'answer' for 'tone.1|answer'?)``), else every valid one."""
    close = {name: difflib.get_close_matches(name, among, n=1) for name in names}
    near = [f"{found[0]!r} for {name!r}" for name, found in close.items() if found]
    if len(names) == 1 or not near:
        return nearest(names[0], among, what)  # the one name's nearest, or every valid one
    return f" (did you mean {', '.join(near)}?)"


def write_snapshot(directory: Path, snapshot: list[tuple[str, str]]) -> None:
    """Write a :meth:`Session.snapshot` into ``directory`` as one set (:mod:`creatures.state_set`):
    after a crash the folder holds all of one save, never creatures from two."""
    write_set(directory, snapshot)
