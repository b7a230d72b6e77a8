"""The extension API (issue 15): parts from a user's pip package (entry points) and from a
``plugins`` file next to the config are usable from TOML like the built-in ones, which
register the same way; a plugin that fails is a clear error and exit 2."""

from __future__ import annotations

import base64
import hashlib
import subprocess
import sys
import textwrap
import tomllib
import zipfile
from importlib.metadata import entry_points
from pathlib import Path

import pytest

from creatures.authored import registry
from creatures.cli import main
from creatures.config import ConfigError
from creatures.events import read_events
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation

# Parts a test's plugin registers leave with it (tests/conftest.py).
pytestmark = pytest.mark.usefixtures("own_registry")

ROOT = Path(__file__).resolve().parents[1]

CROAK = '''
"""A third party's action: a low croak."""
from creatures.authored.actions import ActionPart, Playing
from creatures.authored.registry import ACTIONS
from pydantic import BaseModel, Field
from midi.notes import NoteEvent


class CroakParams(BaseModel):
    pitch: int = Field(36, description="how low")


@ACTIONS.register
class Croak(ActionPart):
    """Croak: one low note, twice."""

    name = "{name}"
    thesis = "the action-tuple"
    Params = CroakParams
    ends = True

    def build(self, params, creature, name):
        croaks = [NoteEvent(0.0, params.pitch, 100, 0, 0.2), NoteEvent(0.3, params.pitch, 100, 0, 0.2)]
        return Playing(name, creature, lambda t: croaks)
'''

CONFIG = '''
title = "plugin"
duration = 20.0
{top}

[output]
wav = false
report = false

[[creature]]
name = "frog"
kind = "authored"

[creature.tuples.croak]
action = {{ type = "{name}", pitch = 38 }}
until = {{ done = true }}

[creature.tuples.rest]
action = "rest"
until = {{ seconds = 1.0 }}
value = 0.5

[creature.groups.main]
tuples = ["croak", "rest"]
alpha = 0.0
'''


def _wheel(tmp_path: Path, module: str, source: str, group: str = "actions") -> Path:
    """A minimal pure-Python wheel of ``module`` whose entry point joins creature_music.<group>."""
    dist = f"{module}-0.1.dist-info"
    files = {
        f"{module}.py": source,
        f"{dist}/METADATA": f"Metadata-Version: 2.1\nName: {module}\nVersion: 0.1\n",
        f"{dist}/WHEEL": "Wheel-Version: 1.0\nGenerator: test\nRoot-Is-Purelib: true\nTag: py3-none-any\n",
        f"{dist}/entry_points.txt": f"[creature_music.{group}]\nextras = {module}\n",
    }
    record = []
    for name, text in files.items():
        digest = base64.urlsafe_b64encode(hashlib.sha256(text.encode()).digest()).rstrip(b"=").decode()
        record.append(f"{name},sha256={digest},{len(text.encode())}")
    record.append(f"{dist}/RECORD,,")
    wheel = tmp_path / f"{module}-0.1-py3-none-any.whl"
    with zipfile.ZipFile(wheel, "w") as z:
        for name, text in files.items():
            z.writestr(name, text)
        z.writestr(f"{dist}/RECORD", "\n".join(record) + "\n")
    return wheel


def _croaks(inst, out: Path) -> list[int]:
    run_offline(inst, out, duration=20.0)
    return [e["pitch"] for e in read_events(out / "events.jsonl") if e["kind"] == "note"]


@pytest.mark.slow
def test_an_action_from_an_installed_package_is_usable_from_toml(tmp_path, monkeypatch):
    site = tmp_path / "site"
    wheel = _wheel(tmp_path, "frog_extras", CROAK.replace("{name}", "croak"))
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index",
                    "--target", str(site), str(wheel)], check=True)
    monkeypatch.syspath_prepend(str(site))
    assert "croak" not in registry.ACTIONS
    assert any(ep.value == "frog_extras" for ep in entry_points(group="creature_music.actions"))
    config = tmp_path / "frog.toml"
    config.write_text(CONFIG.format(top="", name="croak"))
    pitches = _croaks(load_installation(config), tmp_path / "out")
    assert pitches[:2] == [38, 38] and len(pitches) >= 6


POND = '''
"""A third party's whole creature kind: a pond that plops once a second."""
from typing import Literal

from creatures.kinds import register
from creatures.kinds.base import CreatureKind, CreatureSpec
from midi.notes import NoteEvent


class PondSpec(CreatureSpec):
    kind: Literal["pond"]
    pitch: int = 40


@register("pond")
class Pond(CreatureKind):
    Spec = PondSpec
    next = 1.0

    def tick(self, t):
        if t >= self.next:
            self.world.play(self, NoteEvent(t, self.spec.pitch, 80, 0, 0.1))
            self.next += 1.0
'''


@pytest.mark.slow
def test_a_whole_kind_from_an_installed_package_is_usable_from_toml(tmp_path, monkeypatch):
    site = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index", "--target",
                    str(site), str(_wheel(tmp_path, "pond_kind", POND, group="kinds"))], check=True)
    monkeypatch.syspath_prepend(str(site))
    config = tmp_path / "pond.toml"
    config.write_text('title = "pond"\n[output]\nwav = false\nreport = false\n'
                      '[[creature]]\nname = "p"\nkind = "pond"\npitch = 43\n')
    inst = load_installation(config)
    run_offline(inst, tmp_path / "out", duration=5.0)
    assert [e["pitch"] for e in read_events(tmp_path / "out" / "events.jsonl") if e["kind"] == "note"] == [43] * 5  # t = 1 … 5 s


@pytest.mark.slow
def test_an_installed_package_whose_entry_point_fails_is_exit_2(tmp_path, monkeypatch, capsys):
    site = tmp_path / "site"
    wheel = _wheel(tmp_path, "toad_extras", "raise RuntimeError('toads are not ready')\n")
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index",
                    "--target", str(site), str(wheel)], check=True)
    monkeypatch.syspath_prepend(str(site))
    config = tmp_path / "frog.toml"
    config.write_text(CONFIG.format(top="", name="rest"))
    assert main(["offline", str(config), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "toad_extras" in err and "toads are not ready" in err and str(config) in err
    assert not (tmp_path / "out").exists()


def test_an_action_from_a_plugins_file_is_usable_from_toml(tmp_path):
    (tmp_path / "my_actions.py").write_text(CROAK.replace("{name}", "ribbit"))
    config = tmp_path / "frog.toml"
    config.write_text(CONFIG.format(top='plugins = ["my_actions.py"]', name="ribbit"))
    pitches = _croaks(load_installation(config), tmp_path / "out")
    assert pitches[:2] == [38, 38] and len(pitches) >= 6


def test_a_plugin_that_fails_to_import_is_exit_2_naming_it(tmp_path, capsys):
    (tmp_path / "broken.py").write_text("import no_such_module_anywhere\n")
    config = tmp_path / "frog.toml"
    config.write_text(CONFIG.format(top='plugins = ["broken.py"]', name="rest"))
    with pytest.raises(ConfigError) as info:
        load_installation(config)
    assert info.value.key == "plugins.0" and info.value.line == 4 and "broken.py" in info.value.message
    assert main(["offline", str(config), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    assert "no_such_module_anywhere" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_mistyped_plugins_file_names_the_nearest_one(tmp_path):
    (tmp_path / "my_actions.py").write_text(CROAK.replace("{name}", "ribbit"))
    config = tmp_path / "frog.toml"
    config.write_text(CONFIG.format(top='plugins = ["my_actons.py"]', name="ribbit"))
    with pytest.raises(ConfigError) as info:
        load_installation(config)
    assert info.value.key == "plugins.0" and "(did you mean 'my_actions.py'?)" in info.value.message


def test_the_builtin_parts_register_through_the_projects_own_entry_points():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"]
    declared = {group.removeprefix("creature_music."): sorted(eps.values()) for group, eps in project.items()
                if group.startswith("creature_music.")}
    assert declared == {group: sorted(modules) for group, modules in registry.BUILTIN.items()}


def test_a_part_without_a_name_is_refused():
    with pytest.raises(registry.PluginError, match="needs a class attribute 'name'"):
        registry.ACTIONS.register(type("Nameless", (registry.Part,), {}))


def test_an_unknown_part_suggests_the_nearest(tmp_path):
    config = tmp_path / "frog.toml"
    config.write_text(textwrap.dedent(CONFIG.format(top="", name="ech")))
    with pytest.raises(ConfigError, match="did you mean 'echo'"):
        load_installation(config)
