"""``plugins = ["my_actions.py"]``: Python files next to a config that register parts
(:mod:`creatures.authored.registry`). Imported before the creatures are validated, so their
names resolve like the built-in ones; one that fails is a :class:`ConfigError` at its line.
"""

from __future__ import annotations

from pathlib import Path

from creatures.authored.registry import PluginError, load_plugin_file
from creatures.config import config_error, nearest_file


def load_plugins(files: list[str], config: Path, where: dict) -> None:
    for k, name in enumerate(files):
        try:
            load_plugin_file(config.parent / name)
        except PluginError as exc:
            missing = not (config.parent / name).is_file()  # a typo: offer the nearest file there
            raise config_error(config, where, ("plugins", k),
                               str(exc) + (nearest_file(name, config.parent) if missing else "")) from None
