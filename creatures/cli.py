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


def _version(_: argparse.ArgumentParser) -> None:
    pass


@command("version", "print the version", _version)
def _print_version(_: argparse.Namespace) -> int:
    from creatures import __version__

    print(f"creature-music {__version__}")
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
