"""The loader's edges for an artist's own files: ``include`` and ``plugins`` written in an
``extends`` base, deep chains of files, and what a bad file says (docs/authoring.md: every
problem is an error naming the file, the key and the line, before anything runs)."""

from __future__ import annotations

import pytest

from creatures.authored import registry
from creatures.config import MAX_CONFIG_CHAIN, ConfigError
from creatures.runtime.schema import load_installation
from tests.test_authored import CREATURE, HEAD, line_of, write

# Parts a test's plugin registers leave with it (tests/conftest.py).
pytestmark = pytest.mark.usefixtures("own_registry")

CROAK = '''
from creatures.authored.actions import ActionPart, Playing
from creatures.authored.registry import ACTIONS
from midi.notes import NoteEvent


@ACTIONS.register
class Croak(ActionPart):
    """A croak from a plugin next to a shared base config."""

    name = "croak_of_the_base"
    ends = True

    def build(self, params, creature, name):
        return Playing(name, creature, lambda t: [NoteEvent(0.0, 36, 100, 0, 0.2)])
'''


def test_a_base_in_another_folder_includes_and_imports_from_its_own_folder(tmp_path):
    """A shared base (``extends = "../shared/base.toml"``) naming ``include`` and ``plugins``
    beside itself: they were looked for beside the extending file, and the base could not be
    shared at all."""
    write(tmp_path, CREATURE, "shared/heron.toml")
    write(tmp_path, CROAK, "shared/croak.py")
    write(tmp_path, HEAD + 'include = ["heron.toml"]\nplugins = ["croak.py"]\n', "shared/base.toml")
    inst = load_installation(write(tmp_path, 'extends = "../shared/base.toml"\n', "rooms/inst.toml"))
    assert [s.name for s in inst.specs] == ["c"]
    assert "croak_of_the_base" in registry.ACTIONS


def _naming(key: str, file: str) -> str:
    """The line of a config that names ``file`` with ``key``."""
    return f'include = ["{file}"]\n' if key == "include" else f'extends = "{file}"\n'


def _chain(tmp_path, key: str, links: int):
    """``KEY.toml`` and ``links`` files after it, each naming the next with ``key``; the last
    holds the creature (and, for ``extends``, the installation's keys)."""
    write(tmp_path, CREATURE if key == "include" else HEAD + CREATURE, f"{key}/{links - 1}.toml")
    for i in range(links - 1):
        write(tmp_path, _naming(key, f"{i + 1}.toml"), f"{key}/{i}.toml")
    return write(tmp_path, (HEAD if key == "include" else "") + _naming(key, f"{key}/0.toml"), f"{key}.toml")


@pytest.mark.parametrize("key", ["include", "extends"])
def test_a_chain_of_files_ends_at_a_limit_named_at_its_line(tmp_path, key):
    """A thousand files each naming the next (a generator's slip) ran out of stack: a
    traceback for ``extends``, and for ``include`` an error blaming nesting in a file that
    nests nothing."""
    assert [s.name for s in load_installation(_chain(tmp_path / "ok", key, MAX_CONFIG_CHAIN - 1)).specs] == ["c"]
    for links in (MAX_CONFIG_CHAIN, 1000):
        with pytest.raises(ConfigError) as info:
            load_installation(_chain(tmp_path / str(links), key, links))
        error = info.value
        assert f"more than {MAX_CONFIG_CHAIN}" in error.message and error.line == 1
        assert error.file.name == f"{MAX_CONFIG_CHAIN - 2}.toml" and error.key.startswith(key)


def test_too_many_creatures_is_said_at_the_first_one_too_many_without_quoting_them_all(tmp_path):
    """300 generated creatures: the error quoted every table (half a megabyte of one line),
    with no line; it names the 257th at its line, and a value repeated back stays short."""
    path = write(tmp_path, HEAD + "".join(CREATURE.replace('name = "c"', f'name = "c{i}"') for i in range(300)))
    with pytest.raises(ConfigError) as info:
        load_installation(path)
    error = info.value
    assert error.key == "creature.256" and "at most 256" in error.message and "not 300" in error.message
    assert error.line == line_of(path, 'name = "c256"') - 1 and len(str(error)) < 300
    long_name = write(tmp_path, HEAD + CREATURE.replace('name = "c"', f'name = {["x" * 50] * 40}'), "long.toml")
    with pytest.raises(ConfigError) as info:
        load_installation(long_name)
    assert info.value.key == "creature.0.name" and len(str(info.value)) < 300 and info.value.message.endswith("…)")


CLASH = '''
from creatures.authored.actions import ActionPart
from creatures.authored.registry import ACTIONS
from creatures.kinds import register
from creatures.kinds.base import CreatureKind


{decorator}
class Mine({base}):
    """A part named as a built-in one."""

    name = "echo"
'''


@pytest.mark.parametrize("decorator, base, taken", [("@ACTIONS.register", "ActionPart", "action name 'echo'"),
                                                     ('@register("authored")', "CreatureKind",
                                                      "creature kind name 'authored'")])
def test_a_plugin_part_named_as_a_built_in_one_is_refused_at_its_plugins_line(tmp_path, decorator, base, taken):
    """It silently took the built-in's place for every creature after it (this config's
    ``echo`` tuple then failed on a key the plugin's part lacked)."""
    write(tmp_path, CLASH.format(decorator=decorator, base=base), "mine.py")
    path = write(tmp_path, HEAD + 'plugins = ["mine.py"]\n' + CREATURE.replace(
        'action = "rest"', 'action = { type = "echo", count = 2 }'))
    with pytest.raises(ConfigError) as info:
        load_installation(path)
    error = info.value
    assert error.key == "plugins.0" and error.line == 3 and "mine.py" in error.message
    assert taken in error.message and "give this one a name of its own" in error.message
    assert registry.ACTIONS.get("echo").__module__ == "creatures.authored.actions"
    assert [s.name for s in load_installation(write(tmp_path, HEAD + CREATURE, "after.toml")).specs] == ["c"]


def test_a_plugin_that_exits_as_it_imports_is_an_error_at_its_line(tmp_path):
    """A script reused as a plugin, parsing its command line at import: its ``SystemExit``
    ended ``creatures`` with the script's usage line, not a word of the config."""
    write(tmp_path, "import argparse\nargparse.ArgumentParser().parse_args(['--frogs'])\n", "script.py")
    with pytest.raises(ConfigError) as info:
        load_installation(write(tmp_path, HEAD + 'plugins = ["script.py"]\n' + CREATURE))
    assert info.value.key == "plugins.0" and info.value.line == 3 and "SystemExit: 2" in info.value.message


@pytest.mark.parametrize("key", ["include", "plugins"])
def test_a_folder_named_as_a_file_is_said_to_be_a_folder(tmp_path, key):
    """``include = ["creatures"]`` for the folder of creature files: "not found", of a folder
    that is there."""
    (tmp_path / "creatures").mkdir()
    with pytest.raises(ConfigError) as info:
        load_installation(write(tmp_path, HEAD + f'{key} = ["creatures"]\n' + CREATURE))
    error = info.value
    assert error.key == f"{key}.0" and error.line == 3
    assert "'creatures' is a directory, not a regular file" in error.message and "not found" not in error.message


@pytest.mark.parametrize("twice", [False, True])
def test_a_duplicate_creature_name_says_where_the_first_was_written(tmp_path, twice):
    """Two creatures named alike files apart (or one file included twice): the error named
    the second's line only, and the first had to be hunted for through the includes."""
    first = write(tmp_path, CREATURE, "creatures/c.toml")
    second = first if twice else write(tmp_path, CREATURE, "creatures/also_c.toml")
    line = line_of(first, 'name = "c"')
    with pytest.raises(ConfigError) as info:
        load_installation(write(tmp_path, HEAD + f'include = ["creatures/c.toml", "creatures/{second.name}"]\n'))
    error = info.value
    assert error.file == second and error.line == line_of(second, 'name = "c"')
    assert f"duplicate creature name 'c' (the first is at c.toml:{line})" in error.message
