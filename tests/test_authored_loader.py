"""The loader's edges for an artist's own files: ``include`` and ``plugins`` written in an
``extends`` base, deep chains of files, and what a bad file says (docs/authoring.md: every
problem is an error naming the file, the key and the line, before anything runs)."""

from __future__ import annotations

from creatures.authored import registry
from creatures.runtime.schema import load_installation
from tests.test_authored import CREATURE, HEAD, write

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
