"""``creatures rehearse``: a gallery week on the simulated clock with visitors, measured per hour
(issue 20, "rehearsing a gallery week"). The measures are tested on made-up hours that must
tell silence, repetition and variety apart; the visitors on their own rules; the rehearsal of
every shipped installation over 7 simulated days, reduced to short opening days, and one
whole 8-hour opening day of structure (the full gallery week of exchange is ``python -m bench
rehearse``)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import installations
from installations import UNHEARD

from creatures.cli import main
from creatures.config import ConfigError
from creatures.runtime.measures import HourTally, Swings, repetition
from creatures.runtime.rehearse import GALLERY, open_spans, rehearse, report
from creatures.runtime.schema import RehearseSection, ScheduleSection, load_installation
from creatures.runtime.session import Session
from creatures.runtime.visitors import CorpusError, Phrase, Visitors, generated, load_corpus
from midi.files import write_notes
from midi.notes import NoteEvent


def note(t: float, pitch: int, creature: str = "a") -> dict:
    return {"t": t, "kind": "note", "creature": creature, "time": t, "pitch": pitch, "duration": 0.5}


def test_the_default_gallery_opens_48_hours_a_week_and_the_schedule_is_taken():
    spans = open_spans(GALLERY, 7)
    assert len(spans) == 6 and sum(b - a for a, b in spans) == 48 * 3600
    assert spans[0] == (86400 + 10 * 3600, 86400 + 18 * 3600)  # Monday is closed
    night = open_spans(ScheduleSection(days=["fri"], opens="20:00", closes="02:00"), 7)
    assert night == [(4 * 86400 + 20 * 3600, 5 * 86400 + 2 * 3600)]  # past midnight, one span


def test_hour_measures_tell_silence_repetition_and_variety_apart():
    def hour(records):
        tally = HourTally(1, 10, ["a"])
        tally.open.append((0.0, 3600.0))
        for r in records:
            tally.add(r)
        return tally.finish(answered=3, unanswered=1, cycles=None, visitors=2)

    silent = hour([])
    assert silent.acts_per_minute == 0 and silent.silence == 1.0 and silent.pitch_entropy is None
    loop = hour([note(k * 0.5, [60, 62, 64, 65][k % 4]) for k in range(7200)])
    assert loop.silence == 0.0 and loop.acts_per_minute == 120.0
    assert loop.repetition > 0.99 and loop.pitch_entropy == pytest.approx(2.0)
    rng = np.random.default_rng(0)
    wander = hour([note(k * 0.5, int(rng.integers(48, 84))) for k in range(7200)])
    assert wander.repetition < loop.repetition and wander.pitch_entropy > 3.5
    sparse = hour([note(k * 60.0, 60) for k in range(60)])  # half a second in every minute
    assert sparse.silence == pytest.approx(1 - 30 / 3600) and loop.answer_rate == 0.75
    assert repetition([1, 2, 3]) is None


def test_boredom_cycles_count_rises_and_falls():
    swings = Swings(0.25)
    for x in [0.0, 0.3, 0.5, 0.2, 0.1, 0.4, 0.1, 0.12, 0.05]:
        swings.update(x)
    assert swings.cycles == 2


def test_visitors_play_again_sooner_when_answered_and_leave_when_not():
    params = RehearseSection(visitors_per_hour=60, stay=3600, phrase_every=20, patience=2, answer_window=5)

    def crowd(answering: bool) -> Visitors:
        v = Visitors(params, generated(False), np.random.default_rng(1))
        v.open(0.0)
        for k in range(1, 3600):
            for start, phrase in v.play(k - 1.0, float(k)):
                if answering:
                    v.hear(start + phrase.length + 1.0, phrase.notes[0].pitch + 12)  # an octave up: its class
        v.close(3600.0)
        return v

    answered, ignored = crowd(True), crowd(False)
    assert answered.unanswered == 0 and ignored.answered == 0
    assert answered.arrived > 40 and ignored.arrived > 40  # about 60 an hour
    # ignored visitors leave after `patience` phrases; answered ones stay and play on
    assert ignored.unanswered == 2 * ignored.arrived and answered.answered > 20 * answered.arrived


def test_an_answer_must_share_a_pitch_class_unless_the_phrase_was_spoken():
    v = Visitors(RehearseSection(answer_window=5), [Phrase((NoteEvent(0.0, 60, 90, 0, 0.5),))], np.random.default_rng(0))
    v.present.append(_visitor())
    v.play(0.0, 1.0)
    v.hear(2.0, 61)
    assert v.answered == 0
    v.hear(3.0, 72)
    assert v.answered == 1
    spoken = Visitors(RehearseSection(), [Phrase(line="look on my works")], np.random.default_rng(0))
    spoken.present.append(_visitor())
    spoken.play(0.0, 1.0)
    spoken.hear(2.0, None)
    assert spoken.answered == 1


def _visitor():
    from creatures.runtime.visitors import Visitor

    return Visitor(leaves=100.0, next_phrase=0.0)


def test_a_corpus_is_read_and_a_bad_one_is_named(tmp_path: Path):
    write_notes(tmp_path / "a.mid", [NoteEvent(5.0 + i, p, 90, 0, 0.5) for i, p in enumerate([60, 64, 67])])
    (tmp_path / "lines.txt").write_text("look on my works\n\nye mighty\n")
    [phrase] = load_corpus(tmp_path / "a.mid")
    assert [n.pitch for n in phrase.notes] == [60, 64, 67] and phrase.notes[0].time == 0.0
    assert [p.line for p in load_corpus(tmp_path / "lines.txt")] == ["look on my works", "ye mighty"]
    assert len(load_corpus(tmp_path)) == 1
    with pytest.raises(CorpusError, match=r"\[rehearse\] corpus .*nothing.mid"):
        load_corpus(tmp_path / "nothing.mid")


def test_a_corpus_folder_takes_midi_files_whatever_the_case_of_their_names(tmp_path: Path):
    """Files from Windows or a DAW ("TAKE1.MID", "b.midi") were passed over: "holds no phrase"."""
    write_notes(tmp_path / "TAKE1.MID", [NoteEvent(0.0, 60, 90, 0, 0.5)])
    write_notes(tmp_path / "b.midi", [NoteEvent(0.0, 67, 90, 0, 0.5)])
    (tmp_path / "notes.txt").write_text("not a phrase of the folder\n")
    assert [[n.pitch for n in p.notes] for p in load_corpus(tmp_path)] == [[60], [67]]


def test_the_rehearse_section_is_bounded():
    base = installations.path("curve").read_text()  # a shipped config without a [rehearse] of its own
    assert "[rehearse]" not in base
    path = Path(installations.path("curve")).parent / ".bad-rehearse.toml"
    try:
        path.write_text(base + "\n[rehearse]\nvisitors_per_hour = 1e6\n")
        with pytest.raises(ConfigError, match="visitors_per_hour"):
            load_installation(path)
        path.write_text(base + "\n[rehearse]\nvisiters = 3\n")
        with pytest.raises(ConfigError, match="visiters"):
            load_installation(path)
    finally:
        path.unlink(missing_ok=True)


def short(name: str, minutes: int = 5, tick: float = 0.5):
    """A shipped installation with a short opening day and a busy door (the reduced week)."""
    inst = load_installation(installations.path(name))
    inst.settings.rehearse.hours = ScheduleSection(opens="10:00", closes=f"10:{minutes:02d}")
    inst.settings.rehearse.visitors_per_hour = 60.0
    inst.settings.rehearse.tick = tick
    return inst


def test_a_crash_loses_its_hour_and_the_colony_goes_on(monkeypatch):
    real = Session.step
    calls = Counter()

    def flaky(self, t, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 900:  # day 2 (600 ticks a day)
            raise RuntimeError("a creature fell over")
        return real(self, t, *args, **kwargs)

    monkeypatch.setattr(Session, "step", flaky)
    r = rehearse(short("exchange"), 3)
    assert [h.crashed for h in r.hours] == [False, True, False] and r.crash_free == 2
    assert "a creature fell over" in r.crashes[0]
    assert r.hours[2].acts_per_minute > 0  # rebuilt from the hour's state, it plays on


def test_compare_puts_two_rehearsals_side_by_side():
    a, b = rehearse(short("exchange", 2), 1), rehearse(short("wren", 2), 1)
    text = report(a, b)
    assert "exchange: 1 days" in text and "wren: 1 days" in text
    row = text.splitlines()[-1]
    assert row.startswith("mon  10h") and row.count("|") == 6


def test_the_command_rehearses_and_refuses_a_bad_corpus(tmp_path: Path, capsys):
    config = tmp_path / "exchange.toml"
    shipped = installations.path("exchange").read_text()
    hours = '[rehearse]\nhours = { opens = "10:00", closes = "10:02" }'
    config.write_text(shipped.replace("[rehearse]", hours, 1))
    assert main(["rehearse", str(config), "--days", "1", "--json", str(tmp_path / "r.json")]) == 0
    said = capsys.readouterr()
    assert "acts/min" in said.out and (tmp_path / "r.json").exists()
    assert said.err == "exchange: mon 10h rehearsed (1 of 1 opening hours)\n"  # progress, hour by hour
    other = tmp_path / "wren.toml"  # --compare: the second config rehearsed beside it, one table
    other.write_text(installations.path("wren").read_text() + "\n" + hours)  # wren has no [rehearse] of its own
    assert main(["rehearse", str(config), "--days", "1", "--compare", str(other)]) == 0
    text = capsys.readouterr().out
    assert "exchange: 1 days" in text and "wren: 1 days" in text, text
    assert text.splitlines()[-1].startswith("mon  10h") and text.splitlines()[-1].count("|") == 6
    assert main(["rehearse", str(config), "--days", "1", "--compare", str(config)]) == 0  # one piece twice
    assert "exchange (exchange.toml): 1 days" in capsys.readouterr().out
    config.write_text(shipped.replace("[rehearse]", '[rehearse]\nhours = { days = ["tue"], opens = "10:00", '
                                                    'closes = "10:02" }', 1))
    assert main(["rehearse", str(config), "--days", "1"]) == 2  # Monday alone: nothing open to rehearse
    assert "1 day(s) from Monday hold no opening hours (open tue)" in capsys.readouterr().err
    config.write_text(shipped.replace("[rehearse]", hours + '\ncorpus = "missing.mid"', 1))
    assert main(["rehearse", str(config), "--days", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "[rehearse] corpus" in err and "missing.mid" in err


@pytest.mark.slow
@pytest.mark.parametrize("name", installations.names())
def test_every_shipped_installation_rehearsed_for_seven_days_is_never_silent_for_a_day(name):
    """Seven simulated days, each open 5 minutes at a 0.5 s tick, a visitor a minute: every
    creature acts within every opening day's length of open time, every open hour has its
    measures, and no hour crashed. (sand:stone, whose visitors move rocks, once left a rock
    away long enough to be silent 355.5 s; its rocks now long to sing in silence and call out
    within about two minutes, longest silence 131 s. The flock, once skipped as too slow,
    lives its week in about two minutes since a closed night is a clock gap the crowd stands
    through: longest silence 21 s, 36 visitors.)"""
    r = rehearse(short(name), 7)
    assert [(h.day, h.hour) for h in r.hours] == [(d, 10) for d in range(7)]
    assert all(h.open_seconds == 300 for h in r.hours) and r.crash_free == 7
    heard = {who: s for who, s in r.longest_silence.items() if (name, who) not in UNHEARD}
    # A statue moves, never sounds; (void*)'s characters dance and its camera cuts, and the score
    # plays for them (tests/test_void.py: the rehearsed days possess every character every day).
    assert max(heard.values()) <= r.opening_day, r.longest_silence
    assert all(h.acts_per_minute > 0 and h.silence < 1.0 for h in r.hours), [h.acts for h in r.hours]
    # the door is seeded Poisson at 60 an hour over 35 open minutes (mean 35); fewer than 15
    # would be a door that stopped opening (p < 1e-4), not chance (duncan, seed 0: 18)
    assert r.visitors >= 15


@pytest.mark.slow
def test_a_whole_gallery_day_of_structure_hears_every_creature_every_few_minutes():
    """The week above shortens each opening day to 5 minutes, so "never silent for a day" is
    checked against 5 minutes of open time; what a short day cannot show is a slow change over
    a long one. One real opening day (10:00-18:00) of structure at its own visitor rate (6 an
    hour; tick 0.5 s, 70 s of CPU), whose complexity arc runs 24 cycles of 20 minutes: every
    hour acts, and no creature is silent for more than 3 minutes of it (longest: bo 58.5 s, ada
    45.5 s, cy 80.5 s), a long way under the day."""
    inst = load_installation(installations.path("structure"))
    inst.settings.rehearse.hours = ScheduleSection(opens="10:00", closes="18:00")
    inst.settings.rehearse.tick = 0.5
    r = rehearse(inst, 1)
    assert [(h.day, h.hour) for h in r.hours] == [(0, hour) for hour in range(10, 18)]
    assert r.opening_day == 8 * 3600 and r.crash_free == 8
    assert max(r.longest_silence.values()) <= 180.0, r.longest_silence
    assert all(h.acts_per_minute > 0 and h.silence < 0.5 for h in r.hours), [h.silence for h in r.hours]


def test_a_silent_piece_fails_the_week(monkeypatch):
    """The week's check bites: exchange whose strikes play nothing is silent for longer than an
    opening day (two days of two minutes: four minutes) and acts in no hour."""
    from creatures.kinds.note_world import NoteWorld

    monkeypatch.setattr(NoteWorld, "strike", lambda self, t, obj, strength: None)
    r = rehearse(short("exchange", 2), 2)
    assert max(r.longest_silence.values()) == 240 > r.opening_day == 120
    assert all(h.acts_per_minute == 0 and h.silence == 1.0 for h in r.hours)


def test_the_command_reads_every_config_and_its_json_folder_before_rehearsing(tmp_path: Path, capsys):
    """A typo in --compare's config, or --json into a folder that is not there, was found only
    after the first config's week had been rehearsed (minutes; a quarter of an hour for
    exchange's); the JSON is written whole or not at all."""
    config = tmp_path / "exchange.toml"
    hours = '[rehearse]\nhours = { opens = "10:00", closes = "10:02" }'
    config.write_text(installations.path("exchange").read_text().replace("[rehearse]", hours, 1))
    other = tmp_path / "other.toml"
    other.write_text(config.read_text().replace("[rehearse]", "[rehearse]\nday = 2", 1))
    assert main(["rehearse", str(config), "--days", "1", "--compare", str(other)]) == 2
    said = capsys.readouterr()
    assert "other.toml" in said.err and "day" in said.err and "rehearsed" not in said.err, said.err
    (tmp_path / "empty").mkdir()  # a corpus folder with no MIDI file in it: said before the first week too
    other.write_text(config.read_text().replace("[rehearse]", '[rehearse]\ncorpus = "empty"', 1))
    assert main(["rehearse", str(config), "--days", "1", "--compare", str(other)]) == 2
    said = capsys.readouterr()
    assert "corpus" in said.err and "holds no phrase" in said.err and "rehearsed" not in said.err, said.err
    missing = tmp_path / "no" / "r.json"
    assert main(["rehearse", str(config), "--days", "1", "--json", str(missing)]) == 2
    said = capsys.readouterr()
    assert f"there is no folder {missing.parent}" in said.err and "rehearsed" not in said.err, said.err
    assert main(["rehearse", str(config), "--days", "1", "--json", str(tmp_path / "r.json")]) == 0
    assert [p.name for p in tmp_path.glob("*.json*")] == ["r.json"]  # no temporary file left beside it


def test_a_rehearsal_file_the_week_does_not_play_is_said_once(tmp_path: Path, capsys):
    """flock's ``[[input.map]] file = "flock-rehearsal.csv"`` (a visitor's walk, timed from a
    run's start) fed its offline runs; a rehearsed week never played a row of it and said
    nothing, so its author could think the week had heard it. It is not played (its rows are one
    take from a run's start; the week's visitors are [rehearse]'s, and it starts on a closed
    Monday night): the command says so once, before the week, naming the file and its line."""
    config = tmp_path / "exchange.toml"
    (tmp_path / "walk.csv").write_text("1,/clap,1\n2,/clap,1\n")
    shipped = installations.path("exchange").read_text()
    hours = '[rehearse]\nhours = { opens = "10:00", closes = "10:01" }'
    config.write_text(shipped.replace("[rehearse]", hours, 1) + '\n[[input.map]]\nfile = "walk.csv"\n\n'
                      '[[input.map]]\nosc = "/clap"\nto = "reward"\n')
    assert main(["rehearse", str(config), "--days", "2"]) == 0
    err = capsys.readouterr().err.splitlines()
    line = config.read_text().splitlines().index('file = "walk.csv"') + 1
    assert err[0] == (f"{config}:{line}: input.map.0.file: the rehearsal file 'walk.csv' (2 rows) is not played in a "
                      "rehearsed week: its rows are one take timed from a run's start (`creatures offline` and live "
                      "runs play it); the week's visitors are [rehearse]'s"), err
    assert sum("walk.csv" in e for e in err) == 1 and len(err) == 3  # once, then each of the two opening hours


def test_a_silence_under_a_minute_is_said_in_seconds() -> None:
    """The summary's longest silences: 40 s was printed '0 min', as if the creature never fell silent."""
    from creatures.runtime.rehearse import _span

    assert [_span(s) for s in (40.0, 59.4, 60.0, 131.0)] == ["40 s", "59 s", "1 min", "2 min"]
