"""The installation config: what ``creatures run`` and ``creatures offline`` read.

Every key is documented in ``docs/config.md``; the field descriptions here are the source
of that page. Unknown keys are errors (a typo must never be silently ignored in a gallery).
"""

from __future__ import annotations

import difflib
import ipaddress
import re
import socket
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field, field_validator, model_validator

import installations

from creatures.bounds import FINITE, LONGEST_OFFLINE, Bounded
from creatures.authored.include import expand_includes, expand_kinds, expand_likes
from creatures.authored.plugins import load_plugins
from creatures.authored.registry import PluginError
from creatures.runtime.cc_sources import check_source
from creatures.runtime.trainer_spec import TrainerSection, check_trainer, unrewarded
from creatures.config import ConfigError, config_error, nearest, read_toml, validate, written_in
from creatures.kinds import CreatureSpec, load_all
from creatures.authored.percepts import ROOM_PERCEPTS, watched
from creatures.room.crowd import CrowdError, created as crowd_created, expand as expand_crowds
from creatures.room.spec import RoomSection
from creatures.score.spec import ScoreSpec
from creatures.room.stage import UNTRACKED, RoomError, StageError, check_places, recipes as room_recipes
from creatures.kinds.body_source import MaterialSpec
from creatures.motor.material import MaterialError


LONGEST_SEED = 2**63 - 1
"""Largest seed: numpy's SeedSequence takes any non-negative int, a config needs no more."""


class Strict(BaseModel):
    model_config = FINITE


class AudioSection(Strict):
    """Sample rate, live audio devices, and whether creatures hear each other."""

    sample_rate: int = Field(22050, ge=8000, le=192000, description="rate of synthesis and analysis, Hz. The "
                             "scanned strings are band-limited: a note with fewer than 16 of its string's harmonics "
                             "below 0.45 × this rate is read without those above, so a high voice does not alias "
                             "(measured at 22050: under 0.0001 % of a MIDI 96's or 108's energy off its harmonics, "
                             "was 8.8 % and 64 %; a lower note folds under 0.005 %) but keeps only its harmonics "
                             "below 9.9 kHz there; such a note costs more CPU (its string's shape is projected at "
                             "every physics frame)")
    block: int = Field(512, ge=32, le=16384, description="frames per audio block")
    input_device: str | int | None = Field(None, description="live input device (name fragment or index, or "
                                                            "'default' for the system's); none = no microphone")
    output_device: str | int | None = Field(None, description="live output device (name fragment or index)")
    output: bool = Field(True, description="live runs open an audio output; false when the sound comes from an "
                                           "external synth (MIDI or OSC): no device is opened, no underruns counted")
    air: bool = Field(False, description="creatures hear each other's voices (and their own) through "
                                         "the room, one tick late, as well as the input")
    transcribe: bool | None = Field(None, description="hear the pitched notes of the input audio (file or "
                                                      "microphone) as note events; unset = only when the "
                                                      "run has no MIDI note input")
    look: Literal["live", "quick"] = Field("live", description="how a live run hears notes in audio: 'live' "
                                             "names a struck note 35 ms past its attack's hop (p99 39 ms "
                                             "through JACK at 128 frames) and hears bowed, blown and "
                                             "chorded notes best; 'quick' 23 ms past it (p99 23 ms), "
                                             "hearing those worse (docs/hearing.md); an offline run "
                                             "always looks further")


class MidiSection(Strict):
    """Live MIDI ports (absent ports are reported and looked for again), and how each creature's
    channel is set up at the start of a run (live and in ``out.mid``) for creatures that do not
    set ``program``, ``bank``, ``volume`` or ``bend_range`` themselves; pan comes from each creature's ``pan``."""

    input_port: str | None = Field(None, description="live MIDI input port name or pattern")
    max_rate: int = Field(500, ge=100, le=100_000, description="MIDI input messages a second taken at most "
                                                              "(half a second's worth at once); beyond, "
                                                              "they are dropped and counted as throttled, "
                                                              "except the note-off of a note let in")
    output_port: str | None = Field(None, description="live MIDI output port name or pattern")
    program: int | None = Field(None, ge=0, le=127, description="General MIDI program (0 = piano) sent on "
                                                                "every creature's channel at start; none = the synth's own")
    bank: int | None = Field(None, ge=0, le=16383, description="bank (CC 0 and 32) sent before the program")
    volume: int | None = Field(None, ge=0, le=127, description="channel volume (CC 7) sent at start")
    bend_range: float | None = Field(None, ge=0, le=24, description="pitch-bend range in semitones (RPN 0) sent "
                                                                    "at start, for synths that bend the creatures' pitch")


class OscSection(Strict):
    """OSC (UDP) between colonies and to other tools."""

    host: str = Field("127.0.0.1", description="address OSC listeners bind to (loopback by default)")
    port: int | None = Field(None, ge=1024, le=65535, description="UDP port to listen on; none = no OSC")
    peers: list[str] = Field(default_factory=list, max_length=256,
                             description="host:port of other colonies to send notes to (IPv4)")
    max_peers: int = Field(64, ge=1, le=1024, description="remote creatures learned from (proved) hellos kept "
                                                         "at once; hellos beyond, or faster than 2 new a "
                                                         "second, are refused and counted (the network is "
                                                         "no amplifier: see README)")
    max_rate: int = Field(1_000, ge=100, le=1_000_000, description="OSC packets read per second at most; a "
                                                                    "flood beyond is dropped by the kernel and "
                                                                    "counted, and the creatures keep their time")


class StreamSection(Strict):
    """The body stream (``docs/stream.md``): each creature's joint positions and rotations, its
    end-effector, note objects in space, drives and current action, and the notes played and
    heard, at ``rate`` frames a second, for renderers (TouchDesigner, a browser view). Only a
    snapshot is taken on the creature's thread; a thread of its own encodes and sends."""

    rate: float = Field(30.0, gt=0, le=240, description="frames a second")
    targets: list[str] = Field(default_factory=list, max_length=64,
                               description="host:port of renderers a live run sends the stream to as OSC "
                                           "(IPv4); none = no OSC stream")
    file: bool = Field(False, description="offline runs write the stream into stream.jsonl beside out.mid")
    queue: int = Field(64, ge=1, le=4096, description="frames waiting for the sender thread at most; a frame "
                                                      "beyond is dropped and counted")


class ConsoleSection(Strict):
    """The remote console (``docs/stream.md``): OSC requests with ids, answered with replies,
    to read drives, values, percept trees and state, set a creature's spec key, trigger a
    tuple, reward, pause, resume and save. Off unless ``port`` is set."""

    port: int | None = Field(None, ge=1024, le=65535, description="UDP port the console listens on; none = no console")
    host: str = Field("127.0.0.1", description="address the console binds to (loopback by default; beyond "
                                               "loopback a secret is needed)")
    secret: str | None = Field(None, min_length=8, max_length=256,
                               description="shared secret every request carries after its id; none = no secret "
                                           "(only on loopback)")
    max_rate: int = Field(1_000, ge=10, le=100_000, description="requests a second answered at most; beyond, "
                                                                "they are counted and dropped unanswered")
    queue: int = Field(64, ge=1, le=1024, description="requests waiting for the creatures' thread at most; "
                                                      "beyond, answered 'busy' and counted")


class HealthSection(Strict):
    """How a run says it is alive: a JSON status over HTTP (``GET /health``) and an OSC
    heartbeat (``/colony/heartbeat``), both from threads of their own."""

    port: int | None = Field(None, ge=1024, le=65535, description="HTTP port of the health endpoint; none = none")
    host: str = Field("127.0.0.1", description="address the health endpoint binds to (loopback by default)")
    heartbeat: list[str] = Field(default_factory=list, max_length=64,
                                 description="host:port the OSC heartbeat goes to (IPv4); none = no heartbeat")
    every: float = Field(1.0, ge=0.1, le=3600, description="seconds between heartbeats")


class SnapshotSection(Strict):
    """Dated snapshots of the learned state, beside it in ``STATE/snapshots/`` (live runs with a
    state folder; creatures/runtime/snapshots.py): what the colony knew on any day of a long show."""

    every: float | None = Field(None, ge=60, le=366 * 24 * 3600.0,
                                description="seconds of the run's clock between snapshots (86400 = daily); none = none")
    keep_daily: int = Field(7, ge=1, le=3660, description="keep the newest snapshot of each of this many last days")
    keep_weekly: int = Field(8, ge=0, le=520, description="and of each of this many last ISO weeks")


class ScheduleSection(Strict):
    """Opening hours. A live run sleeps outside them — no sound, no selection, state kept — and
    wakes when they come round again (creatures/runtime/opening.py); a rehearsal
    (``[rehearse] hours``) brings its visitors only within them."""

    days: list[Literal["mon", "tue", "wed", "thu", "fri", "sat", "sun"]] = Field(
        ["mon", "tue", "wed", "thu", "fri", "sat", "sun"], min_length=1, max_length=7, description="days it opens")
    opens: str | None = Field(None, description="time of day it opens, HH:MM; none = always open")
    closes: str = Field("24:00", description="time of day it closes, HH:MM (before `opens`: past midnight)")
    timezone: str | None = Field(None, description="IANA zone of the hours, e.g. Europe/Paris; none = the machine's")

    @field_validator("opens", "closes")
    @classmethod
    def _time_of_day(cls, text: str | None) -> str | None:
        from creatures.runtime.opening import clock_time

        if text is not None:
            clock_time(text)
        return text

    @field_validator("timezone")
    @classmethod
    def _zone(cls, zone: str | None) -> str | None:
        from zoneinfo import ZoneInfo

        if zone is not None:
            try:
                ZoneInfo(zone)
            except (ValueError, OSError, KeyError):
                raise ValueError(f"unknown time zone {zone!r} (an IANA name such as Europe/Paris)") from None
        return zone


class PulseSection(Strict):
    """The colony's heard pulse, as competing metrical readings of what it hears.

    Every reading hears the rhythm from outside and is scored; the best is the pulse
    (creatures/temporal/readings.py; thesis "exotic duration models": "a population of
    (possibly competing) views and interpretations")."""

    readings: list[Literal["simple", "duple", "triple"]] = Field(
        ["simple"], min_length=1, max_length=3,
        description="metres read at once, each a low-integer-ratio model of its own ratios ('simple': every ratio "
                    "of 1-4; 'duple': 1/4, 1/2, 1, 2, 4; 'triple': 1/3, 2/3, 1, 2, 3); the best-scoring one is the "
                    "pulse every Du, percept and phrase of the colony follows")
    prior: float = Field(0.5, ge=0.05, le=3.0, description="seconds: the pulse assumed before any is heard")

    @field_validator("readings")
    @classmethod
    def _once(cls, readings: list[str]) -> list[str]:
        if len(set(readings)) != len(readings):
            raise ValueError(f"each metre is read once (got {readings})")
        return readings


class RehearseSection(Strict):
    """``creatures rehearse``: a gallery week on the simulated clock, with visitors who come and
    go over the opening hours, play or speak phrases from a corpus and answer what they hear
    (creatures/runtime/rehearse.py, creatures/runtime/visitors.py)."""

    days: int = Field(7, ge=1, le=366, description="simulated days rehearsed when `--days` is not given")
    hours: ScheduleSection | None = Field(None, description="the gallery's hours for the rehearsal; none = "
                                                            "`[schedule]`'s, or 10:00-18:00 Tuesday to Sunday if it has none")
    tick: float | None = Field(None, gt=0.0005, le=0.5, description="behaviour tick of the rehearsal, seconds; "
                                                                    "none = the installation's (every behaviour "
                                                                    "advances from elapsed time, so a coarser "
                                                                    "tick rehearses a week sooner)")
    visitors_per_hour: float = Field(6.0, ge=0, le=600, description="mean arrivals an opening hour (Poisson)")
    stay: float = Field(600.0, ge=10, le=8 * 3600.0, description="mean seconds a visitor stays (exponential)")
    phrase_every: float = Field(20.0, ge=1, le=3600, description="mean seconds between one visitor's phrases; "
                                                                 "an answered phrase is followed twice as soon")
    patience: int = Field(3, ge=1, le=100, description="phrases left unanswered in a row before a visitor leaves")
    answer_window: float = Field(8.0, gt=0, le=120, description="seconds after a phrase in which a creature's "
                                                                "act answers it (for notes: on one of its pitch classes)")
    corpus: str | None = Field(None, description="what visitors play: a MIDI file or folder of them (each file a "
                                                 "phrase), or a text file whose lines they speak (relative to "
                                                 "the config); none = the generated fragments, or the poem for "
                                                 "`generate = \"speech\"`")


class Arg(Strict):
    """A value read from the message: argument ``arg`` (0 = the first), or ``default`` when
    the message has no such argument."""

    arg: int = Field(ge=0, le=63, description="index of the message argument (0 = the first)")
    default: Bounded | str | None = Field(None, description="used when the message has no argument `arg`")


Number = Bounded | Arg
"""A constant, or ``{arg = N, default = X}``: read from the message."""

_NOTE_NAME = re.compile(r"([A-Ga-g])([#b]?)(-?\d)")
_STEPS = {"c": 0, "d": 2, "e": 4, "f": 5, "g": 7, "a": 9, "b": 11}


def named_pitch(text: str) -> int | None:
    """The MIDI number of a note name (``C4`` = 60, ``F#3``, ``Bb2``), else ``None``: a note
    map's ``pitch`` may be written either way, as may the message's argument it reads."""
    name = _NOTE_NAME.fullmatch(text.strip())
    if name is None:
        return None
    return 12 * (int(name[3]) + 1) + _STEPS[name[1].lower()] + {"#": 1, "b": -1}.get(name[2], 0)


class InputMap(Strict):
    """One `[[input]]` table: an outside source mapped to what the creatures take in
    (an OSC address or a MIDI message to a heard note, a sensor, a reward or a drive), or a
    source of messages (a serial device, a rehearsal file) whose lines are heard as OSC.
    TOML allows `[input]` or `[[input]]` in one file, not both: a config with an `[input]`
    table writes its maps as `[[input.map]]`."""

    osc: str | None = Field(None, description="OSC address pattern heard (OSC 1.0 wildcards: `*`, `?`, `[abc]`, "
                                              "`[!a-z]`, `{foo,bar}`); also matches serial lines and rehearsal rows")
    midi: str | None = Field(None, description="MIDI message heard: 'note', 'note_off', 'cc', 'program', "
                                               "'pitchbend', 'aftertouch' or 'polytouch' (its arguments, by index: "
                                               "note/note_off/polytouch: note, velocity or pressure, channel; "
                                               "cc: value, control, channel; program: program, channel; "
                                               "pitchbend: bend -8192..8191, channel; aftertouch: pressure, channel)")
    channel: int | None = Field(None, ge=0, le=15, description="only MIDI messages on this channel (0-15); none = any")
    control: int | None = Field(None, ge=0, le=127, description="only this controller number (midi = 'cc')")
    note: int | None = Field(None, ge=0, le=127, description="only this note number (midi = 'note', 'note_off', "
                                                              "'polytouch')")
    args: int | None = Field(None, ge=0, le=64, description="OSC arity: only messages with exactly this many "
                                                            "arguments; none = any")
    serial: str | None = Field(None, description="serial device's path read as a source, by one table "
                                                 "(e.g. '/dev/ttyUSB0'; lines `name value ...`, "
                                                 "spaces or commas): a line is heard as the OSC message "
                                                 "`/name value ...`; a missing device is reported and retried")
    baud: int = Field(9600, gt=0, le=4_000_000, description="serial speed, bits per second")
    file: str | None = Field(None, description="rehearsal file (path relative to the config) of timed messages "
                                               "played from the start of the run: CSV rows `time,address,args...` "
                                               "or JSON lines {\"time\", \"address\", \"args\"}; address 'midi' "
                                               "takes the MIDI bytes as args. Rows past the run's end are said: "
                                               "offline before it plays, live as a count when it stops")
    to: str | None = Field(None, description="what the message becomes: 'note' (a heard note), 'sensor' (a named "
                                             "sensor creatures read as a percept), 'reward' (the clicker) or "
                                             "'drive' (a drive perturbation)")
    pitch: Number | None = Field(None, description="to = 'note': MIDI pitch (a fractional one, a sensor's 60.4, "
                                                   "to the nearest key), or a note name such as 'C4' (default: "
                                                   "{arg = 0})")
    velocity: Number | None = Field(None, description="to = 'note': velocity 1-127 (default: the MIDI note's, "
                                                      "else 100)")
    duration: Number | None = Field(None, description="to = 'note': seconds (default 0.25)")
    name: str | None = Field(None, pattern=r"^[A-Za-z0-9_.\-]+$", description="to = 'sensor' (needed): the sensor's name "
                                                                             "(world.sensors[name], a StateObject: "
                                                                             "saliency = |reading|, habituating "
                                                                             "to repetition)")
    value: Number | None = Field(None, description="to = 'sensor': the reading (default: {arg = 0})")
    range: tuple[Bounded, Bounded] | None = Field(None, description="to = 'sensor': scale the reading linearly from "
                                                                "`input_range` to [lo, hi]")
    input_range: tuple[Bounded, Bounded] | None = Field(None, description="to = 'sensor', with `range`: the reading's "
                                                                      "own span, not empty; reversed inverts it "
                                                                      "(default: the MIDI value's, 0-127 or "
                                                                      "-8192..8191; for OSC [0, 1])")
    creatures: Annotated[list[str], Field(max_length=256)] | Arg | None = Field(None, description="to = 'reward' or 'drive': the creatures it "
                                                                "reaches, or {arg = N} naming one; none = every "
                                                                "creature that can take it")
    amount: Number | None = Field(None, description="to = 'reward': value of the reward (default 1.0; negative "
                                                    "punishes; beyond ±1000 the message is malformed); "
                                                    "to = 'drive': added to the drive's level")
    set: Number | None = Field(None, description="to = 'drive': the level the drive is set to (instead of amount)")
    drive: str | None = Field(None, description="to = 'drive': the drive's name (e.g. 'boredom')")
    window: float = Field(1.5, ge=0, le=10, description="to = 'reward': seconds before the click in which a tuple "
                                                        "that was active still takes the reward (a late click lands "
                                                        "where the visitor meant it)")
    rate: float = Field(0.2, ge=0, le=1, description="to = 'reward': how far one reward moves a credited tuple's "
                                                     "value, V += rate x trigger x amount (its own credit "
                                                     "assignment's blend parameter, whatever the creature's alpha)")
    limit: float | None = Field(None, gt=0, le=10_000, description="most messages a second the map takes (a "
                                "burst of `limit` passes, then `limit` a second); more are dropped, counted as "
                                "`throttled` and logged: a stuck sensor or a flooding sender cannot retrain the "
                                "colony or swamp a drive. Default: 10 for to = 'reward' (a visitor's clicks), "
                                "none otherwise")

    @field_validator("pitch", mode="before")
    @classmethod
    def _named_pitch(cls, value: Any) -> Any:
        """``pitch = "C4"``, as the description offers, is read as its number here; it was
        refused as "not a valid number". Other text is left to the number's own error."""
        if isinstance(value, str) and (number := named_pitch(value)) is not None:
            return number
        return value

    @field_validator("pitch", "velocity")
    @classmethod
    def _midi_number(cls, value: Any, info: Any) -> Any:
        """A constant pitch or velocity is a MIDI number: one beyond it (``pitch = 200``) made
        every note the map heard malformed, counted and dropped, and the config loaded."""
        low = 0 if info.field_name == "pitch" else 1
        if isinstance(value, int | float) and not low <= value <= 127:
            raise ValueError(f"a {info.field_name} is a MIDI number {low}-127"
                             + (" or a note name such as 'C4'" if info.field_name == "pitch" else ""))
        return value


class InputSection(Strict):
    """What an offline run hears when the command line gives no files (and `map`: the input maps, see `[[input]]`)."""

    audio: str | None = Field(None, description="recorded audio fed offline (path relative to the config)")
    midi: str | None = Field(None, description="recorded MIDI fed offline (path relative to the config)")
    generate: Literal["phrase", "speech", "none"] = Field("phrase",
                          description="input generated when no recording is given (--audio, --midi, or "
                                      "`audio`/`midi` here): 'phrase' (three note fragments, as notes and as "
                                      "tones), 'speech' (the poem Ozymandias read by formant voices, audio only) "
                                      "or 'none'. An input map's rehearsal `file` plays beside it: 'none' to "
                                      "hear the rehearsal alone")
    map: list[InputMap] = Field(default_factory=list, max_length=1024, description="the input maps (see `[[input]]`)")
    trainer: TrainerSection | None = Field(None, description="a simulated clicker trainer that says cues and clicks, "
                                                             "offline only")


class CcSection(Strict):
    """One ``[[output.cc]]`` stream: a creature's drive or body feature sent as a MIDI control
    change (live and in ``out.mid``), e.g. boredom opening a synth's filter, or the hand's
    height (``creatures/runtime/cc_sources.py``)."""

    source: str = Field(pattern=r"^[A-Za-z0-9_\-]+(\.[A-Za-z0-9_\-]+){1,2}$",
                        description="'<creature>.<drive>', e.g. 'ada.boredom', or, for a creature with a body, "
                                    "'<creature>.body.<feature>': effector_x, effector_y, effector_z, "
                                    "effector_height (= effector_y, up) or speed (the end-effector's, units/s)")
    controller: int = Field(ge=0, le=119, description="MIDI controller number (on the creature's channel)")
    range: tuple[Bounded, Bounded] = Field((0.0, 1.0), description="source values mapped to 0 and 127 (clipped)")
    rate: float = Field(10.0, gt=0, le=100, description="most messages a second (sent only when the value changes)")


class OutputSection(Strict):
    """What an offline run writes into its output directory, and MIDI control streams."""

    midi: bool = Field(True, description="write out.mid")
    wav: bool = Field(True, description="write out.wav")
    frames: bool = Field(False, description="render the bodies to PNG frames (needs EGL or OSMesa)")
    video: bool = Field(False, description="also encode frames to out.mp4")
    fps: float = Field(12.0, gt=0, le=120, description="frame rate of rendered frames")
    width: int = Field(320, ge=16, le=3840, description="frame width, pixels")
    height: int = Field(240, ge=16, le=2160, description="frame height, pixels")
    follow: bool = Field(True, description="the camera follows walking bodies (it keeps the middle of their roots "
                                           "where the first frame had it); false: it stays where it framed "
                                           "the first frame, and a walking body walks out of the picture")
    report: bool = Field(True, description="write report/ (plots and index.html) after an offline run")
    cc: list[CcSection] = Field(default_factory=list, max_length=256, description="MIDI control-change streams")


class ViewSection(Strict):
    """The live view in a browser (``creatures run --view``) and the bodies an offline run keeps
    in its events log for ``creatures view`` and ``creatures render`` (docs/view.md). The view
    binds to loopback only: it shows a colony, it is no remote control."""

    port: int | None = Field(None, ge=1024, le=65535, description="TCP port of the live view on 127.0.0.1 "
                                                                 "(`creatures run --view [PORT]` sets or overrides "
                                                                 "it); none = no view")
    fps: float = Field(30.0, ge=1.0, le=60.0, description="snapshots a second the live view takes from the "
                                                          "colony (bodies, notes, drives); more wait in a "
                                                          "bounded queue, beyond it they are dropped and counted")
    log_fps: float = Field(10.0, ge=0.0, le=60.0, description="body poses a second a run writes into its "
                                                              "events log (offline: events.jsonl; live: --log) "
                                                              "as `pose` events, for replay and re-rendering; "
                                                              "0 = none")


class Installation(Strict):
    title: str = Field(description="name of the installation")
    description: str = Field("", description="free text shown in reports")
    seed: int = Field(0, ge=0, le=LONGEST_SEED, description="seed of every random choice in the run")
    tick: float = Field(0.02, gt=0.0005, le=0.5, description="behaviour tick, seconds")
    duration: float = Field(60.0, gt=0, le=LONGEST_OFFLINE, description="offline run length in simulated seconds (default)")
    save_every: float = Field(60.0, gt=0, le=24 * 3600.0, description="seconds between state saves in live runs")
    state: str | None = Field(None, description="directory for saved creature state (live runs)")
    realtime: bool = Field(True, description="live runs ask the OS for real-time scheduling of the creatures' "
                                             "thread (round-robin, priority 5: below JACK's) where allowed, so a "
                                             "busy machine cannot make ticks late; refused, the run goes on and says so")
    audio: AudioSection = AudioSection()
    midi: MidiSection = MidiSection()
    osc: OscSection = OscSection()
    stream: StreamSection = StreamSection()
    console: ConsoleSection = ConsoleSection()
    health: HealthSection = HealthSection()
    snapshots: SnapshotSection = SnapshotSection()
    schedule: ScheduleSection = ScheduleSection()
    rehearse: RehearseSection = RehearseSection()
    pulse: PulseSection = PulseSection()
    input: InputSection = InputSection()
    output: OutputSection = OutputSection()
    room: RoomSection | None = Field(None, description="[room]: the floor the creatures move on, hear "
                                                        "and sound from (see the room section of docs/config.md)")
    view: ViewSection = ViewSection()
    include: list[str] = Field(default_factory=list, max_length=256, description="creature files ([[creature]] "
                                                                 "tables) included, relative to this file")
    plugins: list[str] = Field(default_factory=list, max_length=256, description="Python files of actions, "
                                                                 "percepts, models or kinds to register, "
                                                                 "relative to this file")
    creature: list[dict[str, Any]] = Field(min_length=1, max_length=256, description="the creatures, one [[creature]] "
                                                                                     "table each (`count = N` makes a "
                                                                                     "crowd of N from one, `vary` their "
                                                                                     "ranges: creatures/room/crowd.py)")

    @model_validator(mode="before")
    @classmethod
    def _input_maps(cls, data: Any) -> Any:
        """``[[input]]`` tables are the maps of the ``[input]`` section (TOML lets a file have
        one form or the other, so both are read into one place)."""
        if isinstance(data, dict) and isinstance(data.get("input"), list):
            data = {**data, "input": {"map": data["input"]}}
        return data


class LoadedInstallation:
    """A validated installation: its top-level settings and each creature's typed spec."""

    def __init__(self, path: Path, settings: Installation, specs: list[CreatureSpec],
                 where: dict[tuple, tuple[Path, int]] | None = None) -> None:
        from creatures.runtime.input_routes import Colony, compile_maps

        self.path = path
        self.settings = settings
        self.specs = specs
        self.where = where or {}  # key path -> (file, line): errors found later still name the line
        kinds = load_all()
        # The input maps, checked against the creatures (unknown names, drives): MapError.
        self.routes = compile_maps(settings.input.map, {
            spec.name: Colony(kinds[spec.kind].drive_names(spec), kinds[spec.kind].rewardable(spec)) for spec in specs})
        self.rehearsals: dict[int, list] = {}  # rows of each rehearsal file, by [[input]] table
        self.notes: list[str] = []
        """What loading found that is not an error but may be a mistake (a run says each at its
        start and keeps it in the events log as a ``config`` event; ``creatures check`` says it)."""

    def error(self, loc: tuple[str | int, ...], message: str) -> ConfigError:
        """A :class:`ConfigError` at key path ``loc`` of this config, with its line."""
        return config_error(self.path, self.where, loc, message)

    def resolve(self, relative: str | None, key: tuple[str | int, ...] = ()) -> Path | None:
        """A path from the config at ``key``, relative to the directory of the file that wrote
        it (an ``extends`` base's paths are its own, not the including file's)."""
        return None if relative is None else (written_in(self.where, key, self.path).parent / relative).resolve()


def _sensed(path: Path, where, loc: tuple, own: str, params: dict, by_name: dict) -> None:
    """A 'sensed' percept names another creature of this installation and one of its percepts."""
    whom, what = params.get("creature"), params.get("percept")
    other = by_name.get(whom)
    if other is None or whom == own:
        others = sorted(n for n in by_name if n != own)
        raise config_error(path, where, (*loc, "creature"),
                           f"no other creature named {whom!r}{nearest(whom, others, 'the others')}")
    percepts = getattr(other, "percepts", None)
    if percepts is None:
        raise config_error(path, where, (*loc, "creature"), f"{whom!r} is a {other.kind!r} creature: only an "
                                                            "authored creature's percepts can be sensed")
    if what not in percepts and what != "whatever":
        raise config_error(path, where, (*loc, "percept"),
                           f"{whom!r} has no percept {what!r}{nearest(what, sorted(percepts), 'its percepts')}")


def _sensor(path: Path, where, loc: tuple, params: dict, sensors: list[str]) -> None:
    """A 'sensor' percept (or a tracked visitor) reads a sensor an ``[[input]]`` map writes
    (``to = "sensor"``), the only thing that makes one: named nowhere, it is a slip to say at
    its line with the nearest name before anything runs (a percept's was found only as the
    creature was built, with no line and no nearest name)."""
    name = params.get("sensor")
    if name not in sensors:
        close = difflib.get_close_matches(str(name), sensors, n=1)
        hint = (f"did you mean {close[0]!r}?" if close else f"the sensors: {sensors}" if sensors else
                'no [[input]] map has to = "sensor"')
        raise config_error(path, where, loc, f"no input map writes a sensor {name!r} ({hint})")


def _crowd_slip(exc: ConfigError, table: dict, index: int, path: Path, where: dict) -> ConfigError:
    """A clone's error under a key only its table's ``vary`` or ``cycle`` wrote (a misspelt
    ``"tuples.chirp.action.transpos"``) is that key's: said at its line, naming it, not at the
    line of the table it landed in, where the misspelling is nowhere to be seen."""
    for parts, section, dotted in crowd_created(table):
        made = ".".join(("creature", str(index), *parts))
        if exc.key == made or exc.key.startswith(made + "."):
            return config_error(path, where, ("creature", index, section, dotted),
                                f"{exc.message} (at {exc.key.removeprefix(f'creature.{index}.')}, which "
                                f"{section} sets for each clone)")
    return exc


def _first_named(where: dict, index: int, path: Path) -> str:
    """Where the first creature of a duplicated name was written: with includes the two may be
    files apart (or one file included twice), and the error's own line is the second's."""
    file, line = where.get(("creature", index, "name")) or where.get(("creature", index), (path, None))
    return f" (the first is at {file.name}:{line})" if line is not None else ""


def load_installation(path: str | Path) -> LoadedInstallation:
    """Read and validate an installation config; :class:`ConfigError` names key and line."""
    path = Path(path).resolve()
    data, where = read_toml(path)
    includes = data.get("include", [])
    expand_includes(data, where, path)
    expand_kinds(data, where, path)
    expand_likes(data, where, path)
    data["include"] = includes
    settings = validate(Installation, data, where, path)
    load_plugins(settings.plugins, path, where)
    try:
        kinds = load_all()
    except PluginError as exc:  # an installed package's entry point that does not import
        raise ConfigError(path, str(exc)) from None
    specs: list[CreatureSpec] = []
    names: dict[str, int] = {}  # each creature's name: its table's index
    said: list[str] = []  # what a creature's check found that runs but may be a mistake
    try:
        tables, origin = expand_crowds(settings.creature, settings.seed)
    except CrowdError as exc:
        raise config_error(path, where, ("creature", exc.index, *exc.key), str(exc)) from None
    for table, i in zip(tables, origin):
        kind = table.get("kind")
        if not isinstance(kind, str) or kind not in kinds:  # kind = [] must not crash the lookup
            known = sorted({*kinds, *installations.creature_names()})  # classes and shipped creature documents
            raise config_error(path, where, ("creature", i, "kind"),
                               f"unknown creature kind {kind!r}{nearest(kind, known, 'choose from')}")
        try:
            spec = validate(kinds[kind].Spec, table, where, path, prefix=("creature", i))
            _resolve_body(kinds[kind], spec, path, where, ("creature", i))
            check = getattr(spec, "check_references", None)  # kinds that name parts resolve them now
            if check is not None:
                said += check(path, where, ("creature", i)) or []
        except ConfigError as exc:
            raise _crowd_slip(exc, settings.creature[i], i, path, where) from None
        if spec.name in names:
            raise config_error(path, where, ("creature", i, "name"), f"duplicate creature name {spec.name!r}"
                                                                     + _first_named(where, names[spec.name], path))
        names[spec.name] = i
        specs.append(spec)
    by_name = {spec.name: spec for spec in specs}
    sensors = sorted({m.name for m in settings.input.map if m.to == "sensor" and m.name})
    for spec, i in zip(specs, origin):
        for name, percept in (getattr(spec, "percepts", None) or {}).items():
            if percept.type in ROOM_PERCEPTS and settings.room is None:
                raise config_error(path, where, ("creature", i, "percepts", name, "type"),
                                   f"percept type {percept.type!r} needs a [room] (where would it be?)")
            if percept.type in ROOM_PERCEPTS and not settings.room.visitors \
                    and watched(percept.type, percept.params()) == "visitor":
                given = "" if "of" in percept.params() else " (its 'of' when none is given)"
                raise config_error(path, where, ("creature", i, "percepts", name, "of"),
                                   f"{percept.type} of the nearest tracked visitor{given}, and the room tracks "
                                   f"none ([[room.visitors]]): {UNTRACKED}")
            if percept.type == "sensed":
                _sensed(path, where, ("creature", i, "percepts", name), spec.name, percept.params(), by_name)
            if percept.type == "sensor":
                _sensor(path, where, ("creature", i, "percepts", name, "sensor"), percept.params(), sensors)
        if settings.room is None and "vehicle" in spec.model_fields_set:  # it would never move, nothing said
            raise config_error(path, where, ("creature", i, "vehicle"),
                               "[creature.vehicle] places and steers a creature on a room's floor, and there is "
                               "no [room]: add one (README, \"Creatures in a room\") or leave the vehicle out")
    if settings.room is not None:  # what the creatures' steering names must be in the room
        try:
            room_recipes(settings.room, specs, {spec.name: i for i, spec in enumerate(specs)})
            check_places(settings.room, specs, [kinds[spec.kind].drive_names(spec) for spec in specs])
        except StageError as exc:
            raise config_error(path, where, ("creature", origin[exc.creature], *exc.key), str(exc)) from None
        except RoomError as exc:
            raise config_error(path, where, ("room", *exc.key), str(exc)) from None
    if settings.room is not None:  # a visitor is tracked through sensors the input map writes
        read: dict[str, str] = {}  # each sensor a visitor reads, by whom
        for k, visitor in enumerate(settings.room.visitors):
            for axis in ("x", "y"):
                name, loc = getattr(visitor, axis), ("room", "visitors", k, axis)
                _sensor(path, where, loc, {"sensor": name}, sensors)
                if name in read:  # a copied table: one person counted twice, or walking the diagonal
                    raise config_error(path, where, loc, f"sensor {name!r} is read by {read[name]} already: "
                                                         "each coordinate of each visitor has a sensor of its own")
                read[name] = f"visitor {k}'s {axis}"
    if settings.input.trainer is not None:
        check_trainer(settings.input.trainer, specs, kinds, path, where)
    for key in ("audio", "midi"):
        file = getattr(settings.input, key)
        if file is not None and not (written_in(where, ("input", key), path).parent / file).exists():
            raise config_error(path, where, ("input", key), f"file not found: {file}")
    if settings.osc.port is not None and (problem := host_problem(settings.osc.host)) is not None:
        raise config_error(path, where, ("osc", "host"), problem)
    for section, what in (("console", "console"), ("health", "health endpoint")):
        part = getattr(settings, section)
        if part.port is not None and (problem := host_problem(part.host, what)) is not None:
            raise config_error(path, where, (section, "host"), problem)
    share = settings.room.share if settings.room is not None else None
    if share is not None:  # as [osc]'s: an IPv6 or typo'd host once passed, said only once the run was set up
        if (problem := host_problem(share.host, "room share")) is not None:
            raise config_error(path, where, ("room", "share", "host"), problem)
        for i, peer in enumerate(share.peers):
            if (problem := peer_problem(peer)) is not None:
                raise config_error(path, where, ("room", "share", "peers", i), problem)
    console = settings.console
    if console.port is not None and console.secret is None and not loopback(console.host):
        raise config_error(path, where, ("console", "host"), OPEN_CONSOLE.format(host=console.host))
    for loc, peers in ((("osc", "peers"), settings.osc.peers), (("stream", "targets"), settings.stream.targets),
                       (("health", "heartbeat"), settings.health.heartbeat)):
        for i, peer in enumerate(peers):
            problem = peer_problem(peer)
            if problem is not None:
                raise config_error(path, where, (*loc, i), problem)
    for i, stream in enumerate(settings.output.cc):
        creature = stream.source.split(".")[0]
        if creature not in names:
            raise config_error(path, where, ("output", "cc", i, "source"),
                               f"no creature named {creature!r}{nearest(creature, sorted(names), 'creatures')}")
        kind = kinds[by_name[creature].kind]
        problem = check_source(stream.source, kind.drive_names(by_name[creature]), kind.has_body(by_name[creature]))
        if problem is not None:
            raise config_error(path, where, ("output", "cc", i, "source"), problem)
    from creatures.score.tiles import unplayed_layers  # tiles read pitches as input maps do: imported late

    notes = unplayed_layers({spec.name: spec.score for spec in specs if isinstance(getattr(spec, "score", None), ScoreSpec)})
    inst = _with_input_maps(path, settings, specs, where, ("input",) if isinstance(data.get("input"), list)
                            else ("input", "map"))
    inst.notes = notes + list(dict.fromkeys(said)) + inst.notes  # a crowd's copies of one table say it once
    if settings.input.trainer is not None and (note := unrewarded(settings.input.trainer, inst.routes)) is not None:
        inst.notes.append(note)
    return inst


def _resolve_body(kind: type, spec: CreatureSpec, path: Path, where: dict[tuple, tuple[Path, int]],
                  prefix: tuple[str | int, ...]) -> None:
    """Build (or load from its cache) a ``[creature.body]`` from files, relative to the file that
    names them (an included creature file's own directory); errors name the key's line and,
    inside, the source file's own line."""
    body = getattr(spec, "body", None)
    if not isinstance(body, MaterialSpec) or not body.custom:
        return
    at = (*prefix, "body")
    named = [file for key, (file, _) in where.items() if key[:len(at)] == at]
    try:
        material = body.resolve((named[0] if named else path).parent, ratios=bool(getattr(spec, "ratio_metric", False)))
    except MaterialError as exc:
        raise config_error(path, where, (*at, *exc.key), str(exc)) from None
    poses = material.graph.poses
    problem = kind.body_problem(spec, poses.every_label, poses.skeleton.names)
    if problem is not None:
        raise config_error(path, where, at, problem)


def _with_input_maps(path: Path, settings: Installation, specs: list[CreatureSpec],
                     where: dict[tuple, tuple[Path, int]], prefix: tuple[str, ...]) -> LoadedInstallation:
    """The installation, once every ``[[input]]`` table is known to work (the rehearsal files
    read, the maps checked against the creatures); :class:`ConfigError` at the table's key."""
    from creatures.runtime.input_routes import MapError
    from creatures.runtime.input_sources import RehearsalError, load_rehearsal

    try:
        inst = LoadedInstallation(path, settings, specs, where)
    except MapError as exc:
        raise config_error(path, where, (*prefix, exc.index, exc.key), str(exc)) from None
    for i, spec in enumerate(settings.input.map):
        if spec.file is not None:
            try:
                inst.rehearsals[i] = load_rehearsal(written_in(where, (*prefix, i, "file"), path).parent / spec.file)
            except RehearsalError as exc:
                raise config_error(path, where, (*prefix, i, "file"), str(exc)) from None
            if not inst.rehearsals[i]:  # an export that wrote only its header: the run heard nothing, and said nothing
                inst.notes.append(str(config_error(path, where, (*prefix, i, "file"), f"{spec.file} holds no rows "
                                                   "(empty, or only a header and comments): it plays nothing")))
    return inst


def host_problem(host: str, what: str = "OSC") -> str | None:
    """Why the colony cannot listen on ``host`` ([osc] host; ``what`` names the listener), or
    None: a host that does not resolve, or one that is IPv6 (refused: every socket here is IPv4,
    and a colony on ::1 that peers on 127.0.0.1 would hear nothing). Checked at load, before
    anything runs or is made."""
    try:
        family = socket.getaddrinfo(host, None, type=socket.SOCK_DGRAM)[0][0]
    except (OSError, UnicodeError) as exc:
        return f"{what} host {host!r} does not resolve ({exc})"
    if family != socket.AF_INET:
        return (f"{what} host {host!r} is not IPv4: every socket here speaks IPv4 only "
                "(use 127.0.0.1, 0.0.0.0 or an IPv4 address of this machine)")
    return None


OPEN_CONSOLE = ("a console open to the network (host {host!r}) needs a secret: a request without one may come "
                "from a forged address, and its reply (up to 60,000 bytes for a 40-byte request) goes to that "
                "address, so the colony would be an amplifier aimed at whomever a stranger names, and anyone "
                "on the network could pause it or set its creatures; set [console] secret (every request "
                "carries it after its id), or keep host = \"127.0.0.1\"")
"""Why a console bound beyond loopback must have a secret (docs/stream.md, "The remote console")."""


def loopback(host: str) -> bool:
    """Whether ``host`` (already known to resolve) is this machine's loopback: only this
    machine's programs can send to it, so no one forges a sender there."""
    return ipaddress.ip_address(socket.getaddrinfo(host, None, type=socket.SOCK_DGRAM)[0][4][0]).is_loopback


def peer_problem(peer: str) -> str | None:
    """Why ``peer`` cannot be spoken to (before anything runs: a typo'd host must not leave a
    colony talking to no one all night, and a port of 99999 once passed and made every send
    raise mid-run), or None. IPv6 is refused: every socket here is IPv4."""
    host, colon, port = peer.rpartition(":")
    if not colon:
        return f"peer {peer!r} is not host:port (no port: a port in 1..65535)"
    if not (port.isascii() and port.isdigit()):  # str.isdigit() takes '²', which int() refuses
        return f"peer {peer!r} is not host:port (port {port!r} is not a number: a port in 1..65535)"
    if not 0 < int(port) < 65536:
        return f"peer {peer!r} is not host:port (port {port} is out of range: a port in 1..65535)"
    if ":" in host or host.startswith("["):
        return f"peer {peer!r} is IPv6: OSC here speaks IPv4 only"
    try:
        socket.gethostbyname(host or "127.0.0.1")
    except OSError as exc:
        return f"peer host of {peer!r} cannot be resolved ({exc.strerror or exc})"
    return None


__all__ = ["ConfigError", "Installation", "LoadedInstallation", "load_installation"]
