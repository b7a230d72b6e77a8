"""A state that loads is a state that runs (issue 13, defect 9: state-mutation fuzz).

Real saved state comes from running each shipped installation offline for a few simulated
seconds (its own generated input: notes, tones or the spoken poem). Hypothesis then damages
one thing at a time, anywhere in any of its state files (every creature's and the colony's):
a number made NaN, ±inf, ±1e308, ±1e12, 2^64, -1, 0 or 0.5; any value replaced by text,
null, a list, a table or a 2,000-deep nesting; a list emptied, lengthened fifty-fold or cut
short; a key dropped or an unknown key added; a flag flipped. Every mutant must either be
refused at load with a :class:`StateFileError` naming the damaged file, or run two simulated
minutes (ticks of 0.5 s, a note heard every 1.5 s, audio rendered every tenth tick; flock half
a minute, :data:`SHORTER`) and save again without error. Ten minutes a mutant made flock's case
alone run past 25 minutes (fifteen singers steering in a room) and CI past its limit; the
exhaustive sweep below lived one simulated minute a mutant, and that minute found all 120 crashes.

Cases: :data:`EXAMPLES` mutants for each shipped installation (425 for the seventeen, drawn
deterministically: tests/conftest.py's profile), each a full run when it loads. During
development the same mutations were also swept exhaustively over every leaf (4,806 mutants, one simulated minute each): 120 of them
crashed on the code before this test's fixes (pulse size 1e12, drive rates 1e308, pose
indices, zero transition counts, sample rates 0 …), none after.
"""

from __future__ import annotations

import copy
import json
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import installations
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.persist import StateFileError
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.notes import NoteEvent
from midi.sinks import MemorySink

EXAMPLES = 25
TICK = 0.5
MINUTES = 2
SHORTER = {"flock": 0.5}
"""Minutes a loading mutant of these pieces lives instead (see the module's docstring)."""
SHIPPED = installations.names()

NUMBERS = [float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 1e12, -1e12, 2**64, -1, 0, 0.5]
OTHERS = ["zz", None, [], {}, True]
DEEP = "deep"  # a 2,000-deep nesting of lists, written as text (json.dumps would recurse as deep)


def _paths(node: Any, path: tuple = ()) -> list[tuple]:
    """Every path into ``node`` (a long list contributes its first, middle and last entries)."""
    found = [path] if path else []
    if isinstance(node, dict):
        for key, child in node.items():
            found += _paths(child, (*path, key))
    elif isinstance(node, list):
        picks = range(len(node)) if len(node) <= 6 else sorted({0, len(node) // 2, len(node) - 1})
        for i in picks:
            found += _paths(node[i], (*path, i))
    return found


def _mutations(value: Any) -> list[Any]:
    """What one value may be turned into (each an operation ``_apply`` knows)."""
    if isinstance(value, bool):
        return [("set", not value), ("set", 2), *(("set", o) for o in OTHERS if o is not True), ("deep",)]
    if isinstance(value, (int, float)):
        return [*(("set", n) for n in NUMBERS), *(("set", o) for o in OTHERS), ("deep",)]
    ops: list[Any] = [("set", o) for o in OTHERS] + [("set", 1e308), ("deep",)]
    if isinstance(value, list):
        ops += [("empty",), ("lengthen",), ("shorten",)]
    if isinstance(value, dict):
        ops += [("drop", key) for key in value] + [("add",)]
    return ops


def _apply(document: dict, path: tuple, op: tuple) -> str:
    """``document`` with ``op`` applied at ``path``, as JSON text."""
    document = copy.deepcopy(document)
    parent = document
    for key in path[:-1]:
        parent = parent[key]
    key, kind = path[-1], op[0]
    if kind == "set":
        parent[key] = op[1]
    elif kind == "deep":
        parent[key] = DEEP
    elif kind == "empty":
        parent[key] = []
    elif kind == "lengthen":
        parent[key] = parent[key] * 50 if parent[key] else [0] * 50
    elif kind == "shorten":
        parent[key] = parent[key][:-1]
    elif kind == "drop":
        parent[key].pop(op[1])
    elif kind == "add":
        parent[key]["unexpected"] = 1
    return json.dumps(document).replace(f'"{DEEP}"', "[" * 2000 + "]" * 2000)


@pytest.fixture(scope="module")
def saved(tmp_path_factory) -> dict[str, Path]:
    """Each shipped installation's state after a few simulated seconds of its own input."""
    root = tmp_path_factory.mktemp("saved")
    for name in SHIPPED:
        run_offline(load_installation(installations.path(name)), root / name, duration=4.0)
    return {name: root / name / "state" for name in SHIPPED}


def _run(name: str, state: Path) -> None:
    """Load ``state`` into a fresh session of ``name`` and live its minutes, then save."""
    inst = load_installation(installations.path(name))
    inst.settings = inst.settings.model_copy(update={"tick": TICK})
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(keep_in_memory=0), MemorySink())
    session.load_state(state)
    rng = np.random.default_rng(13)
    frames = int(TICK * inst.settings.audio.sample_rate)
    for step in range(1, int(SHORTER.get(name, MINUTES) * 60 / TICK) + 1):
        t = step * TICK
        clock.advance_to(t)
        if step % 3 == 0:
            session.world.inject(NoteEvent(t, int(rng.integers(48, 84)), int(rng.integers(40, 120)), 0, 0.4))
        session.step(t, frames, None, audio=step % 10 == 0)
    session.save_state(state)


@pytest.mark.slow
@pytest.mark.parametrize("name", SHIPPED)
@settings(max_examples=EXAMPLES, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_every_mutant_is_refused_naming_its_file_or_runs_and_saves(saved, name, data):
    files = sorted(saved[name].glob("*.json"))
    target = data.draw(st.sampled_from(files), label="file")
    document = json.loads(target.read_text())
    path = data.draw(st.sampled_from([p for p in _paths(document) if p[0] not in ("format", "version")]), label="path")
    value = document
    for key in path:
        value = value[key]
    op = data.draw(st.sampled_from(_mutations(value)), label="mutation")
    with tempfile.TemporaryDirectory() as scratch:
        state = Path(scratch) / "state"
        shutil.copytree(saved[name], state)
        damaged = state / target.name
        damaged.write_text(_apply(document, path, op))
        try:
            _run(name, state)
        except StateFileError as exc:
            assert str(damaged) in str(exc), exc
