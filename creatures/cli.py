"""The ``creatures`` command. Subcommands are small functions registered in ``COMMANDS``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Callable

Configure = Callable[[argparse.ArgumentParser], None]
"""Adds a subcommand's arguments to its parser."""

Run = Callable[[argparse.Namespace], int]
"""Runs a subcommand with its parsed arguments; returns the exit code."""

COMMANDS: dict[str, tuple[str, Configure, Run]] = {}


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
        print("audio devices:" if len(devices) else "audio devices: none found")
        for d in devices:
            print(f"  [{d['index']}] {d['name']} (in {d['max_input_channels']}, out {d['max_output_channels']})")
    except AudioDeviceUnavailable as exc:
        print(f"audio devices: {exc}")
    try:
        import mido

        inputs, outputs = mido.get_input_names(), mido.get_output_names()
        print(f"MIDI inputs ({mido.backend.name}): {inputs or 'none'}")
        print(f"MIDI outputs: {outputs or 'none'}")
    except Exception as exc:  # any backend failure is reported, never fatal here
        print(f"MIDI devices: unavailable ({exc}); on Linux without ALSA start a JACK server and set "
              "MIDO_BACKEND=mido.backends.rtmidi/UNIX_JACK")
    return 0


def _offline_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", type=Path, help="installation config (TOML), or a shipped installation's name")
    parser.add_argument("--audio", type=Path, help="recorded audio to feed (overrides the config)")
    parser.add_argument("--midi", type=Path, help="recorded MIDI to feed (overrides the config)")
    parser.add_argument("--out", type=Path, required=True, help="directory for the outputs")
    parser.add_argument("--duration", type=float, help="simulated seconds (default: the config's)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--frames", action="store_true", help="draw the bodies into DIR/frames (PNGs; needs EGL or OSMesa)")
    parser.add_argument("--video", action="store_true", help="draw the frames and encode them to DIR/out.mp4")


def _config_path(config: Path) -> Path:
    """A config path, or the name of a shipped installation (as ``demo`` takes)."""
    import installations

    if config.exists() or config.suffix == ".toml":
        return config
    try:
        return installations.path(str(config))
    except FileNotFoundError:
        return config  # the loader reports it as a missing config file


def _run_offline(config: Path, out: Path, *, audio: Path | None = None, midi: Path | None = None,
                 duration: float | None = None, progress: bool = True, frames: bool = False,
                 video: bool = False) -> int:
    """``frames``/``video`` turn the config's ``[output]`` keys on (never off)."""
    from audio.sources import AudioFileError
    from creatures.config import ConfigError
    from creatures.runtime.offline import run_offline
    from creatures.runtime.schema import load_installation
    from midi.files import MidiFileError

    try:
        installation = load_installation(_config_path(config))
        output = installation.settings.output
        output.frames = output.frames or frames or video
        output.video = output.video or video
        for given in (audio, midi):
            if given is not None and not given.is_file():
                raise FileNotFoundError(f"{given}: no such file")
        summary = run_offline(installation, out, audio=audio, midi=midi, duration=duration, progress=progress)
    except (ConfigError, AudioFileError, MidiFileError, OSError) as exc:  # OSError: e.g. disk full
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    for message in summary.messages:
        print(f"note: {message}")
    print(f"{installation.settings.title}: {summary.simulated:.1f} simulated s in {summary.wall:.2f} wall s "
          f"({summary.speed:.1f}x real time), {summary.notes_played} notes played")
    for name, file in summary.files.items():
        print(f"  {name:<7} {file}")
    return 0


@command("offline", "run an installation on recorded input, faster than real time", _offline_options)
def _offline(args: argparse.Namespace) -> int:
    return _run_offline(args.config, args.out, audio=args.audio, midi=args.midi, duration=args.duration,
                        progress=not args.no_progress, frames=args.frames, video=args.video)


def _run_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", type=Path, help="installation config (TOML)")
    parser.add_argument("--state", type=Path, help="directory for saved creature state (overrides the config)")
    parser.add_argument("--log", type=Path, help="write the events log (JSONL) here")
    parser.add_argument("--duration", type=float, help="stop after this many seconds (default: run until Ctrl-C)")
    parser.add_argument("--frames", type=Path, help="draw the bodies into this directory (PNGs; a video if the config asks)")


NO_STATE = ("no state directory: learned state will not be kept (nothing is saved or restored); "
            "use --state DIR or `state = \"DIR\"` in the config")


@command("run", "run an installation live with its configured devices (Ctrl-C stops cleanly)", _run_options)
def _run(args: argparse.Namespace) -> int:
    from creatures.config import ConfigError
    from creatures.persist import StateFileError
    from creatures.runtime.live import run_live
    from creatures.runtime.schema import load_installation

    try:
        installation = load_installation(args.config)
        if args.state is None and installation.settings.state is None:
            print(f"note: {NO_STATE}")
        summary = run_live(installation, duration=args.duration, state=args.state, log_path=args.log,
                           pictures=args.frames)
    except (ConfigError, StateFileError) as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    restored = f", restored {', '.join(summary.restored)}" if summary.restored else ""
    print(f"stopped after {summary.seconds:.1f} s: {summary.ticks} ticks, {summary.notes_played} notes, "
          f"{summary.late} late{restored}; sound {summary.sound}; {summary.underruns} audio underruns, "
          f"{summary.overruns} input overruns")
    return 0


def _inspect_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("path", type=Path, help="an offline output directory (events.jsonl) and/or a state directory")
    parser.add_argument("--out", type=Path, help="where to write the plots and index.html (default: PATH/inspect)")


@command("inspect", "show what the creatures learned: plots and one self-contained HTML page", _inspect_options)
def _inspect(args: argparse.Namespace) -> int:
    from creatures.runtime.inspect import InspectError, inspect

    try:
        page = inspect(args.path, args.out or args.path / "inspect")
    except (InspectError, ValueError, OSError) as exc:  # ValueError: a malformed events line
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    print(f"open {page}")
    return 0


@command("config-docs", "print the reference of every config key (docs/config.md)", lambda parser: None)
def _config_docs(_: argparse.Namespace) -> int:
    from creatures.runtime.docs import config_reference

    sys.stdout.write(config_reference())
    return 0


def _describe_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", type=Path, help="installation config (TOML), or a shipped installation's name")


@command("describe", "print each creature's drives, percept trees, groups and tuples as a tree", _describe_options)
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
    parser.add_argument("--duration", type=float, default=30.0, help="simulated seconds")


@command("demo", "run a shipped installation offline on generated input (no hardware needed)", _demo_options)
def _demo(args: argparse.Namespace) -> int:
    import installations

    try:
        config = installations.path(args.name)
    except FileNotFoundError as exc:
        print(f"creatures: {exc}", file=sys.stderr)
        return 2
    code = _run_offline(config, args.out, duration=args.duration, frames=True, video=True)
    if code == 0:
        print(f"open {args.out / 'report' / 'index.html'} to see what the creatures did")
    return code


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="creatures", description="Autonomous musical creatures.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (help_text, configure, fn) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        configure(p)
        p.set_defaults(run=fn)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from threadpoolctl import threadpool_limits

    # Creatures do many tiny matrix operations; multi-threaded BLAS only fights over the
    # cores for them (measured: scipy's expm on 5x5 went from 15 us to 2 ms under load).
    threadpool_limits(limits=1)
    return int(args.run(args))


if __name__ == "__main__":
    sys.exit(main())
