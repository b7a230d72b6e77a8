"""The ``creatures`` command. Subcommands are small functions registered in ``COMMANDS``."""

from __future__ import annotations

import argparse
import difflib
import os
import signal
import sys
from pathlib import Path
from typing import Callable

from creatures.bounds import LONGEST_OFFLINE, LONGEST_SECONDS, number

Configure = Callable[[argparse.ArgumentParser], None]
"""Adds a subcommand's arguments to its parser."""

Run = Callable[[argparse.Namespace], int]
"""Runs a subcommand with its parsed arguments; returns the exit code."""

COMMANDS: dict[str, tuple[str, Configure, Run]] = {}


def _seconds(longest: float, what: str = "a number of seconds") -> Callable[[str], float]:
    """An argparse ``type``: a finite number (of seconds, unless ``what`` says otherwise) in
    (0, ``longest``]; anything else (``nan``, ``inf``, ``-5``) is argparse's usage error, exit
    2, naming the option."""

    def parse(text: str) -> float:
        try:
            value = number(float(text), "seconds", low=0.0, high=longest)
        except ValueError:
            value = 0.0
        if value == 0.0:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what} in (0, {longest:g}]")
        return value

    return parse


def _bounded(low: float, high: float) -> Callable[[str], float]:
    """An argparse ``type``: a finite number in [``low``, ``high``]; anything else is argparse's
    usage error, exit 2, naming the option."""

    def parse(text: str) -> float:
        try:
            return number(float(text), "value", low=low, high=high)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number in [{low:g}, {high:g}]") from None

    return parse


def command(name: str, help_text: str, configure: Configure) -> Callable[[Run], Run]:
    """Register ``fn(args) -> exit code`` as ``creatures NAME``."""

    def register(fn: Run) -> Run:
        COMMANDS[name] = (help_text, configure, fn)
        return fn

    return register


@command("version", "print the version", lambda parser: None)
def _print_version(_: argparse.Namespace) -> int:
    from creatures import __version__

    print(f"creature-music {__version__}")
    return 0


def _no_options(_: argparse.ArgumentParser) -> None:
    pass


@command("devices", "list audio and MIDI devices (and say why when a backend is missing)", _no_options)
def _devices(_: argparse.Namespace) -> int:
    from audio.device import AudioDeviceUnavailable, sounddevice_module

    try:
        sd = sounddevice_module()
        devices = sd.query_devices()
        print("audio devices:" if len(devices) else "audio devices: none found (PortAudio sees no sound card and "
                                                     "no JACK server): plug one in or start a JACK server")
        for d in devices:
            print(f"  [{d['index']}] {d['name']} (in {d['max_input_channels']}, out {d['max_output_channels']})")
    except AudioDeviceUnavailable as exc:
        print(f"audio devices: {exc}")
    try:
        import mido

        from midi.ports import BACKEND_HINT

        inputs, outputs = mido.get_input_names(), mido.get_output_names()
        print(f"MIDI inputs ({mido.backend.name}): {inputs or 'none'}")
        print(f"MIDI outputs: {outputs or 'none'}")
    except Exception as exc:  # any backend failure is reported, never fatal here
        print(f"MIDI devices: unavailable ({exc}); {BACKEND_HINT}")
    return 0


def _offline_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", type=Path, help="installation config (TOML), or a shipped installation's name")
    parser.add_argument("--audio", type=Path, help="recorded audio to feed (overrides the config)")
    parser.add_argument("--midi", type=Path, help="recorded MIDI to feed (overrides the config)")
    parser.add_argument("--out", type=Path, required=True, help="directory for the outputs")
    parser.add_argument("--duration", type=_seconds(LONGEST_OFFLINE), help="simulated seconds (default: the config's)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--frames", action="store_true", help="draw the bodies into DIR/frames (PNGs; needs EGL or OSMesa)")
    parser.add_argument("--video", action="store_true", help="draw the frames and encode them to DIR/out.mp4")


def _config_path(config: Path) -> Path:
    """A config path, ``NAME`` for ``NAME.toml`` here, or the name of a shipped installation
    (as ``demo`` takes). A name that is none of these is a :class:`ConfigError` naming the
    nearest shipped installation, if one is near."""
    import installations
    from creatures.config import ConfigError

    if config.exists() or config.suffix == ".toml":
        return config
    if config.with_name(config.name + ".toml").is_file():
        return config.with_name(config.name + ".toml")
    try:
        return installations.path(str(config))
    except FileNotFoundError:
        beside = difflib.get_close_matches(config.name, [p.stem for p in config.parent.glob("*.toml")], n=1)
        close = installations.nearest(str(config))
        raise ConfigError(config.resolve(), "config file not found" + (
            f" (did you mean {config.with_name(beside[0] + '.toml')}?)" if beside else
            f" (did you mean the shipped {close!r}?)" if close else
            f", nor {config.name}.toml, nor a shipped installation ({', '.join(installations.names())})")) from None


def _run_offline(config: Path, out: Path, *, audio: Path | None = None, midi: Path | None = None,
                 duration: float | None = None, progress: bool = True, frames: bool = False,
                 video: bool = False) -> int:
    """``frames``/``video`` turn the config's ``[output]`` keys on (never off)."""
    from audio.sources import AudioFileError
    from creatures.config import ConfigError
    from creatures.paths import regular_file
    from creatures.runtime.offline import run_offline
    from creatures.runtime.schema import load_installation
    from midi.files import MidiFileError

    try:
        installation = load_installation(_config_path(config))
        output = installation.settings.output
        output.frames = output.frames or frames or video
        output.video = output.video or video
        for given, what in ((audio, "--audio"), (midi, "--midi")):
            if given is not None and not regular_file(given, what).exists():
                raise FileNotFoundError(f"{given}: no such file")
        summary = run_offline(installation, out, audio=audio, midi=midi, duration=duration, progress=progress)
    except (ConfigError, AudioFileError, MidiFileError, OSError) as exc:  # OSError: e.g. disk full, locked
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    for message in summary.messages:
        print(f"note: {message}")
    print(f"{installation.settings.title}: {summary.simulated:.1f} simulated s in {summary.wall:.2f} wall s "
          f"({summary.speed:.1f}x real time), {summary.notes_played} notes played"
          + (f", {summary.sounds_made} sounds sung or words read" if summary.sounds_made else ""))
    for name, file in summary.files.items():
        print(f"  {name:<7} {file}")
    return 0


def _rehearse_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", type=Path, help="installation config (TOML), or a shipped installation's name")
    parser.add_argument("--days", type=_integer(1, 366, "a whole number of days"), metavar="N",
                        help="simulated days, 1-366 (default: [rehearse] days, 7)")
    parser.add_argument("--compare", type=Path, metavar="OTHER", help="a second config rehearsed beside it, "
                                                                     "side by side in one report")
    parser.add_argument("--json", type=Path, metavar="FILE", help="also write every hour's measures as JSON")


@command("rehearse", "a gallery week on the simulated clock, with visitors, measured hour by hour",
         _rehearse_options)
def _rehearse(args: argparse.Namespace) -> int:
    import dataclasses
    import json

    from creatures.config import ConfigError
    from creatures.persist import atomic_write
    from creatures.runtime.rehearse import plan, rehearse, report
    from creatures.runtime.schema import load_installation
    from creatures.runtime.visitors import CorpusError

    try:
        # Every config is read (its opening hours and corpus too), and the --json folder looked
        # at, before a week is rehearsed: a slip in --compare's config, or a missing folder, was
        # found after the minutes of the first one's week.
        configs = [args.config] + ([args.compare] if args.compare is not None else [])
        loaded = [load_installation(_config_path(c)) for c in configs]
        folder = None if args.json is None else args.json.parent
        if folder is not None and not (folder.is_dir() and os.access(folder, os.W_OK)):
            raise OSError(f"--json {args.json}: " + (f"{folder} is not writable" if folder.is_dir()
                                                      else f"there is no folder {folder}"))
        plans = [plan(inst, args.days) for inst in loaded]
        runs = [rehearse(inst, planned=p, progress=lambda line: print(line, file=sys.stderr, flush=True))
                for inst, p in zip(loaded, plans)]
        if len(runs) == 2 and runs[0].title == runs[1].title:  # two versions of one piece: name them by file
            runs = [dataclasses.replace(r, title=f"{r.title} ({c.name})") for r, c in zip(runs, configs)]
        print(report(*runs))
        if args.json is not None:
            text = json.dumps([r.to_dict() for r in runs], indent=1)
            atomic_write(args.json, lambda handle: handle.write(text), "w")
    except (ConfigError, CorpusError, OSError) as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    return 0


@command("offline", "run an installation on recorded input, faster than real time", _offline_options)
def _offline(args: argparse.Namespace) -> int:
    return _run_offline(args.config, args.out, audio=args.audio, midi=args.midi, duration=args.duration,
                        progress=not args.no_progress, frames=args.frames, video=args.video)


def _config_and_state(parser: argparse.ArgumentParser) -> None:
    """The config and ``--state`` that ``run``, ``check`` and ``service`` all take."""
    parser.add_argument("config", type=Path, help="installation config (TOML), or a shipped installation's name")
    parser.add_argument("--state", type=Path, help="directory for saved creature state (overrides the config)")


def _run_options(parser: argparse.ArgumentParser) -> None:
    _config_and_state(parser)
    parser.add_argument("--log", type=Path, help="write the events log (JSONL) here")
    parser.add_argument("--duration", type=_seconds(LONGEST_SECONDS),
                        help="stop after this many seconds (default: run until Ctrl-C)")
    parser.add_argument("--frames", type=Path, help="draw the bodies into this directory (PNGs; a video if the config asks)")
    parser.add_argument("--out", type=Path, help="write the run's out.mid here when it stops (published all or none, "
                                                 "as `creatures offline` does; [output] midi = false turns it off)")
    parser.add_argument("--view", type=_port, nargs="?", const=0, metavar="PORT",
                        help=f"serve the live view on http://127.0.0.1:PORT/ (default: [view] port, else "
                             f"{DEFAULT_VIEW_PORT}); docs/view.md")
    parser.add_argument("--supervise", action="store_true",
                        help="restart the run when it crashes, resuming its saved state (docs/unattended.md)")


DEFAULT_VIEW_PORT = 8765
"""Where ``--view`` without a port serves when the config names none."""


def _integer(low: int, high: int, what: str) -> Callable[[str], int]:
    """An argparse ``type``: an integer in ``low…high``; anything else is argparse's usage error."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = low - 1
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what} in {low}…{high}")
        return value

    return parse


_port = _integer(1024, 65535, "a port")


def _view_port(given: int | None, configured: int | None) -> int | None:
    """The live view's port: ``--view PORT``, else with a bare ``--view`` (0) the config's or
    :data:`DEFAULT_VIEW_PORT`; without ``--view`` the config's (None: no view)."""
    if given is None:
        return configured
    return given or configured or DEFAULT_VIEW_PORT


def _supervised(args: argparse.Namespace) -> list[str]:
    """The options ``run --supervise`` gives each child it starts: every one given but
    ``--supervise`` itself. Only four were passed on (the state, log, duration and frames): a
    supervised run given ``--out`` wrote no ``out.mid`` and one given ``--view`` served no view,
    both without a word."""
    options = []
    for key, value in vars(args).items():
        if key in ("command", "run", "config", "supervise") or value is None or value is False:
            continue
        if value is True or (key == "view" and value == 0):  # a flag; a bare --view: the config's port
            options.append(f"--{key.replace('_', '-')}")
        else:
            options.append(f"--{key.replace('_', '-')}={value}")
    return options


NO_STATE = ("no state directory: learned state will not be kept (nothing is saved or restored); "
            "use --state DIR or `state = \"DIR\"` in the config")


@command("run", "run an installation live with its configured devices (Ctrl-C stops cleanly)", _run_options)
def _run(args: argparse.Namespace) -> int:
    from creatures import log_limit
    from creatures.config import ConfigError
    from creatures.lock import hold
    from creatures.paths import directory
    from creatures.persist import StateFileError
    from creatures.runtime.live import check_before_running, run_live
    from creatures.runtime.ticking import LATE_TICK
    from midi.sinks import LATE_NOTE
    from creatures.runtime.keeper import AFRESH
    from creatures.runtime.network import describe
    from creatures.runtime.schema import load_installation

    if args.supervise:
        from creatures.runtime.keeper import supervise

        return supervise([sys.executable, "-m", "creatures.cli", "run", str(args.config), *_supervised(args)])
    try:
        installation = load_installation(_config_path(args.config))
        state = args.state or installation.resolve(installation.settings.state, ("state",))
        if state is None:
            print(f"note: {NO_STATE}")
        view = _view_port(args.view, installation.settings.view.port)
        check_before_running(installation, state=state, log_path=args.log, pictures=args.frames,  # before a folder is made
                             view=view)
        lock = hold(directory(state, "--state"), "state folder", print) if state is not None else None
        try:  # the state folder is this run's until it ends (creatures/lock.py)
            summary = run_live(installation, duration=args.duration, state=state, log_path=args.log,
                               pictures=args.frames, out=args.out, view=view)
        finally:
            if lock is not None:
                lock.release()
    except (ConfigError, StateFileError, OSError) as exc:  # OSError: a path that is not a file, a locked folder
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    restored = f", restored {', '.join(summary.restored)}" if summary.restored else ""
    network = f"; {describe(summary.network)}" if summary.network is not None else ""
    sounds = f", {summary.sounds_made} sounds sung or words read" if summary.sounds_made else ""
    print(f"stopped after {summary.seconds:.1f} s: {summary.ticks} ticks, {summary.notes_played} notes{sounds}, "
          f"{summary.late} late{restored}; sound {summary.sound}; {summary.audio_gaps} audio gaps put in and "
          f"{summary.audio_skips} skips to keep its lead, {summary.underruns} audio underruns, {summary.overruns} input overruns{network}"
          + (f"; {summary.midi_dropped} MIDI messages dropped (no output port)" if summary.midi_dropped is not None else "")
          + (f"; view: {summary.view_dropped} snapshots dropped (its thread too slow)" if summary.view_dropped else ""))
    if summary.room_share is not None:
        r = summary.room_share
        print(f"shared room: {r['remote']} creatures of {r['owners']} other processes at the end; {r['received']} "
              f"datagrams taken, {sum(r['dropped'].values())} dropped {r['dropped'] or ''}, {r['sent']} sent "
              f"({r['send_errors']} failed)")
    if summary.inputs:
        print("outside input: " + ", ".join(f"{summary.inputs.get(what, 0)} {what}"
                                            for what in ("mapped", "unmapped", "malformed", "throttled", "refused osc"))
              + (f", {junk} refused midi bytes" if (junk := summary.inputs.get("refused midi bytes")) else "")
              + (f"; the MIDI input's queue was full at {full} polls: messages may have been lost"
                 if (full := summary.inputs.get("full midi queue")) else ""))
    print(f"timing: ticks began at most {summary.worst_lateness * 1e3:.1f} ms late (p99 "
          f"{summary.lateness_p99 * 1e3:.2f} ms), {summary.late} more than {LATE_TICK * 1e3:g} ms late, "
          f"{summary.skipped} skips ahead; {summary.late_notes} notes reached the MIDI port more than "
          f"{LATE_NOTE * 1e3:g} ms late" + (f"; {summary.frames_dropped} frames dropped (drawing too slow)"
                                            if summary.frames_dropped else "")
          + (f"; {summary.frames_skipped} frames skipped over clock gaps (the machine suspended or the loop "
             "stalled: the pictures went on from the time it came back)" if summary.frames_skipped else ""))
    for what, counts in summary.outlets.items():  # the body stream's and the console's counters
        said = ", ".join(f"{n} {name.replace('_', ' ')}" for name, n in counts.items())
        print(f"{what}: {said or 'no requests'}")  # the stream always counts: only a console no one asked is empty
    for line in log_limit.install().pending():
        print(line, file=sys.stderr)
    if summary.log_loss:
        print(f"note: {summary.log_loss}")
    if summary.unsaved:
        print(f"creatures: {summary.unsaved}", file=sys.stderr)
        return 1
    if summary.afresh:
        print(f"creatures: stopped to be started afresh, exit status {AFRESH} ({summary.afresh}): --supervise "
              "or systemd starts it again, and the new process opens the device when it is back", file=sys.stderr)
        return AFRESH
    return 0


def _check_options(parser: argparse.ArgumentParser) -> None:
    _config_and_state(parser)


@command("check", "pre-flight of a live run: ports, devices, disk, state folder, GL, a tick's cost", _check_options)
def _check(args: argparse.Namespace) -> int:
    from creatures.config import ConfigError
    from creatures.runtime.preflight import check, table
    from creatures.runtime.schema import load_installation

    try:
        installation = load_installation(_config_path(args.config))
    except ConfigError as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    for note in installation.notes:
        print(f"note: {note}")
    rows = check(installation, args.state or installation.resolve(installation.settings.state, ("state",)))
    print(table(rows))
    failed = [what for what, ok, _ in rows if not ok]
    if failed:
        print(f"creatures: not ready: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


def _service_options(parser: argparse.ArgumentParser) -> None:
    _config_and_state(parser)
    parser.add_argument("--watchdog", type=_seconds(3600.0), default=30.0,
                        help="seconds without a tick before systemd restarts the run (default 30)")
    parser.add_argument("--out", type=Path, help="write the unit here (default: print it)")


@command("service", "write a systemd unit for an installation (restart on failure, watchdog)", _service_options)
def _service(args: argparse.Namespace) -> int:
    from creatures.config import ConfigError
    from creatures.runtime.keeper import unit, write_unit
    from creatures.runtime.schema import load_installation

    try:
        config = _config_path(args.config)
        load_installation(config)  # a unit for a config that does not load would only crash-loop
        text = unit(config, args.state, watchdog=args.watchdog)
        if args.out is None:
            sys.stdout.write(text)
        else:
            write_unit(args.out, text)  # atomic, and never over a file it did not write
            print(f"wrote {args.out}; install: systemctl --user link {args.out.resolve()} && "
                  f"systemctl --user enable --now {args.out.name}")
    except (ConfigError, OSError) as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    return 0


def _inspect_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("path", type=Path, help="an offline output directory (events.jsonl) and/or a state directory")
    parser.add_argument("--out", type=Path, help="where to write the plots and index.html (default: PATH/inspect)")


@command("inspect", "show what the creatures learned: plots and one self-contained HTML page", _inspect_options)
def _inspect(args: argparse.Namespace) -> int:
    from creatures.runtime.inspect import InspectError, inspect

    skipped: list[str] = []
    try:
        page = inspect(args.path, args.out or args.path / "inspect", skipped)
    except (InspectError, ValueError, OSError) as exc:  # ValueError: a malformed events line
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    for why in skipped:
        print(f"note: skipped {why}")
    print(f"open {page}")
    return 0


def _view_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", type=Path, metavar="RUN", help="a run's output directory (its events.jsonl) or events log "
                        "(a live run's --log)")
    parser.add_argument("--port", type=_port, default=DEFAULT_VIEW_PORT, help="serve on http://127.0.0.1:PORT/")
    parser.add_argument("--speed", type=_seconds(1000.0, "a speed"), default=1.0, help="replay speed (× real time)")


@command("view", "replay a run's bodies, notes and drives in the browser (Ctrl-C stops)", _view_options)
def _view(args: argparse.Namespace) -> int:
    import time

    from creatures.view.rerender import learned, load_replay
    from creatures.view.server import ReplaySource, ViewServer, port_problem

    if (problem := port_problem(args.port)) is not None:  # said as a run's --view says it
        print(f"creatures: {problem.replace('--view PORT', '--port PORT')}", file=sys.stderr)
        return 2
    try:
        source = ReplaySource(load_replay(args.run_dir), speed=args.speed, learned=learned(args.run_dir))
        server = ViewServer(source, args.port).start()
    except (ValueError, OSError) as exc:  # ValueError: no poses, a malformed log line
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    print(f"view: open {server.url} (Ctrl-C stops)", flush=True)
    try:
        while True:
            time.sleep(1.0)
    finally:
        server.close()


def _render_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", type=Path, metavar="RUN", help="a run's output directory (its events.jsonl) or events log "
                        "(a live run's --log)")
    parser.add_argument("--out", type=Path, help="where frames/ and out.mp4 go (default: RUN/render)")
    parser.add_argument("--width", type=_integer(16, 3840, "a width"), default=640, help="pixels (16…3840)")
    parser.add_argument("--height", type=_integer(16, 2160, "a height"), default=480, help="pixels (16…2160)")
    parser.add_argument("--fps", type=_seconds(120.0, "a frame rate"),
                        help="frames a second (default: the rate the poses were logged at)")
    parser.add_argument("--camera", help="YAW,PITCH,DISTANCE[,X,Y,Z]: an orbit around a target, degrees and "
                                         "metres (default: framed on the first frame, as the view frames it)")
    parser.add_argument("--video", action="store_true", help="also encode out.mp4")
    parser.add_argument("--no-pngs", action="store_true", help="no PNG frames (with --video: the video only)")
    parser.add_argument("--lines", choices=("svg", "ps"), help="draw the bodies as line drawings instead, one SVG "
                                                               "or EPS file a frame in OUT/lines/ (no GL needed)")


@command("render", "draw a finished offline run's bodies again, at any size and camera", _render_options)
def _render(args: argparse.Namespace) -> int:
    import time

    from creatures.body.render import RenderUnavailable
    from creatures.view.rerender import parse_orbit, render_run

    out = args.out or (args.run_dir if args.run_dir.is_dir() else args.run_dir.parent) / "render"
    if args.lines:
        return _render_lines(args, out)
    try:
        camera = parse_orbit(args.camera) if args.camera is not None else None
        if args.no_pngs and not args.video:
            raise ValueError("--no-pngs without --video would draw nothing")
        t0 = time.perf_counter()
        count = render_run(args.run_dir, out, width=args.width, height=args.height, fps=args.fps, camera=camera,
                           pngs=not args.no_pngs, video=args.video)
    except (ValueError, OSError, RenderUnavailable) as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - t0
    print(f"rendered {count} frames at {args.width}×{args.height} in {wall:.2f} s ({count / wall:.0f} frames/s) into {out}")
    return 0


def _images_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", type=Path, metavar="RUN", help="an offline run of ozymandias (its <creature>.edl.json); "
                                                                  "the video lasts to the end of its last entry")
    parser.add_argument("--creature", required=True, help="whose edit decision list walks the footage")
    parser.add_argument("--footage", default="cube", help='"cube", a directory of PNG frames (e.g. a run\'s '
                                                         'frames/) or a video file (default: cube)')
    parser.add_argument("--fps", type=_seconds(120.0, "a frame rate"), default=25.0,
                        help="frames a second of the footage and the video (default 25)")
    parser.add_argument("--out", type=Path, help="where <creature>.mp4 and .images.json go (default: RUN/images)")
    parser.add_argument("--png", action="store_true", help="also write the frames as PNGs")


@command("images", "make ozymandias's video again from a creature's EDL, with any footage (thesis: "
         "off-line image processing)", _images_options)
def _images(args: argparse.Namespace) -> int:
    from creatures.image.spec import ImagesSpec, make_video
    from creatures.kinds.ozymandias import read_edl
    from creatures.persist import StateFileError
    from creatures.runtime.outputs import publishing

    out = args.out or args.run_dir / "images"
    name = args.creature
    try:
        edl = read_edl(_edl_of(args.run_dir, args.creature))
        spec = ImagesSpec(footage=args.footage, fps=args.fps, png=args.png)
        problem = spec.resolve(Path.cwd())
        if problem is not None:
            raise ValueError(problem)
        rate = edl["sample_rate"]
        last = max((e["output_frame"] + e["source_end_frame"] - e["source_start_frame"] for e in edl["entries"]),
                   default=0)
        # made aside and published whole: stopped with --png, the frames were drawn over the last ones
        with publishing(out, {f"{name}.mp4", f"{name}.images.json", f"{name}.frames"}) as staged:
            files = make_video(spec, name, edl["entries"], rate, last / rate if rate else 0.0, staged)
    except (ValueError, OSError, StateFileError) as exc:  # FootageError is a ValueError
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    for what, path in files.items():
        print(f"  {what:<20} {out / path.relative_to(staged)}")
    return 0


def _edl_of(run_dir: Path, creature: str) -> Path:
    """``RUN/<creature>.edl.json``; ValueError naming the nearest creature with one (a typo said
    only "state file not found")."""
    from creatures.config import nearest

    path = run_dir / f"{creature}.edl.json"
    if not path.is_file():
        names = sorted(p.name.removesuffix(".edl.json") for p in run_dir.glob("*.edl.json"))
        raise ValueError(f"{run_dir}: no edit decision list of creature {creature!r} ({path.name})"
                         f"{nearest(creature, names, 'creatures with one')}")
    return path


def _render_lines(args: argparse.Namespace, out: Path) -> int:
    """``creatures render --lines``: the line renderer (creatures/body/lines.py)."""
    from creatures.body.lines import render_lines
    from creatures.view.rerender import parse_orbit

    try:
        orbit = parse_orbit(args.camera) if args.camera is not None else None
        if args.video:
            raise ValueError("--lines draws SVG or EPS files, not a video")
        count = render_lines(args.run_dir, out, fmt=args.lines, width=args.width, height=args.height, fps=args.fps,
                             yaw=orbit.yaw if orbit else 0.0, pitch=orbit.pitch if orbit else 0.0)
    except (ValueError, OSError) as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    print(f"drew {count} line frames ({args.lines}) at {args.width}×{args.height} into {out / 'lines'}")
    return 0


def _export_motion_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("path", type=Path, help="a run's output directory or a state directory (with events.jsonl), "
                                               "or an events log (a live run's --log)")
    parser.add_argument("out", type=Path, help="the BVH file to write (one that exists and is not a BVH "
                                               "is refused, kept as it was)")
    parser.add_argument("--creature", required=True, help="whose path to export")
    parser.add_argument("--config", type=Path, help="the installation (default: the one the run's log names)")
    parser.add_argument("--fps", type=float, default=30.0, help="frames per second of the BVH, 1..1000 (default 30)")


@command("export-motion", "write the path a creature's body took as BVH (loads back as an animation)",
         _export_motion_options)
def _export_motion(args: argparse.Namespace) -> int:
    from creatures.config import ConfigError
    from creatures.motor.export import ExportError
    from creatures.runtime.motion_export import export_motion_of_run

    if not 1.0 <= args.fps <= 1000.0:  # also refuses nan
        print(f"creatures: --fps {args.fps:g} is not a frame rate in 1..1000", file=sys.stderr)
        return 2
    try:
        frames = export_motion_of_run(args.path, args.creature, args.out, config=args.config, fps=args.fps)
    except (ConfigError, ExportError, ValueError, OSError) as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    print(f"{args.creature}: {frames} frames at {args.fps:g} fps written to {args.out}")
    return 0


def _state_options(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    d = sub.add_parser("diff", help="what each creature learned between two state folders or snapshots")
    d.add_argument("before", type=Path)
    d.add_argument("after", type=Path)
    r = sub.add_parser("rollback", help="put one creature's state back as a snapshot holds it, byte for byte")
    r.add_argument("state", type=Path, help="the state folder")
    r.add_argument("snapshot", type=Path, help="a snapshot folder, or its name in STATE/snapshots")
    r.add_argument("--creature", required=True)
    m = sub.add_parser("merge", help="add what one creature learned to another's repertoire (same kind)")
    m.add_argument("source", type=Path, help="state folder or snapshot to take from")
    m.add_argument("--creature", required=True, help="the creature of SOURCE")
    m.add_argument("target", type=Path, help="state folder to merge into")
    m.add_argument("--into", required=True, help="the creature of TARGET")
    s = sub.add_parser("snapshots", help="list the dated snapshots of a state folder")
    s.add_argument("state", type=Path)


@command("state", "learned state over a long life: diff, rollback, merge, snapshots (docs/unattended.md)",
         _state_options)
def _state(args: argparse.Namespace) -> int:
    from creatures.persist import StateFileError
    from creatures.runtime import repertoire, snapshots

    try:
        if args.action == "diff":
            changes = repertoire.diff(args.before, args.after)
            for change in changes:
                print(change)
            print(f"{len(changes)} change(s)")
        elif args.action == "rollback":
            snapshot = snapshots.find(args.state, args.snapshot)
            print(f"restored {repertoire.rollback(args.state, snapshot, args.creature)} from {snapshot}")
        elif args.action == "merge":
            added = repertoire.merge(args.source, args.creature, args.target, args.into)
            print(f"{args.into}: added {', '.join(added) if added else 'nothing (it knew all of it)'}")
            left = repertoire.not_carried(args.source, args.creature)
            if left:
                print(f"note: not carried: {', '.join(left)} ({args.into} keeps its own)")
        else:
            if not args.state.is_dir():
                raise StateFileError(f"{args.state}: no such state folder")
            found = snapshots.listed(args.state)
            for when, path in found:
                print(f"{when:%Y-%m-%d %H:%M:%S} UTC  {path}")
            if not found:
                print(f"{args.state}: no snapshots yet (a live run with [snapshots] every = N takes them)")
    except (StateFileError, OSError) as exc:  # OSError: a folder a run holds (creatures/lock.py)
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    return 0


def _aural_model_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("out", type=Path, help="the aural model to write (.json, and its .npz beside it)")
    parser.add_argument("sounds", type=Path, nargs="+", help="sound files, one sample each, in memory order")
    parser.add_argument("--rate", type=int, default=22050, choices=(16000, 22050, 44100, 48000),
                        help="sample rate of the creatures that will hear and sing them (their [audio] sample_rate)")
    parser.add_argument("--top-db", type=_bounded(0.0, 120.0), default=40.0,
                        help="trim each file's leading and trailing sound quieter than its peak by this (dB, "
                             "0–120; 0: keep all)")
    parser.add_argument("--force", action="store_true", help="replace OUT if it exists")


@command("aural-model", "make an aural model from sound files: pre-selected samples to seed a creature's memory "
                        "or to flush it by a score (seed_model, [[creature.score]])", _aural_model_options)
def _aural_model(args: argparse.Namespace) -> int:
    from librosa.effects import trim

    import numpy as np

    from audio.sources import AudioFileError, load_audio
    from audio.utterance import aural_model_of, save_aural_model

    refused = (f"{args.out}: an aural model is written as a .json file (and its .npz)" if args.out.suffix != ".json"
               else f"{args.out.parent}: no such folder" if not args.out.parent.is_dir()
               else f"{args.out} exists: give --force to replace it" if args.out.exists() and not args.force
               else None)
    if refused:
        print(f"creatures: {refused}", file=sys.stderr)
        return 2
    try:
        sounds = [load_audio(path, samplerate=args.rate, say=lambda m: print(f"creatures: {m}", file=sys.stderr))
                  for path in args.sounds]
        if args.top_db > 0:
            sounds = [trim(sound, top_db=args.top_db)[0] for sound in sounds]
        silent = [str(path) for path, sound in zip(args.sounds, sounds) if not np.any(sound)]
        if silent:
            raise AudioFileError(f"{', '.join(silent)}: silent: nothing to remember")
        save_aural_model(aural_model_of(sounds, args.rate), args.out)
    except (AudioFileError, OSError) as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    print(f"{args.out}: {len(sounds)} samples, {sum(map(len, sounds)) / args.rate:.2f} s")
    return 0


@command("config-docs", "print the reference of every config key (docs/config.md)", lambda parser: None)
def _config_docs(_: argparse.Namespace) -> int:
    from creatures.runtime.docs import config_reference

    sys.stdout.write(config_reference())
    return 0


def _describe_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", type=Path, help="installation config (TOML), or a shipped installation's name")


@command("describe", "print each creature's drives, percept trees, groups, tuples and (in a room) steering as a tree", _describe_options)
def _describe(args: argparse.Namespace) -> int:
    from creatures.authored.describe import describe
    from creatures.config import ConfigError
    from creatures.runtime.schema import load_installation

    try:
        sys.stdout.write(describe(load_installation(_config_path(args.config))))
    except ConfigError as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    return 0


def _new_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", help="the installation's (and its creature's) name")
    parser.add_argument("--dir", type=Path, default=Path("."), help="where to write NAME.toml")


@command("new", "write a commented starting installation with one authored creature", _new_options)
def _new(args: argparse.Namespace) -> int:
    from creatures.authored.scaffold import new_installation

    try:
        path = new_installation(args.name, args.dir)
    except (ValueError, OSError) as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {path}; run it with: creatures offline {path} --out {args.name}-out")
    return 0


def _demo_options(parser: argparse.ArgumentParser) -> None:
    import installations

    parser.add_argument("name", nargs="?", default="exchange", help=f"one of {installations.names()}")
    parser.add_argument("--out", type=Path, default=Path("creatures-demo"), help="output directory")
    parser.add_argument("--duration", type=_seconds(LONGEST_OFFLINE),
                        help="simulated seconds (default: the piece's own, its config's duration)")


@command("demo", "run a shipped installation offline on generated input (no hardware needed)", _demo_options)
def _demo(args: argparse.Namespace) -> int:
    """A piece runs as long as it was composed (its config's ``duration``) unless ``--duration``
    says otherwise: one 30 s default for every piece (until 2026-12-07) showed Duncan four cues
    and no learning, and cut void's 180 s and cadence's 120 s short."""
    import installations

    try:
        config = installations.path(args.name)
    except FileNotFoundError as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    code = _run_offline(config, args.out, duration=args.duration, frames=True, video=True)
    report = args.out / "report" / "index.html"
    if code == 0 and report.exists():  # an installation may write none (`[output] report = false`)
        print(f"open {report} to see what the creatures did")
    return code


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="creatures", description="Autonomous musical creatures.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (help_text, configure, fn) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        configure(p)
        p.set_defaults(run=fn)
    return parser


COMPILING = {"offline", "demo", "run", "rehearse", "inspect", "render", "images", "view"}
"""Commands that run creatures (or draw them) and so compile numba's kernels on a first run."""


PRINTING = {"version", "devices", "config-docs", "describe", "state"}
"""Commands that only print: a reader that stops reading (``| head``) ends them silently. Not
the shows, whose sockets must never end a run by a signal."""


STOPPED = {
    "rehearse": "no report was printed",
    "offline": "nothing was published; the output directory holds the previous run's outputs as they were",
    "demo": "nothing was published; the output directory holds the previous run's outputs as they were",
    "run": "stopped before the run began or as it ended; the state folder holds the last state saved",
    "inspect": "the page was not written",
    "view": "the view was closed",
    "render": "nothing was replaced; the output directory holds the previous render as it was",
    "export-motion": "the BVH file was not written (or is the previous one)",
    "images": "nothing was replaced; the output directory holds the previous video and images as they were",
}
"""What a command stopped by Ctrl-C, SIGTERM or SIGHUP outside its own handling left behind."""


def main(argv: list[str] | None = None) -> int:
    from creatures import stop

    args = build_parser().parse_args(argv)
    piped = args.command in PRINTING and hasattr(signal, "SIGPIPE")
    if piped:  # `creatures state diff … | head` ends quietly, as cat does
        sigpipe = signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    restore = stop.install()
    unsay: Callable[[], None] = lambda: None  # noqa: E731
    try:
        import scipy.linalg  # noqa: F401 - loads numpy's and scipy's BLAS, so the limit below reaches them
        from threadpoolctl import threadpool_limits

        # Creatures do many tiny matrix operations; multi-threaded BLAS only fights over the
        # cores for them (measured: scipy's expm on 5x5 went from 15 us to 2 ms under load).
        # The limit reaches only libraries already loaded: until scipy.linalg was imported
        # here it reached none, and four live processes of a shared room on 2 cores spent
        # 68 ms per 2x2 expm in BLAS threads fighting each other (ticks 30 s late).
        threadpool_limits(limits=1)
        from creatures import log_limit
        from midi import alsa

        log_limit.install().reset()  # a library that logs per bad packet must not flood stderr; counts per command
        alsa.quiet()  # libasound's own stderr lines: the errors they precede are reported once, in words
        if args.command in COMPILING:  # a first run's long start, said (on a terminal)
            from creatures.runtime.first_compile import say_first_compile

            unsay = say_first_compile()
        return int(args.run(args))
    except KeyboardInterrupt as stopped:  # creatures/stop.py: SIGTERM and SIGHUP are raised as Ctrl-C is
        signum = stopped.signum if isinstance(stopped, stop.Terminated) else signal.SIGINT
        left = STOPPED.get(args.command)
        how = stop.named(signum)
        print(f"creatures {args.command}: stopped by {how}" + (f"; {left}" if left else ""), file=sys.stderr)
        return 128 + signum
    finally:
        unsay()
        restore()
        if piped:
            signal.signal(signal.SIGPIPE, sigpipe)


if __name__ == "__main__":
    sys.exit(main())
