"""Every number is finite and bounded at every door (issue 13, defects 8 and 9).

Config values, command-line arguments and MIDI file notes are checked where they enter: what
cannot be a number of the right size is refused with a message naming the file, key and
line (config), the option (command line, exit 2), or clamped where a sound file's meaning
is clear (a note held for a year is held as long as any note may be).
"""

from __future__ import annotations

import re
import types
import typing
from pathlib import Path

import annotated_types
import json
import mido
import numpy as np
import pytest
from pydantic import BaseModel

import installations
from creatures.cli import main
from creatures.clock import SimulatedClock
from creatures.config import MAX_CONFIG_BYTES, ConfigError
from creatures.events import EventLog
from creatures.kinds import load_all
from creatures.persist import StateFileError
from creatures.runtime.schema import Installation, load_installation
from creatures.runtime.session import COLONY_FILE, Session
from midi.notes import NoteEvent
from midi.sinks import MemorySink


def _config(tmp_path: Path, name: str, key: str, value: str) -> Path:
    """Installation ``name`` with ``key = value``: the key's first line replaced if the
    file has it, else added at the top (a top-level key) or to the first ``[[creature]]``."""
    text = installations.path(name).read_text()
    if re.search(rf"^{key} = ", text, flags=re.M):
        text = re.sub(rf"^{key} = .*$", f"{key} = {value}", text, count=1, flags=re.M)
    elif key in Installation.model_fields:
        text = f"{key} = {value}\n" + text
    else:
        text = re.sub(r"^(\[\[creature\]\]\n)", rf"\1{key} = {value}\n", text, count=1, flags=re.M)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _line_of(path: Path, key: str) -> int:
    return next(i for i, line in enumerate(path.read_text().splitlines(), 1) if line.startswith(f"{key} ="))


@pytest.mark.parametrize("name, key, value", [
    ("curve", "place", "nan"),  # passed, and the first save died on NaN
    ("curve", "place", "1e308"),
    ("exchange", "drives.boredom.growth", "inf"),
    ("exchange", "drives.boredom.growth", "1e308"),
    ("exchange", "duration", "inf"),
    ("exchange", "duration", "1e308"),
    ("exchange", "seed", "-1"),
    ("exchange", "seed", "100000000000000000000"),
    ("three_creatures", "latency", "[0.3, inf]"),
    ("ozymandias", "clicks", "[1.0, nan]"),
    ("sandstone", "percepts.presence.points", "[[0.0, nan]]"),
    ("sandstone", "drives.desire.decay", "1e308"),
])
def test_a_non_finite_or_huge_number_is_refused_at_its_key_and_line(tmp_path, name, key, value):
    path = _config(tmp_path, name, key, value)
    with pytest.raises(ConfigError) as caught:
        load_installation(path)
    error = caught.value
    assert error.file == path.resolve() and error.line == _line_of(path, key)
    assert re.fullmatch(rf"(creature\.0\.)?{key}(\.\d+)*", error.key), error.key


VALIDATED = {"AudioSection.input_device": "an index or name looked up among the devices present",
             "AudioSection.output_device": "an index or name looked up among the devices present",
             "OscSection.peers": "host:port strings, no numbers (the network's own checks)"}


def _unbounded(annotation: object, metadata: list) -> list[str]:
    """What in ``annotation`` (with its field ``metadata``) has no bound: a number without
    an upper bound, a list without a longest length."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is typing.Annotated:
        inner, *infos = args
        return _unbounded(inner, [*metadata, *(m for info in infos for m in getattr(info, "metadata", [info]))])
    if origin in (typing.Union, types.UnionType):
        return [gap for a in args if a is not type(None) for gap in _unbounded(a, metadata)]
    if origin is list:
        own = [] if any(isinstance(m, annotated_types.MaxLen) for m in metadata) else ["list length"]
        return own + _unbounded(args[0], [])
    if origin is tuple:
        return [gap for a in args for gap in _unbounded(a, [])]
    if annotation in (int, float) and not any(isinstance(m, (annotated_types.Le, annotated_types.Lt)) for m in metadata):
        return [annotation.__name__]
    return []


def test_every_number_in_the_schema_is_finite_and_bounded():
    """Systematic, not case by case: every config model refuses NaN/inf, every numeric key
    (the items of lists and tuples included) has an upper bound, every list a longest length."""
    models, seen, gaps = [Installation, *(kind.Spec for kind in load_all().values())], set(), {}
    while models:
        model = models.pop()
        if model in seen:
            continue
        seen.add(model)
        assert model.model_config.get("allow_inf_nan") is False, model.__name__
        for name, field in model.model_fields.items():
            models += [a for a in (field.annotation, *typing.get_args(field.annotation))
                       if isinstance(a, type) and issubclass(a, BaseModel)]
            found = _unbounded(field.annotation, field.metadata)
            if found and f"{model.__name__}.{name}" not in VALIDATED:
                gaps[f"{model.__name__}.{name}"] = found
    assert gaps == {}


def test_a_seed_model_that_is_not_an_aural_model_is_a_config_error(tmp_path):
    for target in ("/etc/passwd", str(tmp_path / "other.json")):
        (tmp_path / "other.json").write_text('{"format": "something else"}')
        key = 'percepts."any sound".seed_model'  # the aural tree's percept (installations/creatures/soundcreature.toml)
        path = _config(tmp_path, "soundcreatures", key, f'"{target}"')
        with pytest.raises(ConfigError, match="aural model") as caught:
            load_installation(path)
        assert caught.value.line == _line_of(path, key) and caught.value.key == "creature.0.percepts.any sound.seed_model"


def test_a_seed_model_is_found_beside_the_config_that_names_it(tmp_path, monkeypatch):
    """Paths in a config are relative to the config file, not to where the show was started."""
    import shutil

    from creatures.clock import SimulatedClock
    from creatures.events import EventLog
    from creatures.runtime.session import Session
    from midi.sinks import MemorySink

    (tmp_path / "words").mkdir()
    for suffix in (".json", ".npz"):
        shutil.copy(installations.path("three_creatures").parent / "three_creatures" / f"score-a{suffix}",
                    tmp_path / "words" / f"model{suffix}")
    path = _config(tmp_path, "soundcreatures", 'percepts."any sound".seed_model', '"words/model.json"')
    monkeypatch.chdir("/")
    installation = load_installation(path)
    creature = Session(installation, SimulatedClock(), EventLog(), MemorySink()).creatures[0]
    tree = creature.percept("any sound")
    assert len(tree.members) == 4


@pytest.mark.parametrize("nesting", ["[" * 1000 + "]" * 1000, "{a = " * 1000 + "1" + "}" * 1000, "[" * 20 + "]" * 20])
def test_deeply_nested_toml_is_a_config_error_not_a_recursion_error(tmp_path, nesting):
    path = tmp_path / "deep.toml"
    path.write_text(f'title = "deep"\nx = {nesting}\n')
    with pytest.raises(ConfigError, match="nested too deeply") as caught:
        load_installation(path)
    assert caught.value.file == path


def test_a_device_as_config_is_refused_and_a_huge_config_read_no_further_than_the_size_cap(tmp_path):
    """``creatures offline /dev/zero`` read until memory ran out (/dev/zero reports size 0):
    a device is refused unread, and a regular file past the cap is read one byte past it."""
    with pytest.raises(ConfigError, match="character device, not a regular file"):
        load_installation("/dev/zero")
    huge = tmp_path / "huge.toml"
    huge.write_bytes(b"#" * (MAX_CONFIG_BYTES + 10))
    with pytest.raises(ConfigError, match="larger than"):
        load_installation(huge)


@pytest.mark.parametrize("value", ["nan", "inf", "-5", "0", "1e308", "soon"])
@pytest.mark.parametrize("command", ["offline", "run", "demo"])
def test_a_bad_duration_on_the_command_line_is_a_usage_error(tmp_path, capsys, command, value):
    extra = {"offline": ["--out", str(tmp_path / "out")], "run": ["--state", str(tmp_path / "state")],
             "demo": ["--out", str(tmp_path / "out")]}[command]
    with pytest.raises(SystemExit) as caught:
        main([command, "exchange" if command == "demo" else str(installations.path("exchange")), *extra,
              f"--duration={value}"])
    assert caught.value.code == 2
    err = capsys.readouterr().err
    assert "--duration" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists() and not (tmp_path / "state").exists()


@pytest.mark.parametrize("value", ["0", "367", "1.5", "week"])
def test_a_bad_number_of_days_is_one_usage_line_naming_the_range(capsys, value):
    """``--days 0`` printed all 366 allowed values (argparse's ``choices``)."""
    with pytest.raises(SystemExit) as caught:
        main(["rehearse", "exchange", f"--days={value}"])
    assert caught.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].endswith(f"argument --days: {value!r} is not a whole number of days in 1…366") and len(err[-1]) < 120


def test_a_midi_file_note_held_absurdly_long_is_held_at_most_the_longest_note(tmp_path):
    """A file note whose note-off lies 2^27 ticks on at the slowest tempo (about 2,000
    years) is heard as one long note, not as a duration no clock can reach."""
    from midi.files import read_notes
    from midi.notes import LONGEST_NOTE

    midi = mido.MidiFile(type=0, ticks_per_beat=1)
    track = mido.MidiTrack([mido.MetaMessage("set_tempo", tempo=2**24 - 1),
                            mido.Message("note_on", note=60, velocity=100, time=0)])
    track += [mido.Message("note_off", note=60, velocity=0, time=2**27)] + \
             [mido.Message("note_on", note=62, velocity=100, time=0), mido.Message("note_off", note=62, time=1)]
    midi.tracks.append(track)
    midi.save(tmp_path / "long.mid")
    notes = read_notes(tmp_path / "long.mid")
    assert [n.pitch for n in notes] == [60, 62]
    assert notes[0].duration == LONGEST_NOTE and notes[1].duration == pytest.approx(2**24 / 1e6, rel=1e-3)


# -- saved state (defects 9 and 10) ------------------------------------------------------------

def _lived(path: Path, seconds: float, state: Path | None = None) -> Session:
    """A session of the installation at ``path`` (restored from ``state``) after ``seconds``
    of ticks with a note heard every 0.3 s."""
    session = Session(load_installation(path), SimulatedClock(), EventLog(), MemorySink())
    if state is not None:
        session.load_state(state)
    for step in range(1, int(seconds / 0.1) + 1):
        t = round(step * 0.1, 6)
        session.clock.advance_to(t)
        if step % 3 == 0:
            session.world.inject(NoteEvent(t, 60 + step % 7, 90, 0, 0.2))
        session.step(t, 0, None, audio=False)
    return session


def test_an_edited_setting_wins_over_restored_state_and_learned_levels_are_kept(tmp_path):
    """Defect 10: an edited boredom growth (``boredom_rate`` then) was ignored after a restart (the saved drive
    rates replaced the config's). Rates are settings, levels are what the creature lived."""
    before = _lived(installations.path("exchange"), 5.0)
    before.save_state(tmp_path / "state")
    saved_levels = before.creatures[0].motivation.levels.copy()
    edited = _config(tmp_path, "exchange", "drives.boredom.growth", "0.5")
    after = _lived(edited, 0.0, state=tmp_path / "state")
    motivation = after.creatures[0].motivation
    assert motivation.growth[motivation.index("boredom")] == 0.5
    assert np.array_equal(motivation.levels, saved_levels)


def test_a_huge_pulse_size_is_refused_naming_the_file_not_a_memory_error(tmp_path):
    """Defect 9: a colony file with ``size`` 1e12 failed with MemoryError at start."""
    _lived(installations.path("exchange"), 3.0).save_state(tmp_path)
    path = tmp_path / COLONY_FILE
    document = json.loads(path.read_text())
    document["pulse"]["size"] = 10**12
    path.write_text(json.dumps(document))
    with pytest.raises(StateFileError, match=re.escape(str(path))):
        _lived(installations.path("exchange"), 0.0, state=tmp_path)


@pytest.mark.parametrize("damage", ["deep", "1e400", "decay"])
def test_damaged_state_is_refused_at_load_or_runs(tmp_path, damage):
    """Deep nesting hit the recursion limit; ``1e400`` read as an infinite value; a drive decay of
    1e308 loaded and made the levels NaN, so the next save died. Now the first two are
    refused naming the file, and a saved rate is not read (the config's is used)."""
    _lived(installations.path("exchange"), 3.0).save_state(tmp_path)
    path = tmp_path / "ada.json"
    text = path.read_text()
    if damage == "deep":
        text = text.replace('"values":', '"deep": ' + "[" * 5000 + "]" * 5000 + ', "values":')
    elif damage == "1e400":
        text = re.sub(r'("value": )[0-9.e-]+', r"\g<1>1e400", text, count=1)  # a learned value
    else:
        document = json.loads(text)
        document["state"]["motivation"]["decay"]["boredom"] = 1e308
        text = json.dumps(document)
    path.write_text(text)
    if damage == "decay":
        after = _lived(installations.path("exchange"), 60.0, state=tmp_path)
        after.save_state(tmp_path)
        assert np.isfinite(after.creatures[0].motivation.levels).all()
    else:
        with pytest.raises(StateFileError, match=re.escape(str(path))):
            _lived(installations.path("exchange"), 0.0, state=tmp_path)


def test_a_midi_file_past_the_size_cap_is_refused_before_it_is_read(tmp_path):
    from midi.files import MAX_MIDI_BYTES, MidiFileError, read_notes

    path = tmp_path / "huge.mid"
    with open(path, "wb") as handle:  # sparse: no disk is used
        handle.write(b"MThd")
        handle.truncate(MAX_MIDI_BYTES + 1)
    with pytest.raises(MidiFileError, match=f"{re.escape(str(path))}: MIDI file larger than"):
        read_notes(path)


@pytest.mark.parametrize("time, duration", [(0.0, 1e308), (0.0, 3600.5), (1e308, 1.0), (2e12, 1.0)])
def test_a_note_no_clock_reaches_the_end_of_is_refused(time, duration):
    """Every door that makes a NoteEvent (OSC, MIDI, a creature) gets this bound: two OSC
    notes of 1e308 s sent a sandstone drive to infinity (defect 4; the OSC side is tested
    with the network)."""
    from midi.notes import LONGEST_NOTE

    with pytest.raises(ValueError, match="NoteEvent (time|duration) must be"):
        NoteEvent(time, 60, 90, 0, duration)
    assert NoteEvent(1e12, 60, 90, 0, LONGEST_NOTE).end == 1e12 + LONGEST_NOTE
