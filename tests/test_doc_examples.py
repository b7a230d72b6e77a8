"""Every example the user's pages show works as shown (a new user's walkthrough, copy-pasted):
each TOML example of README.md, docs/authoring.md, docs/bodies.md, docs/view.md and
docs/stream.md loads, inside the smallest installation it needs (a fragment shows only its own
tables), the Extending page's Python part plays, and every ``creatures`` command the pages name
takes the options they give it.

A shipped file shown whole is checked by the test of that file (``SHOWN_ELSEWHERE``); any other
new example must be given its installation in ``AROUND``, or this test names it."""

from __future__ import annotations

import argparse
import re
from pathlib import Path
from contextlib import redirect_stderr
from io import StringIO
from typing import Callable

import pytest

from body_fixtures import heron_frames, write_bvh
from creatures.cli import build_parser
from creatures.events import read_events
from creatures.motor.bvh import read_bvh_skeleton
from creatures.motor.material import fingerprint
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation

ROOT = Path(__file__).resolve().parents[1]
PAGES = ["README.md", "docs/authoring.md", "docs/bodies.md", "docs/view.md", "docs/stream.md"]
SHIPPED = {path.read_text() for path in (ROOT / "installations").rglob("*.toml")}
SHOWN_ELSEWHERE = {  # an example's first line → the test that loads it
    "[[input]]                      # a clicker in TouchDesigner": "tests/test_input_map.py::test_the_readme_example_loads",
}

HEAD = 'title = "example"\nduration = 2.0\n[output]\nwav = false\nreport = false\n'
ADA = '[[creature]]\nname = "ada"\nkind = "authored"\n'


def _tuple(name: str, value: str = "1.0") -> str:
    return f'[creature.tuples.{name}]\naction = "rest"\nuntil = {{ seconds = 1.0 }}\nvalue = {value}\n'


def _group(name: str, *tuples: str, alpha: str = "0.0") -> str:
    return f'[creature.groups.{name}]\ntuples = {list(tuples)!r}\nalpha = {alpha}\n'.replace("'", '"')


def examples(page: str, language: str = "toml") -> list[tuple[int, str]]:
    """(line, text) of each fenced example in ``language`` on ``page``."""
    text = (ROOT / page).read_text()
    return [(text[:m.start()].count("\n") + 2, m.group(1))
            for m in re.finditer(rf"^```{language}\n(.*?)^```", text, re.M | re.S)]


def _heron_body(d: Path) -> str:
    write_bvh(d / "heron.bvh", heron_frames())  # 240 frames, a neck and a head: docs/bodies.md's heron
    return fingerprint(read_bvh_skeleton(d / "heron.bvh"))


def _bodies_first(example: str, d: Path) -> str:
    """The heron of files, with the two people's edit files it names (each a different edge)."""
    skeleton = _heron_body(d)
    (d / "edits").mkdir()
    (d / "edits" / "alice.toml").write_text(f'skeleton = "{skeleton}"\n[[reweight]]\nfrom = "heron@20"\n'
                                            'to = "heron@21"\nscale = 1.5\n')
    (d / "edits" / "bob.toml").write_text(f'skeleton = "{skeleton}"\n[[forbid]]\nfrom = "heron@10"\nto = "heron@11"\n')
    return HEAD + example


def _edit_file(example: str, d: Path) -> str:
    """The edit file as shown, for the skeleton it is loaded on (its fingerprint is a placeholder),
    on a take named ``walk`` labelled ``sit`` and ``beg``, with the ``beg_higher.bvh`` it adds."""
    (d / "edits.toml").write_text(example.replace("3fa9c2d1e0b4", _heron_body(d)))
    write_bvh(d / "beg_higher.bvh", heron_frames(seconds=0.65))  # 13 frames: [0, 12]
    return HEAD + ('[[creature]]\nname = "heron"\nkind = "exchange"\n[creature.body]\neffectors = ["head_end"]\n'
                   'scale = 0.01\nrest_labels = ["sit"]\ngraph_edits = ["edits.toml"]\n'
                   '[[creature.body.animations]]\nfile = "heron.bvh"\nname = "walk"\n'
                   'labels = { sit = [[100, 104]], beg = [[200, 204]] }\n')


def _score(example: str, d: Path) -> str:
    (d / "void").mkdir()
    (d / "void" / "tiles.toml").write_text((ROOT / "installations" / "void" / "tiles.toml").read_text())
    percepts = "".join(f'[creature.percepts.{name}]\ntype = "timer"\nafter = 1.0\n'
                       for name in ("eddie_acts", "eddie_glad", "eddie_seen"))
    return HEAD + ADA + percepts + example + _group("main", "eddie")


def _heron_1(example: str, d: Path) -> str:
    return (ROOT / "installations" / "tutorial" / "heron-1.toml").read_text() + example


REST = _tuple("r", "0.1")
AROUND: dict[str, Callable[[str, Path], str]] = {  # an example's first line → the installation around it
    "[[room.flows]]": lambda x, d: HEAD + "[room]\n" + ADA + '[creature.vehicle]\n'
    'steer = [{ behaviour = "flow_following", field = "round" }]\n' + REST + _group("main", "r") + x,
    '[osc]': lambda x, d: (ROOT / "installations" / "tutorial" / "heron-4.toml").read_text().replace(
        'include = ["creatures/heron.toml"]', f'include = ["{ROOT}/installations/tutorial/creatures/heron.toml"]') + x,
    "[creature.tuples.sway]": lambda x, d: HEAD + ADA + "body = true\n" + x + _group("main", "sway"),
    "[creature.tuples.stare]": lambda x, d: HEAD + ADA + "body = true\n" + x + REST + _group("main", "r")
    + _group("look", "stare"),
    '[creature.percepts."beg height"]': lambda x, d: HEAD + ADA + "body = true\n" + x + _group("main", "beg"),
    "[creature.groups.main]\ntuples = [\"lure\"": lambda x, d: HEAD + ADA + _tuple("lure") + _tuple("sit")
    + _tuple("treat", "{ value = 1.0, plastic = false }") + x,
    "[[room.zones]]": lambda x, d: HEAD + "[room]\n" + ADA + "[creature.drives.calm]\ngrowth = 0.0\n" + REST
    + _group("main", "r") + x,
    "[creature.score]": _score,
    "[creature.percepts.onset]": lambda x, d: HEAD + ADA + x,
    "[creature.percepts.visitor]": lambda x, d: HEAD + ADA + x + _group("time", "keep time"),
    "[creature.tuples.b]": lambda x, d: HEAD + ADA + x + _group("main", "b"),
    "[creature.drives.longing]": lambda x, d: HEAD + ADA + "[creature.drives.daring]\nlevel = 0.2\n"
    + "".join(_tuple(name) for name in ("wander", "stray", "predominant", "climb", "answer"))
    + _tuple("summit", '{ kind = "chain", value = 4.0, plastic = false, source = "summit", serves = { summit = "daring" } }')
    + x,
    "drive_floor = -1.0": lambda x, d: HEAD + '[[input]]\nosc = "/click"\nto = "sensor"\nname = "click"\n'
    'value = { arg = 0 }\n' + ADA + x + '[creature.percepts.click]\ntype = "sensor"\nsensor = "click"\n'
    + _group("main", "startle", "eat", alpha="0.2"),
    "[creature.percepts.later]": lambda x, d: HEAD + ADA + _tuple("wait")  # the songs are main's rewards
    + _tuple("low", "{ value = 1.0, plastic = false }") + _tuple("high", "{ value = 2.0, plastic = false }") + x,
    "[[creature]]\nname = \"heron\"\nkind = \"exchange\"": _bodies_first,
    '[creature.body]\nfigure = "dog"': lambda x, d: HEAD + '[[creature]]\nname = "rex"\nkind = "exchange"\n' + x,
    'skeleton = "3fa9c2d1e0b4"': _edit_file,
    "[stream]": _heron_1,
    "[console]": _heron_1,
    "[health]": _heron_1,
}


def _around(example: str) -> Callable[[str, Path], str] | None:
    return next((build for first, build in AROUND.items() if example.lstrip().startswith(first)), None)


ALL = [(page, line, example) for page in PAGES for line, example in examples(page)]


def test_every_example_config_is_checked_somewhere():
    unchecked = [f"{page}:{line}" for page, line, example in ALL
                 if example not in SHIPPED and _around(example) is None
                 and not any(example.startswith(first) for first in SHOWN_ELSEWHERE)]
    assert not unchecked, f"give these examples their installation in AROUND: {unchecked}"


@pytest.mark.parametrize("page, line, example", [pytest.param(*case, id=f"{case[0]}:{case[1]}")
                                                  for case in ALL if _around(case[2]) is not None])
def test_an_example_config_loads_as_the_page_shows_it(page, line, example, tmp_path):
    config = tmp_path / "example.toml"
    config.write_text(_around(example)(example, tmp_path))
    assert load_installation(config).specs, f"{page}:{line}"


def test_the_extending_example_plays_its_croak(tmp_path, own_registry):
    """docs/authoring.md, "Extending": the Python part as shown, next to a config naming it."""
    [(_, code)] = examples("docs/authoring.md", "python")
    (tmp_path / "my_actions.py").write_text(code)
    config = tmp_path / "frog.toml"
    config.write_text('plugins = ["my_actions.py"]\n' + HEAD.replace("duration = 2.0", "duration = 0.5")
                      + '[[creature]]\nname = "frog"\nkind = "authored"\n[creature.tuples.croak]\n'
                      'action = { type = "croak", pitch = 40 }\nuntil = { done = true }\nvalue = 1.0\n'
                      + _group("main", "croak"))
    run_offline(load_installation(config), tmp_path / "out")
    notes = [e for e in read_events(tmp_path / "out" / "events.jsonl") if e["kind"] == "note"]
    first, second = notes[:2]  # one croak: two low notes 0.3 s apart, each 0.2 s
    assert (first["pitch"], second["pitch"], first["duration"]) == (40, 40, 0.2), notes
    assert second["time"] - first["time"] == pytest.approx(0.3), notes


def _commands() -> list[tuple[str, str]]:
    """(page, command) of every ``creatures …`` the pages name, in backticks or in a shell block."""
    found = []
    for page in PAGES + ["docs/unattended.md", "docs/hearing.md"]:
        text = (ROOT / page).read_text()
        prose = re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)
        spans = [" ".join(span.split()) for span in re.findall(r"`([^`]+)`", prose)]  # one may wrap a line
        spans += [line.split("#")[0] for _, block in examples(page, "sh") for line in block.splitlines()]
        found += [(page, m.group(0).strip()) for span in spans
                  for m in re.finditer(r"(?:^|(?<=[\s(]))creatures [a-z][a-z-]*[^;&]*", span)]
    return found


def test_every_command_the_pages_name_takes_the_options_they_give():
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    wrong = []
    for page, command in _commands():
        name = command.split()[1]
        if name not in sub.choices:
            wrong.append(f"{page}: {command!r}: no command {name!r}")
            continue
        options = {o for action in sub.choices[name]._actions for o in action.option_strings}
        wrong += [f"{page}: {command!r}: {flag}" for flag in re.findall(r"--[a-z][a-z-]*", command)
                  if flag not in options]
    assert len(_commands()) > 40 and not wrong, wrong


def _form(word: str) -> bool:
    """``[--out DIR]``, ``svg|ps``, ``SOUND.wav...``: a form of many commands, not one to copy."""
    return bool(re.search(r"[\[\]…|<>]|\.\.\.", word))


def _filled(word: str) -> str:
    """A placeholder (``DIR``, ``NAME``, ``OUT.json``) as a value any of them takes."""
    return "1" if re.match(r"[A-Z][A-Z_]*(\.|$)", word) else word


def test_every_whole_command_the_pages_show_runs_as_written():
    """A command with its arguments is one to copy: it must parse as written, its placeholders
    filled (`creatures offline exchange` lacked the --out every offline run needs)."""
    refused = []
    for page, command in _commands():
        words = [_filled(w) for w in command.split()[1:]]
        if any(_form(w) for w in command.split()) or not any(not w.startswith("-") for w in words[1:]):
            continue  # a form, or a command named in passing (`creatures render --video`)
        try:
            with redirect_stderr(StringIO()) as said:
                build_parser().parse_args(words)
        except SystemExit:
            refused.append(f"{page}: {command!r}: {said.getvalue().strip().splitlines()[-1]}")
    assert not refused, refused
