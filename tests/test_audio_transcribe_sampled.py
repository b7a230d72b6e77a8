"""Transcription of audio made by a real sampler (fluidsynth, Debian's GM soundfont), scored
with mir_eval's note F1 (onset within 50 ms, pitch within 50 cents, no offset criterion).

Each case generates its MIDI (seeded), renders it, optionally puts it in a room (reverb and
noise), streams it through :class:`audio.transcribe.Transcriber` in 20 ms blocks and scores
the notes it heard (with the durations it measured). The floors asserted are the measured F1
less a margin (docs/hearing.md has the table, and the issue's targets beside them).
"""

from __future__ import annotations

import numpy as np
import pytest

from audio.transcribe import LIVE, OFFLINE, QUICK, Transcriber
from bench._sampled import (RANGES, answer_delays, chorale, given_times, have_sampler, note_f1, random_texture, render,
                            room)

pytest.importorskip("mir_eval")
pytestmark = pytest.mark.skipif(not have_sampler(), reason="needs fluidsynth and fluid-soundfont-gm")

TEXTURES = {"random": random_texture, "chorale": chorale}


def transcribe(audio: np.ndarray, rate: int, look: str = OFFLINE) -> list[tuple[float, float, int]]:
    ear = Transcriber(rate, look=look)
    ear.ended = type(ear.ended)()  # unbounded: the test wants every note
    block = rate // 50
    for i in range(0, len(audio), block):
        ear.feed(audio[i:i + block])
    ear.flush()
    return [(n.time, n.end, n.pitch) for n in ear.ended]


def played(instrument: str, voices: int, texture: str, rate: int, *, in_room: bool = False,
           seed: int = 0) -> tuple[list, np.ndarray]:
    """A case's notes and its render (mono), seeded by the case."""
    low, high = RANGES[instrument]
    rng = np.random.default_rng([seed, voices, len(instrument), len(texture)])
    notes = TEXTURES[texture](rng, voices, 20.0, low, high)
    audio = render(notes, instrument, rate)
    if in_room:
        audio = room(audio, rate, rng)
    return notes, audio.mean(axis=1)


def score(instrument: str, voices: int, texture: str, rate: int, *, in_room: bool = False,
          look: str = OFFLINE, seed: int = 0) -> float:
    notes, audio = played(instrument, voices, texture, rate, in_room=in_room, seed=seed)
    return note_f1(notes, transcribe(audio, rate, look))


def delays(instrument: str, voices: int, texture: str, look: str = LIVE) -> tuple[np.ndarray, int]:
    """Milliseconds from each heard note's MIDI onset to its note event, streamed at 44.1 kHz in
    64-frame blocks (a short JACK period); and how many notes were played."""
    notes, audio = played(instrument, voices, texture, 44100)
    return 1e3 * answer_delays(notes, given_times(Transcriber(44100, look=look), audio, 44100)), len(notes)


CASES = [
    # instrument, voices, texture, rate, in a room, floor: the issue's target where it is met,
    # else what was measured (deterministic: seeded MIDI, one soundfont, one model) less 0.05;
    # docs/hearing.md has every texture beside each ear alone and basic-pitch's model.
    # Measured with the offline committee of two models and the noise floor's slower rise
    # (audio/logspectrum.FLOOR_RISE 1.0025, 2026-12-07; before it, with 1.01: in brackets).
    ("piano", 1, "random", 22050, False, 0.9),  # measured 1.000 (1.000)
    ("piano", 1, "random", 44100, True, 0.9),  # 0.986 (0.986)
    ("piano", 4, "random", 44100, False, 0.75),  # 0.899 (0.913)
    ("piano", 4, "random", 16000, True, 0.75),  # 0.904 (0.908)
    ("piano", 4, "chorale", 22050, False, 0.67),  # 0.726 (0.721; target 0.75: below)
    ("piano", 4, "chorale", 48000, True, 0.65),  # 0.718 (0.706)
    ("guitar", 1, "random", 48000, False, 0.9),  # 0.960 (0.960)
    ("guitar", 3, "chorale", 22050, True, 0.75),  # 0.914 (0.906)
    ("flute", 1, "random", 44100, False, 0.9),  # 1.000 (1.000)
    ("strings", 1, "random", 22050, False, 0.6),  # 0.912 (0.912)
    ("strings", 3, "chorale", 44100, True, 0.6),  # 0.636 (0.599, below the target; 0.374 before the slow swell)
    ("organ", 1, "random", 22050, False, 0.36),  # 0.413 (0.417; target 0.6: below)
    ("organ", 3, "chorale", 96000, False, 0.39),  # 0.484 (0.448)
]


@pytest.mark.slow
@pytest.mark.parametrize("instrument, voices, texture, rate, in_room, floor", CASES,
                         ids=[f"{c[0]}-{c[1]}v-{c[2]}-{c[3]}{'-room' if c[4] else ''}" for c in CASES])
def test_note_f1_on_sampled_instruments(instrument: str, voices: int, texture: str, rate: int, in_room: bool,
                                        floor: float) -> None:
    f1 = score(instrument, voices, texture, rate, in_room=in_room)
    print(f"{instrument} {voices}v {texture} {rate} Hz{' room' if in_room else ''}: F1 {f1:.3f}")
    assert f1 >= floor


UNMET = [
    # the issue's targets not reached: strict, so one that starts to pass fails, to be moved up
    ("piano", 4, "chorale", 22050, False, 0.75, "block chords with octave doublings: 0.726"),
    ("organ", 1, "random", 22050, False, 0.6, "FluidR3's organ is 4'-heavy, its octave is heard: 0.413"),
]


@pytest.mark.slow
@pytest.mark.parametrize("instrument, voices, texture, rate, in_room, target", [
    pytest.param(*case[:6], marks=pytest.mark.xfail(strict=True, reason=f"issue 18: {case[6]}"),
                 id=f"{case[0]}-{case[1]}v-{case[2]}") for case in UNMET])
def test_the_issue_s_targets_not_yet_met(instrument: str, voices: int, texture: str, rate: int, in_room: bool,
                                         target: float) -> None:
    assert score(instrument, voices, texture, rate, in_room=in_room) >= target


@pytest.mark.slow
def test_the_live_look_hears_piano_lines_and_chords_and_a_flute() -> None:
    """The live path's look (a struck note 3 hops past the hop it is named in) hears sampled piano
    and a flute too."""
    mono = score("piano", 1, "random", 44100, look=LIVE)
    four = score("piano", 4, "random", 44100, look=LIVE)
    flute = score("flute", 1, "random", 44100, look=LIVE)
    print(f"live look: piano 1 voice F1 {mono:.3f}, 4 voices {four:.3f}, flute {flute:.3f}")
    assert mono >= 0.9 and four >= 0.75 and flute >= 0.9  # measured 1.000, 0.855 and 0.973 (0.847 at FLOOR_RISE 1.01)


@pytest.mark.slow
def test_the_quick_look_hears_piano_lines_and_chords_and_a_flute() -> None:
    """The quick look (≤ 30 ms from a struck onset to its note event on the generated phrases, a
    model on a finer hop) is made for struck instruments: it hears sampled piano lines and chords
    to the issue's targets, and a flute line too. (It hears string chords poorly: docs/hearing.md.)"""
    mono = score("piano", 1, "random", 44100, look=QUICK)
    four = score("piano", 4, "random", 44100, look=QUICK)
    flute = score("flute", 1, "random", 44100, look=QUICK)
    print(f"quick look: piano 1 voice F1 {mono:.3f}, 4 voices {four:.3f}, flute {flute:.3f}")
    assert mono >= 0.9 and four >= 0.75  # measured 0.987 and 0.830 (0.807 at FLOOR_RISE 1.01)
    assert flute >= 0.9  # measured 0.930 (0.866 before SLOW_RISE_SHORT)


@pytest.mark.slow
def test_either_ear_dates_a_note_in_the_hop_its_attack_began() -> None:
    """The two ears tell one rhythm in one time: the onset ear's notes are dated a hop before
    its onset frame (``audio.onset_ear.LEAD``), where the attack began, as the model's are.
    Dated at the onset frame they were 15.8, 16.0 and 17.1 ms after their MIDI onsets (p50)."""
    for instrument, voices, texture, rate in (("piano", 1, "random", 22050), ("guitar", 1, "random", 48000),
                                              ("piano", 4, "chorale", 22050)):
        notes, audio = played(instrument, voices, texture, rate)
        dated = 1e3 * answer_delays(notes, [(t, p, t) for t, _, p in transcribe(audio, rate)])
        print(f"{instrument} {voices}v {texture}: dated p50 {np.median(dated):.1f} ms after the onset")
        assert len(dated) >= 0.5 * len(notes)  # heard, and so dated
        assert abs(np.median(dated)) <= 10  # measured 4.2, 4.4 and 6.2 ms


@pytest.mark.slow
def test_the_live_look_gives_nine_in_ten_struck_notes_of_a_line_within_60_ms() -> None:
    """The issue's ≤ 60 ms from an onset to its note event, on sampled lines: a struck note is
    given 3 hops after the hop the model names it in (its attack's, mostly; a hop or two later
    for a few notes), the time measured from the MIDI onset to the block that gave the note."""
    piano, played_piano = delays("piano", 1, "random")
    guitar, played_guitar = delays("guitar", 1, "random")
    print(f"live look, ms from onset to note: piano line p50 {np.median(piano):.1f} p90 "
          f"{np.percentile(piano, 90):.1f} max {piano.max():.1f}; guitar line p50 {np.median(guitar):.1f} "
          f"max {guitar.max():.1f}")
    assert len(piano) >= 0.9 * played_piano and len(guitar) >= 0.9 * played_guitar  # heard, not silent
    assert np.percentile(piano, 90) <= 60  # measured 57.6 (p50 45.8, max 65.1: one note a hop late)
    assert guitar.max() <= 60  # measured 56.9 (p50 45.6)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, raises=AssertionError,
                   reason="issue 18: a chord's notes come later (4 voices: 81 % within 60 ms, p90 63.8 ms, "
                          "the latest 116.6 ms)")
def test_the_live_look_gives_every_note_of_a_chord_within_60_ms() -> None:
    """Not met: in chords the model gives some notes by its swell rules, hops after their attack,
    and those it does not name come from the onset ear, whose look is a hop longer
    (docs/hearing.md, "Live latency")."""
    four, played_four = delays("piano", 4, "random")
    if len(four) < 0.75 * played_four:  # measured 127 of 158; not the failure expected
        raise RuntimeError(f"heard {len(four)} of {played_four} notes: too few to time")
    assert four.max() <= 60


@pytest.mark.slow
def test_the_live_look_does_not_give_a_bright_note_s_partials_as_notes() -> None:
    """Live, the model's notes cannot wait for the onset ear's, so a guitar's octave and twelfth
    were given beside its note; a model's note at a partial of its own lower note is now that
    note's partial (``OWN_PARTIAL``) unless a chord began (``CHORD``)."""
    line = score("guitar", 1, "random", 48000, look=LIVE)
    chorale = score("guitar", 3, "chorale", 22050, in_room=True, look=LIVE)
    print(f"live look: guitar line F1 {line:.3f}, guitar chorale in a room {chorale:.3f}")
    # measured 0.960: the issue's 0.9 for a line, met live since the live threshold was tuned again
    # with the slow swell (2026-12-06; 0.857 before, 0.766 before the rule; the onset ear alone 0.873)
    assert line >= 0.9
    assert chorale >= 0.78  # measured 0.909 (0.902 at FLOOR_RISE 1.01, 0.778 before the rule): its chords are kept


def test_a_silent_or_random_transcriber_would_fail() -> None:
    """The metric itself: no notes score 0, notes at random pitches score near 0."""
    rng = np.random.default_rng(1)
    notes = random_texture(rng, 2, 10.0, 40, 80)
    assert note_f1(notes, []) == 0.0
    guesses = [(n.onset, n.offset, int(rng.integers(40, 80))) for n in notes]
    assert note_f1(notes, guesses) < 0.2
    assert note_f1(notes, [(n.onset + 0.01, n.offset, n.pitch) for n in notes]) == 1.0


def test_a_missing_soundfont_is_an_error_not_another_sampler_s_sound(monkeypatch: pytest.MonkeyPatch,
                                                                       tmp_path) -> None:
    """fluidsynth renders a missing soundfont's MIDI through its default one (FluidR3 here) and
    says so only on stderr; a tuning set made so would be the tests' sampler. Nor may a render
    through one soundfont be served from the cache for another."""
    notes = random_texture(np.random.default_rng(5), 1, 2.0, 60, 72)
    assert np.abs(render(notes, "piano", 16000)).max() > 0.01
    missing = tmp_path / "TimGM6mb.sf2"
    monkeypatch.setattr("bench._sampled.SOUNDFONT", missing)
    with pytest.raises(FileNotFoundError, match="TimGM6mb.sf2: no such soundfont"):
        render(notes, "piano", 16000)
