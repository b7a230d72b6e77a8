"""The ``creatures`` command. Subcommands are small functions registered in ``COMMANDS``."""

from __future__ import annotations

import argparse
import sys
from typing import Callable

COMMANDS: dict[str, tuple[str, Callable[[argparse.ArgumentParser], None], Callable[[argparse.Namespace], int]]] = {}


def command(name: str, help_text: str, configure: Callable[[argparse.ArgumentParser], None]):
    """Register ``fn(args) -> exit code`` as ``creatures NAME``."""

    def register(fn: Callable[[argparse.Namespace], int]):
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
    return int(args.run(args))


if __name__ == "__main__":
    sys.exit(main())
