"""``creatures inspect``: rendered from a real offline run and from a saved state directory,
the page embeds its plots and names every tuple, drive, percept and duration model."""

from __future__ import annotations

import base64
import re
from collections import Counter

import numpy as np
import pytest

import installations
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.behaviour.value import GaussianValue, ScalarValue
from creatures.cli import main
from creatures.clock import SimulatedClock
from creatures.events import EventLog, read_events
from creatures.persist import load_json, save_json
from creatures.kinds.parts import shared_graph
from creatures.runtime.inspect import InspectError, inspect
from creatures.runtime.offline import run_offline
from creatures.runtime.report import motor_walks
from creatures.runtime.schema import load_installation
from creatures.runtime.session import COLONY_FILE, COLONY_KIND, STATE_KIND, Session
from creatures.runtime.speech_input import spoken_poem
from creatures.temporal.durations import LowIntegerRatioModel
from midi.notes import NoteEvent
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
    assert "3 creature(s) and the colony from saved state" in page  # ada, bo, cy: the colony is not a creature
    for name in ("ada", "bo", "cy", "wander", "seek note", "rest", "boredom", "hunger"):
        assert f"<td>{name}</td>" in page or f"<h3>{name} " in page, name
    # The run saved what its creatures learned into DIR/state, and the page is drawn from it.
    assert {"ada.json", "bo.json", "cy.json", COLONY_FILE} <= {p.name for p in (offline_run / "state").iterdir()}
    assert "(saved state)" in page and "<h3>colony <small>" in page
    # Every kind the log holds is counted, those no plot draws (poses, most of a log) too.
    logged = Counter(e["kind"] for e in read_events(offline_run / "events.jsonl"))
    assert logged["pose"] and f"<p>{logged.total()} events, " in page
    assert f"<td>pose</td><td>{logged['pose']}</td>" in page and f"<td>note</td><td>{logged['note']}</td>" in page


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


PHRASE = [60, 64, 67, 72, 71, 67, 62, 65]
BEATS = [1, 1, 2, 1, 1, 1, 2, 1]  # a rhythm of 1:1 and 2:1 durations
BEAT = 0.3


def _real_run(out, name: str, seconds: float, *, phrase: bool = False, speech: bool = False):
    """A shipped installation run as ``creatures offline`` runs it (one Session on the
    simulated clock, the input's notes injected, its audio fed tick by tick, events logged to
    ``out/events.jsonl``), with its state saved into the same directory, as ``creatures run
    --state`` saves it."""
    inst = load_installation(installations.path(name))
    clock = SimulatedClock()
    log = EventLog(out / "events.jsonl")
    session = Session(inst, clock, log, MemorySink())
    tick, sr = inst.settings.tick, inst.settings.audio.sample_rate
    if phrase:
        onsets = 1.0 + BEAT * np.concatenate(([0], np.cumsum(np.tile(BEATS, 40))))
        for i, onset in enumerate(onsets[onsets < seconds]):
            session.world.inject(NoteEvent(round(float(onset), 6), PHRASE[i % 8], 90, 0, 0.25))
    heard = spoken_poem(seconds, sr, session.input_rng) if speech else None
    for step in range(1, int(round(seconds / tick)) + 1):
        a, b = int(round((step - 1) * tick * sr)), int(round(step * tick * sr))
        clock.advance_to(step * tick)
        session.step(step * tick, b - a, None if heard is None else heard[a:b], audio=False)
    session.close()
    log.close()
    session.save_state(out)
    return session


@pytest.fixture(scope="module")
def listened(tmp_path_factory):
    out = tmp_path_factory.mktemp("listen")
    session = _real_run(out, "listen", 30.0, phrase=True)
    seen = out / "inspect"
    assert main(["inspect", str(out), "--out", str(seen)]) == 0
    return out, session, (seen / "index.html").read_text(), {p.name: p.read_bytes() for p in seen.glob("*.png")}


def test_a_real_run_shows_the_colony_s_heard_pulse(listened):
    out, session, page, pngs = listened
    saved = load_json(out / COLONY_FILE, kind=COLONY_KIND)
    pulse = LowIntegerRatioModel.from_dict(saved["pulse"])
    assert pulse.pulse == pytest.approx(session.world.pulse.model.pulse)
    assert min(abs(pulse.pulse / (BEAT * level) - 1) for level in (0.5, 1, 2)) < 0.05  # the rhythm fed, at some level
    assert saved["heard"] > 50
    # The page shows it: pulse value, ratio histogram (most probable first) and its plot.
    p = pulse.ratio_distribution()
    top = int(np.argmax(p))
    row = (f"<tr><td>pulse</td><td>pulse {pulse.pulse:.3f} s</td><td>{pulse.ratios[top].numerator}/"
           f"{pulse.ratios[top].denominator}: {p[top]:.2f}, ")
    assert "<h3>colony <small>" in page and row in page
    assert {"known_durations.png", "known_values.png", "motor_graph.png"} <= set(pngs)
    assert sorted(_images(page)) == sorted(pngs.values())


def test_a_real_run_shows_the_listener_s_confidence(listened):
    out, session, page, _ = listened
    lis = next(c for c in session.creatures if c.name == "lis")
    saved = load_json(out / "lis.json", kind=STATE_KIND)["state"]["parts"]["percepts"]["heard"]["expected match"]
    expected = GaussianValue.from_dict(saved)
    assert expected.to_dict() == lis.state()["parts"]["percepts"]["heard"]["expected match"]
    assert 0.5 < expected.confidence() <= 1.0  # a phrase heard over and over is expected
    assert f"<td>expected match</td><td>{expected.to_float():.4g}</td><td>{expected.confidence():.3f}</td>" in page
    for name in ("dance", "anticipate", "rest", "excitement"):
        assert f"<td>{name}</td>" in page, name


def _size(node: dict) -> int:
    return 1 + sum(_size(c) for c in node["children"])


@pytest.mark.slow
def test_a_real_run_shows_percept_trees(tmp_path):
    _real_run(tmp_path, "ozymandias", 60.0, speech=True)
    page = inspect(tmp_path, tmp_path / "seen").read_text()
    assert "known_trees.png" in {p.name for p in (tmp_path / "seen").glob("*.png")}
    for creature in ("traveller", "sculptor", "king"):
        tree = load_json(tmp_path / f"{creature}.json", kind=STATE_KIND)["state"]["tree"]["root"]
        children = tree["children"]
        assert children, f"{creature} grew no percept tree in a minute of speech"
        assert f"{tree['name']} <small>({_size(tree)} nodes)" in page
        assert all(f"{c['name']} <small>(" in page for c in children)


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


def test_a_tree_node_without_children_is_a_leaf_and_the_page_is_written_whole(tmp_path, monkeypatch):
    """A hand-edited tree whose leaf lost its ``children``: shown as a leaf (a KeyError traceback
    before). And a page that fails to write (a full disk, Ctrl-C) leaves the previous one whole."""
    import os

    state = tmp_path / "state"
    state.mkdir()
    save_json(state / "lark.json", {"kind": "authored", "state": {"tree": {
        "name": "whatever", "children": [{"name": "high call"}, {"name": "low", "children": "x"}]}}}, kind=STATE_KIND)
    page = inspect(state, tmp_path / "seen")
    before = page.read_bytes()
    assert b"whatever <small>(3 nodes)" in before and b"high call <small>(1 node)" in before

    def full(fd: int) -> None:
        raise OSError(28, "No space left on device")

    save_json(state / "wren.json", {"kind": "authored", "state": {}}, kind=STATE_KIND)
    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OSError, match="No space left"):
        inspect(state, tmp_path / "seen")
    assert page.read_bytes() == before
