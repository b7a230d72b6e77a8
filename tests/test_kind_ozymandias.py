"""ozymandias: the edit decision lists are valid, point inside the source recording, and
re-render the creatures' output from that recording (the EDL is a faithful record)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import soundfile

from audio.formants import speak
from audio.sources import load_audio
from audio_fixtures import SR, alternating_words, warm_librosa  # noqa: F401
from creatures.persist import save_json
from creatures.clock import SimulatedClock
from creatures.events import EventLog, read_events
from creatures.kinds.ozymandias import read_edl, render_edl
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from creatures.runtime.speech_input import POEM
from midi.sinks import MemorySink

CONFIG = Path(__file__).resolve().parents[1] / "installations" / "ozymandias.toml"
DURATION = 30.0

pytestmark = pytest.mark.usefixtures("warm_librosa")


@pytest.fixture(scope="module")
def reading(tmp_path_factory) -> Path:
    """A "recording" of the poem's last lines, twice (a reading the config never generates)."""
    rng = np.random.default_rng(3)
    text = "\n".join(POEM.splitlines()[-4:])
    x = np.concatenate([np.zeros(SR // 2, np.float32), speak(text, rng, SR)[0], speak(text, rng, SR)[0]])
    path = tmp_path_factory.mktemp("reading") / "reading.wav"
    soundfile.write(path, x, SR, subtype="PCM_16")
    return path


@pytest.fixture(scope="module")
def run(tmp_path_factory, reading) -> tuple[Path, list[str]]:
    out = tmp_path_factory.mktemp("ozymandias")
    inst = load_installation(CONFIG)
    inst.settings.output.report = False
    summary = run_offline(inst, out, audio=reading, duration=DURATION)
    names = [spec.name for spec in inst.specs]
    assert {f"edl {n}" for n in names} <= set(summary.files)
    return out, names


def test_edl_is_valid_and_points_inside_the_source(run, reading):
    out, names = run
    source = load_audio(reading, samplerate=SR)
    total = 0
    for name in names:
        edl = read_edl(out / f"{name}.edl.json")
        assert edl["sample_rate"] == SR and edl["creature"] == name
        for e in edl["entries"]:
            assert e["creature"] == name
            assert 0 <= e["source_start_frame"] < e["source_end_frame"] <= len(source)
            assert e["source_start"] == e["source_start_frame"] / SR
            assert 0 <= e["output_frame"] < DURATION * SR and e["gain"] > 0
        total += len(edl["entries"])
    assert total >= 10
    # "out of time": a creature reads material back later than it was spoken
    lags = [e["output_time"] - e["source_start"] for n in names for e in read_edl(out / f"{n}.edl.json")["entries"]]
    assert min(lags) > 0 and np.median(lags) > 1.0


def test_rendering_the_edl_from_the_source_reproduces_the_output(run, reading):
    out, names = run
    source = load_audio(reading, samplerate=SR).astype(np.float64)
    heard, sr = soundfile.read(out / "out.wav")
    again = render_edl([read_edl(out / f"{n}.edl.json") for n in names], source, len(heard))
    assert np.abs(heard).max() > 0.01, "the creatures read something back"
    assert np.abs(again - heard).max() <= 1.5 / 32768  # out.wav is 16-bit
    # and the record is not trivially satisfied: one entry moved by a word breaks it
    edls = [read_edl(out / f"{n}.edl.json") for n in names]
    entry = next(e for edl in edls for e in edl["entries"])
    entry["source_start_frame"] += SR // 5
    entry["source_end_frame"] += SR // 5
    assert np.abs(render_edl(edls, source, len(heard)) - heard).max() > 1e-3


def test_clicks_reward_and_excitement_follows_the_text(run):
    out, names = run
    events = read_events(out / "events.jsonl")
    spec = {s.name: s for s in load_installation(CONFIG).specs}
    for name in names:
        rewards = [e["t"] for e in events if e["kind"] == "reward" and e["creature"] == name]
        clicks = [c for c in spec[name].clicks if c <= DURATION]
        assert len(rewards) == len(clicks)
        assert all(min(abs(r - c) for c in clicks) <= 0.1 for r in rewards)
        credit = [e for e in events if e["kind"] == "credit" and e["creature"] == name and e["new"] == "clicked"]
        assert credit and all(e["target"] > 2.0 for e in credit)  # the click's value flows back
    drive = [e["drives"]["excitement"] for e in events if e["kind"] == "motivation" and e["creature"] == names[0]]
    assert max(drive) > 0.3 and drive[0] == 0.0


def test_bad_edl_is_a_clear_error(tmp_path):
    path = tmp_path / "bad.edl.json"
    save_json(path, {"sample_rate": SR, "creature": "x",
                     "mix": {"gain": 1, "pan": 0},
                     "entries": [{"source_start_frame": 10, "source_end_frame": 5, "output_frame": 0, "gain": 1}]},
              kind="creature-music edl")
    with pytest.raises(ValueError, match="entry 0"):
        read_edl(path)


@pytest.mark.parametrize("edit, message", [
    ({"sample_rate": None}, "sample_rate: must be a whole number in [8000, 192000], found None"),
    ({"sample_rate": "22050"}, "sample_rate: must be a whole number"),
    ({"entries": "x"}, "entries: must be a list, found str"),
    ({"entries": [{"source_start_frame": 0, "source_end_frame": 5, "output_frame": 1e15, "gain": 1}]},
     "entry 0 is malformed (ValueError: output_frame: must be a whole number"),
])
def test_a_hand_edited_edl_is_refused_naming_its_key(tmp_path, edit, message):
    """``creatures images`` on an EDL with no rate, a rate in words or an entry a billion years
    out: a traceback (TypeError, KeyError), or numpy asked for 811 GiB of frames, before."""
    path = tmp_path / "bad.edl.json"
    document = {"sample_rate": SR, "creature": "x", "mix": {"gain": 1, "pan": 0},
                "entries": [{"source_start_frame": 0, "source_end_frame": 5, "output_frame": 0, "gain": 1}]}
    save_json(path, {**document, **edit}, kind="creature-music edl")
    with pytest.raises(ValueError) as caught:
        read_edl(path)
    assert str(caught.value).startswith(f"{path}: ") and message in str(caught.value)


def test_images_of_a_creature_without_an_edl_names_the_nearest(tmp_path, capsys):
    from creatures.cli import main

    save_json(tmp_path / "king.edl.json", {"sample_rate": SR, "creature": "king", "entries": []},
              kind="creature-music edl")
    assert main(["images", str(tmp_path), "--creature", "kin"]) == 2
    assert f"{tmp_path}: no edit decision list of creature 'kin' (kin.edl.json) (did you mean 'king'?)" in \
        capsys.readouterr().err


def test_state_survives_a_save(reading, tmp_path):
    inst = load_installation(CONFIG)
    session = Session(inst, SimulatedClock(), EventLog(tmp_path / "a.jsonl"), MemorySink())
    x = load_audio(reading, samplerate=SR)
    frames = int(0.02 * SR)
    for k in range(1, int(20.0 / 0.02) + 1):
        session.clock.advance_to(k * 0.02)
        session.step(k * 0.02, frames, x[(k - 1) * frames : k * frames])
    creature = next(c for c in session.creatures if len(c.group.tuples) > 4)  # one that grew hypotheses
    saved = json.loads(json.dumps(creature.state()))
    again = Session(inst, SimulatedClock(), EventLog(tmp_path / "b.jsonl"), MemorySink()).creatures[0]
    again.restore(saved)
    assert [tp.name for tp in again.group.tuples] == [tp.name for tp in creature.group.tuples]
    assert [tp.value.to_float() for tp in again.group.tuples] == [tp.value.to_float() for tp in creature.group.tuples]
    assert [len(p.members) for p in again.root.walk()] == [len(p.members) for p in creature.root.walk()]



def test_parts_read_in_a_run_without_audio_are_not_kept(reading, tmp_path):
    """A run that renders no audio (``creatures rehearse``, an offline run with ``[output] wav
    = false``; the shipped config's air is off, so nothing else asks for its voice) never
    calls :meth:`Ozymandias.sound`, which is what starts queued parts. Each read's part was
    queued for ever: 148 parts over the three creatures in 20 s (each a view keeping its whole
    word's samples alive), some 26,000 an hour of a rehearsed gallery week."""
    inst = load_installation(CONFIG)
    session = Session(inst, SimulatedClock(), EventLog(tmp_path / "a.jsonl"), MemorySink())
    x = load_audio(reading, samplerate=SR)
    frames = int(0.02 * SR)
    reads: list[str] = []
    emit = session.world.emit
    session.world.emit = lambda kind, **fields: (reads.append(fields["creature"]) if kind == "read" else None,
                                                 emit(kind, **fields))
    for k in range(1, int(20.0 / 0.02) + 1):
        session.clock.advance_to(k * 0.02)
        session.step(k * 0.02, frames, x[(k - 1) * frames : k * frames], audio=False)
    assert len(reads) > 100, "they read all the same"
    assert all(len(c._queued) <= 1 and not c._playing for c in session.creatures)


def test_a_run_that_writes_no_edl_keeps_none(reading, tmp_path):
    """Only an offline run writes ``<creature>.edl.json`` (its end asks each creature for its
    outputs); a live run kept every line of it for as long as it ran, some 8 a second over the
    shipped three, and never wrote it."""
    session = Session(load_installation(CONFIG), SimulatedClock(), EventLog(tmp_path / "a.jsonl"), MemorySink())
    x = load_audio(reading, samplerate=SR)
    frames = int(0.02 * SR)
    for k in range(1, int(20.0 / 0.02) + 1):
        session.clock.advance_to(k * 0.02)
        session.step(k * 0.02, frames, x[(k - 1) * frames : k * frames])
    assert session.world.sounds_made > 10, "they read aloud all the same"
    assert all(c.edl == [] for c in session.creatures)


def late_readings(out: Path, *, clicking: bool) -> list[str]:
    """One creature hears "ai" and "oe" in turn for 300 s while the author clicks live (the
    reward route, :meth:`Ozymandias.reward`) whenever it starts reading part of an "ai"
    (unless not ``clicking``): the word class of each reading in the last third of the run."""
    inst = load_installation(CONFIG)
    inst.specs = inst.specs[:1]
    inst.specs[0].clicks = []
    length = 300.0
    log = EventLog(out / "events.jsonl")
    session = Session(inst, SimulatedClock(), log, MemorySink())
    creature = session.creatures[0]
    x, spans = alternating_words(("ai", "oe"), length, seed=2, length=length)
    words = [(a - 0.1, b + 0.1, ("ai", "oe")[k % 2]) for k, (a, b) in enumerate(spans)]
    reads: list[tuple[float, str]] = []
    emit = session.world.emit

    def click(kind: str, **fields) -> None:
        emit(kind, **fields)
        if kind == "read":
            middle = fields["source_start"] + fields["length"] / 2
            heard = next((c for a, b, c in words if a <= middle <= b), None)
            t = session.clock.now()
            if heard is not None:
                reads.append((t, heard))
            if heard == "ai" and clicking:
                creature.reward(creature.spec.click_value, t, 0.5, creature.group.alpha)

    session.world.emit = click
    tick = inst.settings.tick
    frames = int(tick * SR)
    for k in range(1, int(length / tick)):
        session.clock.advance_to(k * tick)
        session.step(k * tick, frames, x[(k - 1) * frames : k * frames])
    return [c for t, c in reads if t > 2 * length / 3]


@pytest.fixture(scope="module")
def clicked_readings(tmp_path_factory) -> list[str]:
    return late_readings(tmp_path_factory.mktemp("clicked"), clicking=True)


def test_without_clicks_reading_stays_even(tmp_path):
    """The control: unclicked, the same creature reads both classes alike (measured: 66 of
    122 late readings are "ai", 54 %; 133 of 268 before ``listen`` grounded the values), so
    the narrowing below is the clicks' doing. With the config's seed set to 1…11 it is 40-62 %
    (mean 51 %): once ``read`` and ``echo`` are refined away every reading is a class
    reader's, and the ~130 late ones lean by chance (48-56 % on seven seeds before)."""
    late = late_readings(tmp_path, clicking=False)
    assert abs(late.count("ai") / len(late) - 0.5) <= 0.08


def test_reading_narrows_toward_the_clicked_word_class(clicked_readings):
    """Clicked for "ai", the creature reads "ai" well above the even chance of the control
    (measured: 453 of 583 late readings, 78 %)."""
    assert len(clicked_readings) >= 100
    assert clicked_readings.count("ai") >= 0.6 * len(clicked_readings)


def test_reading_narrows_to_the_clicked_word_class(clicked_readings):
    """The thesis's claim ("ozymandias (video)": trained by the author's clicks): at least
    70 % of the late readings are of the clicked class (78 % here, 71-78 % with the config's
    seed set to 1…11). Issue 20: it stopped at 64 % while ``read`` and ``echo``, reading every
    class, kept a third of the readings beside the classes' own readers (now refined away,
    ``AuralLearning(refine=True)``) and while a click could lose its interruption to another
    reading (now ``CLICK_SALIENCE``)."""
    assert clicked_readings.count("ai") >= 0.7 * len(clicked_readings)
