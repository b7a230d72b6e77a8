"""``plugins = ["my_actions.py"]``: Python files next to a config that register parts
(:mod:`creatures.authored.registry`), relative to the file that names them (an ``extends``
base in another folder names its own). Imported before the creatures are validated, so their
names resolve like the built-in ones; one that fails is a :class:`ConfigError` at its line.
"""

from __future__ import annotations

from pathlib import Path

from creatures.authored.registry import PluginError, load_plugin_file
from creatures.config import config_error, nearest_file, written_in


def load_plugins(files: list[str], config: Path, where: dict) -> None:
    folder = written_in(where, ("plugins",), config).parent
    for k, name in enumerate(files):
        try:
            load_plugin_file(folder / name)
        except PluginError as exc:
            missing = not (folder / name).is_file()  # a typo: offer the nearest file there
            raise config_error(config, where, ("plugins", k),
                               str(exc) + (nearest_file(name, folder) if missing else "")) from None
