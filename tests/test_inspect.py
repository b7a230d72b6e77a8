"""``creatures inspect``: rendered from a real offline run and from a saved state directory,
the page embeds its plots and names every tuple, drive, percept and duration model."""

from __future__ import annotations

import base64
import re

import numpy as np
import pytest

import installations
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.behaviour.value import GaussianValue, ScalarValue
from creatures.cli import main
from creatures.clock import SimulatedClock
from creatures.events import EventLog, read_events
from creatures.persist import save_json
from creatures.kinds.parts import shared_graph
from creatures.runtime.inspect import InspectError, inspect
from creatures.runtime.offline import run_offline
from creatures.runtime.report import motor_walks
from creatures.runtime.schema import load_installation
from creatures.runtime.session import STATE_KIND, Session
from creatures.temporal.durations import LowIntegerRatioModel
from midi.sinks import MemorySink

PNG = re.compile(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"')


def _images(page: str) -> list[bytes]:
    return [base64.b64decode(data) for data in PNG.findall(page)]


@pytest.fixture(scope="module")
def offline_run(tmp_path_factory):
    inst = load_installation(installations.path("exchange"))
    inst.settings.output.wav = inst.settings.output.frames = inst.settings.output.report = False
    out = tmp_path_factory.mktemp("offline")
    run_offline(inst, out, duration=10.0)
    return out


def test_inspect_an_offline_run(offline_run, tmp_path, capsys):
    assert main(["inspect", str(offline_run), "--out", str(tmp_path / "seen")]) == 0
    assert "index.html" in capsys.readouterr().out
    page = (tmp_path / "seen" / "index.html").read_text()
    pngs = sorted((tmp_path / "seen").glob("*.png"))
    names = {p.name for p in pngs}
    assert {"known_values.png", "known_drives.png", "values.png", "motivations.png", "motor_graph.png",
            "selections.png", "notes.png"} <= names
    # Self-contained: every plot is embedded, byte for byte, and nothing is linked.
    assert sorted(_images(page)) == sorted(p.read_bytes() for p in pngs)
    assert ".png\"" not in page
    for name in ("ada", "bo", "cy", "wander", "seek note", "rest", "boredom", "hunger"):
        assert f"<td>{name}</td>" in page or f"<h3>{name} " in page, name


def test_the_motor_graph_is_the_real_graph_and_the_path_walks_its_edges(offline_run):
    walks = motor_walks(read_events(offline_run / "events.jsonl"))
    assert set(walks) == {"ada", "bo", "cy"}
    for creature, walk in walks.items():
        graph = shared_graph(ratios=creature == "cy")  # the whole graph, not only what was walked
        np.testing.assert_allclose(walk.hands, graph.poses.positions[:, graph.skeleton.names.index("hand_r")],
                                   atol=1e-4)
        assert walk.edges == {(min(a, b), max(a, b)) for a, b in graph.edges()}, creature
        assert len(walk.path) > 50 and walk.jumps() == 0, creature  # every node reached, each step a graph edge
        assert len(set(walk.path)) < len(walk.hands) and sum(walk.steps().values()) == len(walk.path) - 1


def _state_dir(tmp_path):
    """Session.save_state of a short exchange run, plus a creature whose state holds a
    Gaussian value (with confidence), a low-integer-ratio duration model and a percept tree."""
    inst = load_installation(installations.path("exchange"))
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(), MemorySink())
    for step in range(1, 101):
        clock.advance_to(step * 0.04)
        session.step(step * 0.04, 0, None, audio=False)
    state = tmp_path / "state"
    session.save_state(state)

    sing = GaussianValue(2.0)
    for v in (2.1, 1.9, 2.05, 2.0, 8.0):
        sing.blend_to(ScalarValue(v), 0.3)
    rhythm = LowIntegerRatioModel(0.5)
    rng = np.random.default_rng(1)
    rhythm.update_many(0.4 * rng.choice([1.0, 2.0, 0.5], 300) * rng.normal(1.0, 0.01, 300))
    root = WhateverPercept()
    heard = FunctionPercept("heard a call", lambda t: 1.0, parent=root)
    FunctionPercept("high call", lambda t: 1.0, parent=heard)
    save_json(state / "lark.json", {"kind": "listen", "state": {
        "values": {"sing back": sing.to_dict(), "keep still": ScalarValue(0.5).to_dict()},
        "rhythm": rhythm.to_dict(), "percepts": root.to_dict()}}, kind=STATE_KIND)
    (state / "notes.txt").write_text("not state")  # other files are passed over
    return state, sing


def test_inspect_a_state_directory(tmp_path):
    state, sing = _state_dir(tmp_path)
    page_path = inspect(state, tmp_path / "seen")
    page = page_path.read_text()
    pngs = {p.name: p.read_bytes() for p in (tmp_path / "seen").glob("*.png")}
    assert {"known_values.png", "known_drives.png", "known_trees.png", "known_durations.png"} == set(pngs)
    assert sorted(_images(page)) == sorted(pngs.values())
    for name in ("ada", "bo", "cy", "lark", "wander", "seek note", "sing back", "keep still", "boredom", "hunger"):
        assert f"<td>{name}</td>" in page or f"<h3>{name} " in page, name
    # The Gaussian value's confidence is shown; the scalar one has none.
    assert f"<td>{sing.confidence():.3f}</td>" in page
    assert "<td>keep still</td><td>0.5</td><td></td>" in page
    # The percept tree with the size below every node.
    assert "whatever <small>(3 nodes)" in page and "high call <small>(1 node)" in page
    assert "<h2>Duration models (saved state)</h2>" in page
    assert "notes.txt" not in page


def test_nothing_to_inspect_is_a_clear_error(tmp_path, capsys):
    with pytest.raises(InspectError, match="no events.jsonl and no creature state"):
        inspect(tmp_path, tmp_path / "seen")
    assert main(["inspect", str(tmp_path)]) == 2
    assert "no events.jsonl" in capsys.readouterr().err
