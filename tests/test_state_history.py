"""Snapshots, diff, rollback and merge of learned state (creatures/runtime/snapshots.py,
creatures/runtime/repertoire.py), on the tutorial heron, which keeps every phrase it hears."""

from __future__ import annotations

import json
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pytest

from creatures.clock import SimulatedClock
from creatures.cli import main
from creatures.events import EventLog
from creatures.persist import StateFileError
from creatures.runtime import repertoire, snapshots
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.notes import NoteEvent
from midi.sinks import MemorySink

HERON = Path(__file__).resolve().parent.parent / "installations/tutorial/heron-4.toml"
FIRST, SECOND = (60, 64, 67), (62, 65, 69)
DAY = datetime(2026, 3, 2, 9, 0, tzinfo=timezone.utc)


def live_for(state: Path | None, seconds: float, phrase: tuple[int, ...] = ()) -> tuple[Session, MemorySink]:
    """The heron restored from ``state`` (if any), hearing ``phrase``, for ``seconds`` simulated."""
    inst = load_installation(HERON)
    clock, sink = SimulatedClock(), MemorySink()
    session = Session(inst, clock, EventLog(keep_in_memory=0), sink)
    if state is not None and state.exists():
        session.load_state(state)
    for i, pitch in enumerate(phrase):
        session.world.inject(NoteEvent(0.5 + 0.3 * i, pitch, 90, 0, 0.2))
    tick, sr = inst.settings.tick, inst.settings.audio.sample_rate
    for step in range(1, int(seconds / tick) + 1):
        clock.advance_to(step * tick)
        session.step(clock.now(), int(round(tick * sr)), None, audio=False)
    return session, sink


def snapshot(state: Path, session: Session, at: datetime) -> Path:
    session.save_state(state)
    return snapshots.take(state, session.snapshot(), at)


def test_diff_lists_exactly_the_phrase_taught(tmp_path: Path) -> None:
    state = tmp_path / "state"
    a = snapshot(state, live_for(None, 10, FIRST)[0], DAY)
    b = snapshot(state, live_for(state, 10, SECOND)[0], DAY + timedelta(days=1))
    changes = repertoire.diff(a, b)
    new = [c for c in changes if c.sign == "+"]
    assert [(c.what, c.path) for c in new] == [("new phrase", ("phrases",)), ("new value", ("values", "main", "phrase 2"))]
    assert [note[1] for note in new[0].new] == list(SECOND)
    assert not [c for c in changes if c.sign == "-"]
    # What else changed is a learned value of a tuple it already had, never a drive level.
    assert {c.path[:3] for c in changes if c.sign == "~"} <= {("values", "main", t) for t in ("listen", "rest", "phrase 1")}
    assert repertoire.diff(a, a) == []


def test_rollback_restores_one_creature_byte_for_byte(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    state = tmp_path / "state"
    a = snapshot(state, live_for(None, 10, FIRST)[0], DAY)
    live_for(state, 10, SECOND)[0].save_state(state)
    assert (state / "heron.json").read_bytes() != (a / "heron.json").read_bytes()
    assert main(["state", "rollback", str(state), a.name, "--creature", "heron"]) == 0
    assert (state / "heron.json").read_bytes() == (a / "heron.json").read_bytes()
    assert main(["state", "rollback", str(state), a.name, "--creature", "egret"]) == 2
    assert "no saved state for creature 'egret' (saved: heron)" in capsys.readouterr().err


def test_merged_repertoire_plays_the_phrases_of_both(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    one, two = tmp_path / "one", tmp_path / "two"
    live_for(None, 10, FIRST)[0].save_state(one)
    live_for(None, 10, SECOND)[0].save_state(two)
    assert main(["state", "merge", str(one), "--creature", "heron", str(two), "--into", "heron"]) == 0
    assert "phrase 2 (was phrase 1: pitches 60 64 67)" in capsys.readouterr().out
    session, sink = live_for(two, 240)
    played = [n.pitch for n in sink.notes()]
    assert sum(played.count(p) for p in FIRST) >= 3 and sum(played.count(p) for p in SECOND) >= 3
    assert set(played) <= set(FIRST) | set(SECOND)
    # Alone, the second heron sings only its own phrase: the first's notes came with the merge.
    _, alone = live_for(tmp_path / "absent", 240, SECOND)
    assert not {n.pitch for n in alone.notes()} & set(FIRST)


def test_retention_keeps_daily_and_weekly(tmp_path: Path) -> None:
    stamps = [DAY + timedelta(hours=12 * i) for i in range(60)]  # a month, twice a day
    keep = snapshots.kept(stamps, daily=3, weekly=3)
    at = lambda day: datetime(2026, 3, day, 21, tzinfo=timezone.utc)  # noqa: E731
    # The newest of Tue 31, Mon 30, Sun 29 (also the week before's newest) and of the week of the 16th.
    assert keep == {at(31), at(30), at(29), at(22)}
    for when in stamps[:3]:
        snapshots.take(tmp_path, [("heron.json", "{}")], when)
    assert [p.name for _, p in snapshots.listed(tmp_path)] == ["2026-03-02T090000Z", "2026-03-02T210000Z",
                                                             "2026-03-03T090000Z"]
    snapshots.prune(tmp_path, daily=1, weekly=0)
    assert [p.name for _, p in snapshots.listed(tmp_path)] == ["2026-03-03T090000Z"]


def test_snapshotter_is_due_on_the_run_clock(tmp_path: Path) -> None:
    shots = snapshots.Snapshotter(tmp_path, every=86400, daily=7, weekly=0)
    assert shots.due(DAY)
    shots.take([("heron.json", "{}")], DAY)
    assert not shots.due(DAY + timedelta(hours=23))
    assert snapshots.Snapshotter(tmp_path, every=86400, daily=7, weekly=0).due(DAY + timedelta(days=1))


def test_snapshots_go_on_after_the_clock_is_set_back(tmp_path: Path) -> None:
    """A machine whose clock ran years ahead (a wrong RTC, set right by NTP later) left a
    snapshot stamped in the future. Counting from it, no snapshot fell due for years; and as
    the newest of all it was the one retention kept, so the snapshot just taken was removed."""
    ahead = DAY + timedelta(days=3 * 365)
    snapshots.take(tmp_path, [("heron.json", '{"n": 0}')], ahead)
    shots = snapshots.Snapshotter(tmp_path, every=86400, daily=1, weekly=0)
    assert shots.due(DAY)  # the clock is behind the newest snapshot: take one now
    taken = shots.take([("heron.json", '{"n": 1}')], DAY)
    assert taken.is_dir() and (taken / "heron.json").read_text() == '{"n": 1}'
    assert not shots.due(DAY + timedelta(hours=23))  # then on the run's clock, as ever
    shots.take([("heron.json", '{"n": 2}')], DAY + timedelta(days=1))
    names = [p.name for _, p in snapshots.listed(tmp_path)]
    assert names == ["2026-03-03T090000Z", "2029-03-01T090000Z"]  # the future one is left as it is


def test_merge_refuses_kinds_that_differ(tmp_path: Path) -> None:
    live_for(None, 1)[0].save_state(tmp_path)
    text = (tmp_path / "heron.json").read_text().replace('"kind": "authored"', '"kind": "exchange"')
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "egret.json").write_text(text)
    with pytest.raises(StateFileError, match="different kinds"):
        repertoire.merge(tmp_path / "other", "egret", tmp_path, "heron")


def test_a_live_run_takes_a_dated_snapshot_of_what_it_saved(tmp_path: Path) -> None:
    from creatures.runtime import live

    config = tmp_path / "live.toml"
    config.write_text('title = "snap"\nsave_every = 0.1\n[snapshots]\nevery = 86400\n[audio]\noutput = false\n'
                      '[[creature]]\nname = "ada"\nkind = "exchange"\n')
    state = tmp_path / "state"
    summary = live.run_live(load_installation(config), duration=1.0, state=state, say=lambda message: None)
    assert summary.saved_at is not None and summary.failed_saves == 0
    taken = snapshots.listed(state)
    assert len(taken) == 1  # due at once, then not again for a day
    assert abs((taken[0][0] - datetime.now(timezone.utc)).total_seconds()) < 600
    assert repertoire.read_creatures(taken[0][1]).keys() == {"ada"}


def test_three_creatures_merge_their_remembered_sounds(tmp_path: Path) -> None:
    """A three_creatures creature's repertoire is its remembered sounds: merging one whose
    memory holds a sound the other lacks appends it after the target's own, and the target
    restores with both (its own first); the same merge again adds nothing."""
    import installations

    inst = load_installation(installations.path("three_creatures"))
    session = Session(inst, SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())
    name = session.creatures[0].name
    one, two = tmp_path / "one", tmp_path / "two"
    session.save_state(one)
    session.save_state(two)
    from creatures.kinds.hearing_parts import pack_samples

    for folder, origin, hz in ((one, "heard in the other room", 440.0), (two, "heard here", 330.0)):
        path = folder / f"{name}.json"
        document = json.loads(path.read_text())
        tone = 0.5 * np.sin(2 * np.pi * hz * np.arange(8000) / 16000.0)
        document["state"]["memory"] = [{"samples": pack_samples(tone.astype(np.float32)), "samplerate": 16000,
                                        "time": 12.5, "origin": origin}]  # one sound each
        path.write_text(json.dumps(document))
    added = repertoire.merge(one, name, two, name)
    assert len(added) == 1 and "heard in the other room" in added[0]
    assert repertoire.merge(one, name, two, name) == []
    restored = Session(inst, SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())
    restored.load_state(two)
    creature = next(c for c in restored.creatures if c.name == name)
    assert [m.origin for m in creature.memory] == ["heard here", "heard in the other room"]


def test_a_merge_says_which_parts_learning_it_does_not_carry(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """listen's model population is its ``heard`` part's own learning, with no phrase or class to
    graft: the merge said only "added nothing" and left it, silently."""
    import installations

    from creatures.cli import main

    inst = load_installation(installations.path("listen"))
    session = Session(inst, SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())
    session.save_state(tmp_path / "a")
    session.save_state(tmp_path / "b")
    assert repertoire.not_carried(tmp_path / "a", "lis") == ["parts.percepts.heard"]
    assert main(["state", "merge", str(tmp_path / "a"), "--creature", "lis", str(tmp_path / "b"), "--into", "lis"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "note: not carried: parts.percepts.heard (lis keeps its own)"
    assert repertoire.not_carried(tmp_path / "a", "ada") == []  # exchange's creatures keep no part of their own


def test_a_kind_without_a_repertoire_merge_says_why(tmp_path: Path) -> None:
    import installations

    inst = load_installation(installations.path("ozymandias"))
    session = Session(inst, SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())
    name = session.creatures[0].name
    session.save_state(tmp_path / "a")
    session.save_state(tmp_path / "b")
    with pytest.raises(StateFileError, match="percept tree clusters"):
        repertoire.merge(tmp_path / "a", name, tmp_path / "b", name)


def test_merged_sound_classes_are_sung_from_both_trees(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A sound creature taught "ai"/"oe" and one taught "ua"/"ieu" (each until its aural tree
    splits into classes): merged, the second's tree holds the first's classes too, renumbered,
    with their tuples, and in the silence after it sings exemplars heard by each."""
    import installations
    from audio_fixtures import SR, alternating_words
    from creatures.kinds.hearing_parts import Mouth, pack_samples

    config = installations.path("soundcreatures")

    def taught(words: tuple[str, str], state: Path) -> None:
        x, _ = alternating_words(words, 30.0, seed=1, length=60.0)
        session = Session(load_installation(config), SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())
        frames, parrot = int(0.02 * SR), session.creatures[0]
        for k in range(1, len(x) // frames + 1):
            session.clock.advance_to(k * 0.02)
            session.step(k * 0.02, frames, x[(k - 1) * frames:k * frames])
            if k * 0.02 >= 30.0 and len(parrot.aural.root.utterance_children()) >= 2:
                break
        assert len(parrot.aural.root.utterance_children()) >= 2
        session.save_state(state)

    one, two = tmp_path / "one", tmp_path / "two"
    taught(("ai", "oe"), one)
    taught(("ua", "ieu"), two)
    heard = {p: {u["samples"] for u in json.loads((p / "parrot.json").read_text())["state"]["aural"]["tree"]
                 ["utterances"]} for p in (one, two)}
    assert main(["state", "merge", str(one), "--creature", "parrot", str(two), "--into", "parrot"]) == 0
    session = Session(load_installation(config), SimulatedClock(), EventLog(keep_in_memory=0), MemorySink())
    session.load_state(two)
    parrot = session.creatures[0]
    classes = [p.name for p in parrot.aural.root.utterance_children()]
    assert classes == ["any sound/1", "any sound/2", "any sound/3", "any sound/4"]
    sung_classes = {tp.action.percept.name for tp in parrot.group.tuples if hasattr(tp.action, "percept")}
    assert {"any sound/3", "any sound/4"} <= sung_classes  # the first's classes came with tuples singing them
    sung: list[str] = []
    sing = Mouth.sing
    monkeypatch.setattr(Mouth, "sing", lambda self, t, u, gain=1.0: sung.append(pack_samples(u.samples))
                        or sing(self, t, u, gain))
    frames = int(0.02 * SR)
    for k in range(1, int(180.0 / 0.02)):
        session.clock.advance_to(k * 0.02)
        session.step(k * 0.02, frames, np.zeros(frames, np.float32))
    only = {p: heard[p] - heard[q] for p, q in ((one, two), (two, one))}
    assert sum(s in only[one] for s in sung) >= 5 and sum(s in only[two] for s in sung) >= 5


def test_a_full_aural_root_keeps_its_own_classes_and_says_what_it_left() -> None:
    def tree(prefix: str, classes: int) -> dict:
        utterances = [{"samples": f"{prefix}{i}", "samplerate": 22050, "time": float(i)} for i in range(classes)]
        children = [{"name": f"any sound/{i + 1}", "born": 0, "members": [i], "children": []} for i in range(classes)]
        return {"tree": {"max_children": 3, "utterances": utterances,
                         "root": {"name": "any sound", "born": classes, "members": list(range(classes)),
                                  "children": children}},
                "tuples": {"main": [[f"any sound/{i + 1}", "attend", f"any sound/{i + 1}|attend"]
                                    for i in range(classes)]}}

    src, dst = tree("a", 2), tree("b", 2)
    values = {"main": {}}
    added = repertoire._merge_aural(src, dst, {"main": {"any sound/1|attend": 1.5}}, values)
    assert [c["name"] for c in dst["tree"]["root"]["children"]] == ["any sound/1", "any sound/2", "any sound/3"]
    assert dst["tree"]["root"]["children"][2]["members"] == [2]  # the source's exemplar, appended once
    assert "not added: sound class any sound/2 (the root holds its max_children classes)" in added
    assert values == {"main": {"any sound/3|attend": 1.5}}
    assert [t[2] for t in dst["tuples"]["main"]] == ["any sound/1|attend", "any sound/2|attend", "any sound/3|attend"]


def test_snapshots_of_a_missing_folder_is_an_error_and_of_an_empty_one_says_none(tmp_path: Path, capsys) -> None:
    from creatures.cli import main

    assert main(["state", "snapshots", str(tmp_path / "nowhere")]) == 2
    assert "no such state folder" in capsys.readouterr().err
    assert main(["state", "snapshots", str(tmp_path)]) == 0
    assert "no snapshots yet" in capsys.readouterr().out


def test_a_printing_command_whose_reader_stops_ends_without_a_word() -> None:
    """`creatures config-docs | head -1`: the pipe closes after one line; the command ends by
    SIGPIPE as cat would, with nothing on stderr (it printed '[Errno 32] Broken pipe')."""
    import subprocess
    import sys

    run = subprocess.Popen([sys.executable, "-m", "creatures.cli", "config-docs"], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, bufsize=0)
    assert run.stdout.readline().startswith(b"# ")
    run.stdout.close()
    _, err = run.communicate(timeout=60)
    assert err == b"" and run.returncode in (-13, 0)  # 0: it had written everything before the close


def test_a_rollback_names_what_it_cannot_find_and_changes_nothing(tmp_path: Path, capsys) -> None:
    """A mistyped snapshot, state folder or creature: each refused with the nearest valid name,
    nothing written. Before, a missing STATE was made (a new folder no run reads, "restored"),
    a stamp one digit off said only "not a state folder or snapshot", and ``--creature`` took a
    path out of the folder."""
    state = tmp_path / "state"
    a = snapshot(state, live_for(None, 2, FIRST)[0], DAY)
    before = (state / "heron.json").read_bytes()
    (tmp_path / "outside.json").write_bytes(before)

    def refused(*argv: str) -> str:
        assert main(["state", "rollback", *argv]) == 2
        err = capsys.readouterr().err
        assert "Traceback" not in err
        return err

    assert "(did you mean '2026-03-02T090000Z'?)" in refused(str(state), "2026-03-02T090001Z", "--creature", "heron")
    assert "(snapshots: none)" in refused(str(tmp_path), a.name, "--creature", "heron")
    assert f"{tmp_path / 'stat'}: no such state folder" in refused(str(tmp_path / "stat"), str(a), "--creature", "heron")
    assert not (tmp_path / "stat").exists()
    assert "(did you mean 'heron'?)" in refused(str(state), a.name, "--creature", "heon")
    assert "no saved state for creature '../../../outside'" in refused(str(state), a.name, "--creature",
                                                                         "../../../outside")
    assert not (state / "outside.json").exists()
    assert (state / "heron.json").read_bytes() == before


def test_a_snapshot_is_never_written_by_a_merge_or_a_rollback(tmp_path: Path, capsys) -> None:
    """A snapshot is history: merged into (or rolled back into, its stamp taken for the state
    folder), it would no longer be the colony as it was that day, and nothing said so."""
    state = tmp_path / "state"
    a = snapshot(state, live_for(None, 2, FIRST)[0], DAY)
    b = snapshot(state, live_for(state, 2, SECOND)[0], DAY + timedelta(days=1))
    kept = (a / "heron.json").read_bytes()
    assert main(["state", "merge", str(b), "--creature", "heron", str(a), "--into", "heron"]) == 2
    assert f"{a}: is a snapshot, kept as the colony was then; merge into the state folder ({state})" \
        in capsys.readouterr().err
    assert main(["state", "rollback", str(a), str(b), "--creature", "heron"]) == 2
    assert "is a snapshot" in capsys.readouterr().err
    assert (a / "heron.json").read_bytes() == kept
    assert main(["state", "merge", str(b), "--creature", "heron", str(state), "--into", "heron"]) == 0  # read, not written


def test_a_rollback_over_a_creature_of_another_kind_is_refused(tmp_path: Path, capsys) -> None:
    """A snapshot of another installation whose creature has the name but not the kind: the run
    would refuse the file at its next start (exit 2, not restarted), so the rollback refuses it."""
    state = tmp_path / "state"
    a = snapshot(state, live_for(None, 2, FIRST)[0], DAY)
    document = json.loads((a / "heron.json").read_text())
    (a / "heron.json").write_text(json.dumps({**document, "kind": "curve"}))
    before = (state / "heron.json").read_bytes()
    assert main(["state", "rollback", str(state), a.name, "--creature", "heron"]) == 2
    assert "kind 'curve'" in capsys.readouterr().err
    assert (state / "heron.json").read_bytes() == before
    (state / "heron.json").write_text("{damaged")  # a damaged file is what a rollback is for
    assert main(["state", "rollback", str(state), a.name, "--creature", "heron"]) == 0


@pytest.mark.parametrize("edit, key", [
    (lambda d: d["state"].update(phrases="abc"), "phrases: must be a list"),
    (lambda d: d["state"].update(phrases=[[[1.0, 60, 90]]]), "phrases.0.0: must be a note"),
    (lambda d: d["state"].update(values=[]), "values: must be a table"),
    (lambda d: d["state"].update(phrases_made="x"), "phrases_made: must be a whole number"),
    (lambda d: d["state"].update(learnt=None), "learnt: must be a list"),
    (lambda d: d["state"].update(gestures=[{}]), "gestures.0.shaping: must be text"),
    (lambda d: d["state"].update(aural={"tree": {"root": {"name": "any sound", "members": [3], "children": []}}}),
     "aural.tree.root.members.0: must be a whole number"),
    (lambda d: d.update(state=[]), "state: must be a table"),
])
@pytest.mark.parametrize("damaged", ["source", "target"])
def test_a_merge_of_a_damaged_state_names_the_file_and_key_and_writes_nothing(
        tmp_path: Path, capsys, edit, key: str, damaged: str) -> None:
    """A hand-edited state file on either side of a merge: refused naming that file and the key,
    both files as they were. Before, each of these ended in a traceback, and a damaged target
    was written back merged."""
    one, two = tmp_path / "one", tmp_path / "two"
    live_for(None, 2, FIRST)[0].save_state(one)
    live_for(None, 2, SECOND)[0].save_state(two)
    path = (one if damaged == "source" else two) / "heron.json"
    document = json.loads(path.read_text())
    edit(document)
    path.write_text(json.dumps(document))
    kept = {p: p.read_bytes() for p in (one / "heron.json", two / "heron.json")}
    assert main(["state", "merge", str(one), "--creature", "heron", str(two), "--into", "heron"]) == 2
    err = capsys.readouterr().err
    assert f"creatures: {path}: malformed authored state ({key}" in err and "Traceback" not in err
    assert {p: p.read_bytes() for p in kept} == kept


def test_every_kind_that_merges_has_its_shape_checked() -> None:
    from creatures.runtime.repertoire_shape import SHAPES

    assert set(SHAPES) == set(repertoire.MERGERS)
