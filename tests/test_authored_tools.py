"""Authoring tools (issue 15): ``creatures new``, ``creatures describe`` and ``creatures
offline NAME`` for a shipped installation."""

from __future__ import annotations

import shutil
from pathlib import Path

from creatures.cli import main
from creatures.events import read_events

TUTORIAL = Path(__file__).resolve().parents[1] / "installations" / "tutorial"


def test_new_writes_a_commented_installation_that_runs(tmp_path, capsys):
    assert main(["new", "egret", "--dir", str(tmp_path)]) == 0
    path = tmp_path / "egret.toml"
    text = path.read_text()
    assert text.count("#") >= 8 and 'kind = "authored"' in text
    assert main(["offline", str(path), "--out", str(tmp_path / "out"), "--duration", "40", "--no-progress"]) == 0
    notes = [e for e in read_events(tmp_path / "out" / "events.jsonl") if e["kind"] == "note"]
    assert notes and {e["creature"] for e in notes} == {"egret"}
    assert main(["new", "egret", "--dir", str(tmp_path)]) == 2  # never overwrites
    assert "not overwritten" in capsys.readouterr().err
    assert main(["new", "bad name", "--dir", str(tmp_path)]) == 2


def test_describe_prints_drives_percept_trees_groups_and_tuples(capsys):
    assert main(["describe", str(TUTORIAL / "heron-4.toml")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1] == "heron (authored)"
    assert "│  └─ boredom = 0 (growth 0.05, decay 0, on_heard -0.3, on_played -0.08)" in out  # what moves it
    assert "│     ├─ bored (drive)" in out
    assert "└─ group main [max_active 1, alpha 0.2, discount 0.8]" in out
    assert "   └─ praised: praise | rest | 0.5 s | V 4, non-plastic" in out  # its action by type


def test_describe_shows_graded_du_and_chained_values(capsys):
    """A chained value says which goal it is (or none yet), its learnt value and the goals it
    serves, beside what it is worth now; a graded Du says so."""
    assert main(["describe", "cadence"]) == 0
    out = capsys.readouterr().out
    assert ("home: whatever if ending(dominant) | play_phrase | 3 s graded until home done | V 0.8, non-plastic, "
            "chained = home (learnt 4; serves home)") in out
    assert "wander: whatever | play_phrase | 2.4 s graded until wander done | V 0.5, chained (learnt 1; serves home, summit)" in out


def test_describe_builds_a_real_visitors_praise_from_the_input_map(tmp_path, capsys):
    """The tutorial's step 4 with the input-map praise its text shows (a sensor read by the
    ``praise`` percept): describe knows the map's sensors, as a run does."""
    shutil.copytree(TUTORIAL, tmp_path / "t")
    heron = tmp_path / "t" / "creatures" / "heron.toml"
    heron.write_text(heron.read_text().replace('type = "played"', 'type = "sensor"\nsensor = "praise"')
                     .replace("pitches = [72]\nwindow = 1.0\n", ""))
    config = tmp_path / "t" / "heron-4.toml"
    config.write_text(config.read_text() + '\n[[input.map]]\nosc = "/praise"\nto = "sensor"\nname = "praise"\n'
                      'value = 1.0\n')
    assert main(["describe", str(config)]) == 0
    assert "│     └─ praise (sensor)" in capsys.readouterr().out.splitlines()


def test_describe_shows_class_based_kinds_and_nested_groups_too(tmp_path, capsys):
    assert main(["describe", "curve"]) == 0
    out = capsys.readouterr().out
    assert "(curve)" in out and "| mirror |" in out
    nested = tmp_path / "nested.toml"
    nested.write_text((TUTORIAL / "heron-1.toml").read_text().replace(
        '[creature.groups.main]      # the tuples compete here\ntuples = ["call", "rest"]',
        '[creature.groups.voice]\ntuples = ["call"]\nalpha = 0.0\n\n[creature.groups.main]\ntuples = ["voice", "rest"]'))
    assert main(["describe", str(nested)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert any(line.endswith("voice: whatever | voice | until voice:done | V 1 [max_active 1, alpha 0, "
                             "discount 0.8]") for line in out), out
    assert any("call: bored | play_phrase | until call done | V 1" in line for line in out)


def test_describe_shows_a_kinds_own_parts_and_no_empty_percept_tree(capsys):
    """three creatures have no action-groups: their memory and the score computer's flushes
    are what an author configured, so they are what the tree shows."""
    assert main(["describe", "three_creatures"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "├─ memory [8 sounds]" in out and "│  └─ the input's latest 2 sounds flushed in every 20 s" in out
    assert "   ├─ at 12 s: 4 slots ← score-a.json" in out and "   └─ at 24 s: 4 slots ← score-b.json" in out
    assert not any(line.endswith("percepts") for line in out)


def test_describe_shows_each_creatures_vehicle_and_steering_in_a_room(capsys):
    """In a room what a creature does is also where it goes: its vehicle (a crowd's clones each
    with their own drawn speed) and its steering in priority order, what each aims at (a seek
    written without a target seeks the visitor) and the percept that gates it. Before, a crowd
    piece's tree said nothing of either."""
    assert main(["describe", "flock"]) == 0
    out = capsys.readouterr().out.splitlines()
    vehicles = [line for line in out if line.startswith("├─ vehicle [")]
    assert len(vehicles) == 15 and len(set(vehicles)) == 15  # vary draws each singer's max_speed
    assert vehicles[0].endswith("max_force 2 N, mass 1 kg, radius 0.25 m, max_turn 360°/s, budget, "
                                "8 neighbours within 3 m, fov 240°, sight 10 m]")
    assert "│  ├─ wall_avoidance (weight 3)" in out
    assert "│  ├─ flee (target loud, panic 4, weight 3)" in out
    assert "│  ├─ arrival (target player, slowing 2.5, weight 1.5, when calm)" in out
    assert "│  └─ wander (weight 0.3)" in out


def test_describe_of_a_bad_config_is_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text((TUTORIAL / "heron-1.toml").read_text().replace('action = "rest"', 'action = "rset"'))
    assert main(["describe", str(bad)]) == 2
    assert "did you mean 'rest'" in capsys.readouterr().err


def test_a_config_named_without_toml_is_found_and_a_misspelt_shipped_one_is_suggested(tmp_path, monkeypatch,
                                                                                      capsys):
    monkeypatch.chdir(tmp_path)
    shutil.copy(TUTORIAL / "heron-1.toml", tmp_path / "mine.toml")
    shutil.copytree(TUTORIAL / "creatures", tmp_path / "creatures")
    assert main(["describe", "mine"]) == 0 and "heron (authored)" in capsys.readouterr().out
    assert main(["offline", "exchang", "--out", str(tmp_path / "o")]) == 2
    assert "config file not found (did you mean the shipped 'exchange'?)" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
    # a file beside it before a shipped piece; a tutorial step; the demo's own name lookup
    assert main(["describe", "mie"]) == 2
    assert "mie: config file not found (did you mean mine.toml?)" in capsys.readouterr().err
    assert main(["describe", "tutorial/heron1"]) == 2
    assert "(did you mean the shipped 'tutorial/heron-1'?)" in capsys.readouterr().err
    assert main(["demo", "exchang", "--out", str(tmp_path / "d")]) == 2
    assert "no shipped installation 'exchang' (did you mean 'exchange'?)" in capsys.readouterr().err


def test_offline_takes_a_shipped_installations_name(tmp_path):
    assert main(["offline", "tutorial/heron-1", "--out", str(tmp_path / "h"), "--duration", "5", "--no-progress"]) == 0
    assert main(["offline", "exchange", "--out", str(tmp_path / "e"), "--duration", "1", "--no-progress"]) == 0
    assert (tmp_path / "e" / "events.jsonl").is_file()
    assert main(["offline", "no-such-piece", "--out", str(tmp_path / "n"), "--no-progress"]) == 2
