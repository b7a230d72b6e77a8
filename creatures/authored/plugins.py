"""``plugins = ["my_actions.py"]``: Python files next to a config that register parts
(:mod:`creatures.authored.registry`), relative to the file that names them (an ``extends``
base in another folder names its own). Imported before the creatures are validated, so their
names resolve like the built-in ones; one that fails is a :class:`ConfigError` at its line.
"""

from __future__ import annotations

from pathlib import Path

from creatures.authored.registry import PluginError, load_plugin_file
from creatures.config import config_error, not_a_file, written_in


def load_plugins(files: list[str], config: Path, where: dict) -> None:
    folder = written_in(where, ("plugins",), config).parent
    for k, name in enumerate(files):
        if not (folder / name).is_file():  # a typo (offered the nearest file there), or a folder
            raise config_error(config, where, ("plugins", k), f"plugin file {name!r} {not_a_file(name, folder)}")
        try:
            load_plugin_file(folder / name)
        except PluginError as exc:
            raise config_error(config, where, ("plugins", k), str(exc)) from None
