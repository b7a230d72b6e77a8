"""Config errors name the file, key path and line, and suggest the nearest valid key."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from pydantic import BaseModel, ConfigDict

import installations
from creatures.config import ConfigError, key_lines, load_config


class Voice(BaseModel):
    model_config = ConfigDict(extra="forbid")
    stiffness: float = 0.1


class CreatureSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: str
    kind: str
    voice: Voice = Voice()


class Installation(BaseModel):
    model_config = ConfigDict(extra="forbid")
    title: str
    seed: int = 0
    creature: list[CreatureSpec] = []


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_valid_config_loads(tmp_path):
    path = write(tmp_path, "a.toml", 'title = "x"\n[[creature]]\nname = "a"\nkind = "listen"\n')
    config = load_config(path, Installation)
    assert config.creature[0].kind == "listen"


def test_unknown_key_names_line_and_suggests(tmp_path):
    text = 'title = "x"\n\n[[creature]]\nname = "a"\nkind = "listen"\n\n[[creature]]\nname = "b"\nknid = "exchange"\n'
    path = write(tmp_path, "a.toml", text)
    with pytest.raises(ConfigError) as err:
        load_config(path, Installation)
    assert err.value.line == 9
    assert err.value.key == "creature.1.knid"
    assert "did you mean 'kind'" in str(err.value)
    assert str(path.resolve()) in str(err.value)


def test_wrong_type_in_nested_table(tmp_path):
    text = 'title = "x"\n[[creature]]\nname = "a"\nkind = "k"\n[creature.voice]\nstiffness = "stiff"\n'
    path = write(tmp_path, "a.toml", text)
    with pytest.raises(ConfigError) as err:
        load_config(path, Installation)
    assert err.value.key == "creature.0.voice.stiffness"
    assert err.value.line == 6
    assert "'stiff'" in str(err.value)


def test_missing_key_and_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="title: Field required"):
        load_config(write(tmp_path, "a.toml", "seed = 3\n"), Installation)
    with pytest.raises(ConfigError, match="config file not found"):
        load_config(tmp_path / "absent.toml", Installation)


def test_invalid_toml_reports_line(tmp_path):
    with pytest.raises(ConfigError) as err:
        load_config(write(tmp_path, "a.toml", 'title = "x"\nseed = = 3\n'), Installation)
    assert err.value.line == 2


def test_extends_merges_and_locates_errors_in_the_base(tmp_path):
    write(tmp_path, "base.toml", 'title = "base"\nseed = "seven"\n')
    child = write(tmp_path, "child.toml", 'extends = "base.toml"\ntitle = "child"\n')
    with pytest.raises(ConfigError) as err:
        load_config(child, Installation)
    assert err.value.file.name == "base.toml" and err.value.line == 2
    write(tmp_path, "base.toml", 'title = "base"\nseed = 7\n')
    config = load_config(child, Installation)
    assert (config.title, config.seed) == ("child", 7)


def test_extends_loop_is_an_error(tmp_path):
    write(tmp_path, "a.toml", 'extends = "b.toml"\n')
    write(tmp_path, "b.toml", 'extends = "a.toml"\n')
    with pytest.raises(ConfigError, match="loops back"):
        load_config(tmp_path / "a.toml", Installation)


def test_key_lines_handles_dotted_and_quoted_keys():
    lines = key_lines('a.b = 1\n"quoted key" = 2\n[t]\nx = 3\n[[arr]]\ny = 4\n[[arr]]\ny = 5\n')
    assert lines[("a", "b")] == 1
    assert lines[("quoted key",)] == 2
    assert lines[("t", "x")] == 4
    assert lines[("arr", 1, "y")] == 8


def test_a_table_a_header_or_dotted_key_implies_is_at_the_line_that_writes_it(tmp_path):
    """``[creature.group.mood]`` (for ``groups``) is a typo on its own line; it was said at the
    ``[[creature]]`` line, which holds no ``group``, dozens of lines above in a real piece."""
    lines = key_lines('[[creature]]\nname = "a"\n[creature.group.mood]\nalpha = 0\nedits.favour.x = 1\n')
    assert lines[("creature", 0, "group")] == 3
    assert lines[("creature", 0, "group", "mood")] == 3
    assert lines[("creature", 0, "group", "mood", "edits")] == 5
    assert lines[("creature", 0)] == 1
    from creatures.runtime.schema import load_installation

    heron = (Path(installations.__file__).parent / "tutorial" / "heron-1.toml").read_text()
    assert "[creature.groups.main]" in heron
    path = write(tmp_path, "heron.toml", heron.replace("[creature.groups.main]", "[creature.group.main]"))
    with pytest.raises(ConfigError) as err:
        load_installation(path)
    typo = next(n for n, line in enumerate(path.read_text().splitlines(), 1) if "[creature.group.main]" in line)
    assert (err.value.key, err.value.line) == ("creature.0.group", typo)
    assert "did you mean 'groups'" in str(err.value)


def test_missing_extends_file_names_the_key_and_the_including_line(tmp_path):
    child = write(tmp_path, "child.toml", 'title = "child"\n\nextends = "bases/absent.toml"\n')
    with pytest.raises(ConfigError) as err:
        load_config(child, Installation)
    assert (err.value.file.name, err.value.key, err.value.line) == ("child.toml", "extends", 3)
    assert "'bases/absent.toml' not found" in str(err.value)
    assert str(tmp_path.resolve() / "bases" / "absent.toml") in str(err.value)


def test_a_mistyped_extends_names_the_nearest_file(tmp_path):
    (tmp_path / "bases").mkdir()
    write(tmp_path, "bases/gallery.toml", 'title = "base"\n')
    child = write(tmp_path, "child.toml", 'extends = "bases/galery.toml"\n')
    with pytest.raises(ConfigError) as err:
        load_config(child, Installation)
    assert "(did you mean 'bases/gallery.toml'?)" in str(err.value)


def test_a_fifo_as_extends_is_said_as_a_fifo_not_as_missing(tmp_path):
    os.mkfifo(tmp_path / "base.toml")
    child = write(tmp_path, "child.toml", 'extends = "base.toml"\n')
    with pytest.raises(ConfigError) as err:
        load_config(child, Installation)
    assert (err.value.key, err.value.line) == ("extends", 1)
    assert "'base.toml' is a FIFO (named pipe), not a regular file" in str(err.value)


@pytest.mark.parametrize("edit, key, message", [
    (("growth = 0.05", "growht = 0.05"), "creature.0.drives.boredom.growht", "did you mean 'growth'"),
    (('trigger = "bored"', 'triger = "bored"'), "creature.0.tuples.sing.triger", "did you mean 'trigger'"),
    (("alpha = 0.0", "alph = 0.0"), "creature.0.groups.main.alph", "did you mean 'alpha'"),
    (("until = { pulse = 2 }", "until = { puls = 2 }"), "creature.0.tuples.rest.until.puls", "did you mean 'pulse'"),
    (("value = 1.0", 'value = "high"'), "creature.0.tuples.sing.value", "valid number"),
    (("[[creature]]", "[creature]"), "creature", "write [[creature]] (two brackets)"),
    # a pair written with one value was 'creature.0.tuples.rest.until.gaussian.1: Field required'
    (("until = { pulse = 2 }", "until = { gaussian = [2.0] }"), "creature.0.tuples.rest.until.gaussian",
     "too few values: a value is wanted at position 2 (got [2.0])"),
    # a figure's name where a table is wanted named an internal class: 'instance of FigureBodySpec'
    (('kind = "authored"', 'kind = "authored"\nbody = "stick"'), "creature.0.body",
     "true, false or a table is wanted here: body = { … } or a [creature.body] table (docs/config.md) (got 'stick')"),
])
def test_a_typo_in_a_starting_piece_is_named_at_its_key_with_the_nearest_valid_one(tmp_path, edit, key, message):
    """The mistakes a new author makes in `creatures new`'s piece: a key inside a named table
    (a drive, a tuple, a group) gets its suggestion like any other, the key path holds only
    keys the author wrote, and a table written for a list of tables says so (not a dump)."""
    from creatures.authored.scaffold import new_installation
    from creatures.runtime.schema import load_installation

    path = new_installation("piece", tmp_path)
    text = path.read_text()
    assert edit[0] in text
    path.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(ConfigError) as err:
        load_installation(path)
    assert err.value.key == key and message in str(err.value)
    assert err.value.line is not None and len(str(err.value)) < 300


def test_an_extends_bases_paths_are_relative_to_the_base(tmp_path, monkeypatch):
    """A base config in another folder names its rehearsal file and its state folder relative
    to itself; a child that extends it from elsewhere finds them there (they were looked for
    beside the child)."""
    from creatures.runtime.schema import load_installation

    (tmp_path / "base").mkdir()
    (tmp_path / "pieces").mkdir()
    (tmp_path / "base" / "visit.csv").write_text("time,address,args\n1.0,/play,60\n")
    (tmp_path / "base" / "show.toml").write_text(
        'title = "base"\nstate = "saved"\n[[input]]\nosc = "/play"\nto = "note"\npitch = { arg = 0 }\n'
        '[[input]]\nfile = "visit.csv"\n[[creature]]\nname = "a"\nkind = "exchange"\n')
    child = tmp_path / "pieces" / "child.toml"
    child.write_text('extends = "../base/show.toml"\ntitle = "child"\n')
    monkeypatch.chdir("/")
    inst = load_installation(child)
    assert [row.address for row in inst.rehearsals[1]] == ["/play"]
    assert inst.resolve(inst.settings.state, ("state",)) == tmp_path / "base" / "saved"


def test_an_offline_run_says_it_does_not_read_the_live_state_folder(tmp_path):
    """`state = "DIR"` in a config is a live run's: an offline run starts fresh, and says so
    (it started fresh in silence, and an author expected it to resume)."""
    from creatures.authored.scaffold import new_installation
    from creatures.runtime.offline import run_offline
    from creatures.runtime.schema import load_installation

    path = new_installation("piece", tmp_path)
    path.write_text(path.read_text().replace('title = "piece"', 'title = "piece"\nstate = "saved"', 1))
    inst = load_installation(path)
    assert inst.settings.state == "saved"
    summary = run_offline(inst, tmp_path / "out", duration=1.0, progress=False)
    assert any(m.startswith("state = 'saved' is for live runs") for m in summary.messages)
    assert not (tmp_path / "saved").exists()


MAPS = "\n[[input]]\nosc = \"/knob\"\nto = \"drive\"\ncreatures = [\"ada\"]\ndrive = \"boredom\"\nset = 0.5\n"


@pytest.mark.parametrize("edit, key, got", [
    (("tick = 0.04", 'tick = "0.04"'), "tick", "'0.04'"),
    (("size = [6, 6]", 'size = [6, "6"]'), "creature.1.percepts.maps.size.1", "'6'"),  # a tuple's entry
    (("velocity = 0.4", 'velocity = "0.4"'), "creature.1.tuples.anticipate.action.velocity", "'0.4'"),
    (("hears_input = false", 'hears_input = "false"'), "creature.2.hears_input", "'false'"),
    (("hears_input = false", "hears_input = 0"), "creature.2.hears_input", "0"),
    (("set = 0.5", 'set = "0.5"'), "input.0.set", "'0.5'"),  # [[input]], read into [input] map
])
def test_a_number_or_truth_value_in_quotes_is_refused_at_its_key(tmp_path, edit, key, got):
    """Pydantic's lax mode (which fills tuple fields from TOML arrays) would read "0.04" as
    0.04 and 0 as false; an artist's slip is pointed at, at its line, like any other."""
    from creatures.runtime.schema import load_installation

    path = tmp_path / "maps.toml"
    text = (Path(installations.__file__).parent / "listen_maps.toml").read_text() + MAPS
    assert edit[0] in text
    path.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(ConfigError) as err:
        load_installation(path)
    assert err.value.key == key and f"(got {got})" in str(err.value)
    assert ("without quotes" in str(err.value)) == got.startswith("'")
    assert err.value.line == next(n for n, line in enumerate(path.read_text().splitlines(), 1) if edit[1] in line)


def test_a_note_name_a_field_reads_is_not_a_number_in_quotes(tmp_path):
    """Text that a field's validator reads as a number (a tile's note name, "F2") is no slip."""
    from creatures.runtime.schema import load_installation

    path = tmp_path / "maps.toml"
    path.write_text((Path(installations.__file__).parent / "listen_maps.toml").read_text() + MAPS)
    assert load_installation(path).settings.input.map[0].set == 0.5
    assert load_installation(installations.path("void")).specs


def test_input_maps_as_a_list_beside_an_input_table_is_explained(tmp_path):
    """tomllib says only "Cannot overwrite a value"; the author wrote [[input]] maps and an
    [input] table (generate = "none"), so the message says to write [[input.map]]."""
    path = write(tmp_path, "a.toml", 'title = "x"\n[[input]]\nosc = "/a"\nto = "note"\n[input]\ngenerate = "none"\n')
    with pytest.raises(ConfigError, match=r"\[\[input\]\] and \[input\] are both written.*\[\[input\.map\]\]"):
        load_config(path, Installation)


def test_a_misspelt_generated_input_names_the_nearest_choice(tmp_path):
    """`generate` is one of three words: a slip says which was meant, as every other choice
    does (it said only that the text should match a pattern)."""
    from creatures.runtime.schema import load_installation

    text = 'title = "x"\n[input]\ngenerate = "phrse"\n[[creature]]\nname = "a"\nkind = "exchange"\n'
    with pytest.raises(ConfigError, match=r"did you mean 'phrase'") as info:
        load_installation(write(tmp_path, "a.toml", text))
    assert info.value.line == 3
