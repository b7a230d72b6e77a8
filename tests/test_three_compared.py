"""The thesis's comparison (three creatures (performance)): the shipped
``three_creatures_compared`` room, two null-hypothesis creatures and two behaviour-system
sound creatures in one air, played by one performer over several seeds.

The thesis says the null hypothesis lacks "an illusion of intelligence" and "perceptual
abilities", and that the soundcreatures are "learning what sounds they need to produce in
order to hear sounds back". Each claim gets a measure that a singer choosing at random
scores at chance, so a difference in it is a difference in character, not in loudness:

* **contingency** (perception): each song and each of the performer's words is classed as
  one of two word kinds ("ai"/"ua", nearest template: :func:`halves`); ``Δp = P(song ai |
  latest word ai) − P(song ai | latest word ua)``, the latest word a call or an answer alike
  (both are the performer's words, each of a random kind; no creature can tell them apart, and
  against the latest call alone a song answering the performer's answer counts as answering
  the call before it). Not raw agreement or profile correlation: any two vowel-like sounds
  correlate, and a singer stuck on one kind agrees half the time with random words; Δp is 0
  for every singer whose choice ignores the words (fixed, random or biased) and 1 for a
  perfect echo. Computed within each run (pooling runs whose repertoires lean to different
  kinds made a spurious Δp of 0.3 out of repertoire drift: Simpson's paradox).
* **learning** (credit): the performer answers every song of one kind ("ai") and never
  the other; the share of "ai" songs in the last third of a creature's songs minus the first.
* **persistence** (action selection): the share of songs of the kind of the creature's
  previous song, minus the same share with its songs shuffled in time (each creature's own
  mix of kinds sets the chance level).

Controls show each measure bites (an echo singer scores Δp 1, shuffled songs score 0, a
singer drifting to the answered kind scores as learning). What separates the two kinds and
what does not is asserted or, where it does not hold robustly over the seeds, only printed
and written down in README.md ("three creatures: the score computer and the comparison").
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from audio.formants import word
from audio.utterance import Utterance
from audio_fixtures import SR, warm_librosa  # noqa: F401
from creatures.clock import SimulatedClock
from creatures.events import EventLog, read_events
from creatures.kinds.hearing_parts import Mouth
from creatures.kinds.three_creatures import PROFILE, SAME, correlations, profile
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.sinks import MemorySink

pytestmark = pytest.mark.usefixtures("warm_librosa")

ROOM = Path(__file__).resolve().parents[1] / "installations" / "three_creatures_compared.toml"
KINDS = ("ai", "ua")
FAVOURITE = 0  # the performer answers songs of KINDS[FAVOURITE]
LENGTH = 60.0  # simulated seconds per run
SEEDS = tuple(range(3, 11))  # installation seed; the performer's is seed + 100
TICK = 0.02
ANSWER = 3.0  # a song starting this long after a call ends answers it (answer rate)
REPLY = 0.3  # the performer answers this long after a favoured song ends
NULL, BEHAVIOUR = ("left", "right"), ("parrot", "mynah")


def say(kind: str, rng: np.random.Generator) -> np.ndarray:
    return word(kind, rng, SR, stretch=rng.uniform(0.9, 1.1), f0=rng.uniform(110, 140), rms=0.05).astype(np.float32)


def halves(samples: np.ndarray) -> np.ndarray:
    """The profiles of a sound's first and second halves, end to end. The word kinds share an
    "a" and differ in order ("ai" begins like "a", "ua" like "u"): the whole-sound profile
    the null creatures correlate rates them alike (0.90 between the kinds, 0.92 within, on
    twenty of each) and classes 63–70 % of them right; the halves class all of them."""
    h = len(samples) // 2
    return np.r_[profile(samples[:h], SR), profile(samples[h:], SR)]


@pytest.fixture(scope="module")
def templates() -> np.ndarray:
    """Each word kind's mean :func:`halves` over eight words of an RNG the performer never uses."""
    rng = np.random.default_rng(1000)
    return np.array([np.mean([halves(say(k, rng)) for _ in range(8)], axis=0) for k in KINDS])


def kind_of(samples: np.ndarray, templates: np.ndarray) -> int:
    """The word kind whose template is nearest (squared distance)."""
    return int(np.argmin(((templates - halves(samples)) ** 2).sum(axis=1)))


@dataclass
class Played:
    """One run: the performer's calls (start, end, kind), every word it said, calls and
    answers (end, kind, profile), each creature's songs (start, kind, profile), and how often
    each behaviour creature selected each tuple."""

    calls: list[tuple[float, float, int]] = field(default_factory=list)
    selected: dict[tuple[str, str], int] = field(default_factory=dict)  # (creature, tuple): selections
    words: list[tuple[float, int, np.ndarray]] = field(default_factory=list)
    songs: dict[str, list[tuple[float, int, np.ndarray]]] = field(default_factory=dict)


class Performer:
    """Calls a word of a random kind every 2.5–4.5 s, and answers (a word of a random kind,
    so the room's repertoire is not tilted) every song of the favoured kind that ends while
    it is free. It writes into the input signal ahead of the clock."""

    def __init__(self, rng: np.random.Generator, templates: np.ndarray, played: Played) -> None:
        self.rng, self.templates, self.played = rng, templates, played
        self.signal = np.zeros(int((LENGTH + 5) * SR), np.float32)
        self.next_call, self.busy_until = 1.0, 0.0

    def _say(self, t: float, kind: int) -> float:
        w = say(KINDS[kind], self.rng)
        i = int(t * SR)
        self.signal[i: i + len(w)] += w
        self.busy_until = t + len(w) / SR
        self.played.words.append((self.busy_until, kind, profile(w, SR)))
        return self.busy_until

    def tick(self, t: float) -> None:
        if t >= self.next_call and t >= self.busy_until and t < LENGTH - 2:
            kind = int(self.rng.integers(2))
            end = self._say(t, kind)
            self.played.calls.append((t, end, kind))
            self.next_call = end + self.rng.uniform(2.5, 4.5)

    def sang(self, creature: str, t: float, end: float, samples: np.ndarray) -> None:
        p = profile(samples, SR)
        kind = kind_of(samples, self.templates)
        self.played.songs.setdefault(creature, []).append((t, kind, p))
        reply = end + REPLY
        if kind == FAVOURITE and reply >= self.busy_until and reply < self.next_call and reply < LENGTH - 1:
            self._say(reply, int(self.rng.integers(2)))


def play(seed: int, templates: np.ndarray, tmp: Path) -> Played:
    """The shipped room (its seed replaced) for LENGTH s of the performer."""
    inst = load_installation(ROOM)
    inst.settings.seed = seed
    inst.settings.output.report = False
    session = Session(inst, SimulatedClock(), EventLog(tmp / "events.jsonl"), MemorySink())
    played = Played()
    performer = Performer(np.random.default_rng(seed + 100), templates, played)
    names = {id(getattr(c, "mouth", None) or c.aural.mouth): c.name for c in session.creatures}
    original = Mouth.sing

    def sing(self: Mouth, t: float, utterance: Utterance, gain: float = 1.0) -> float:  # each mouth's songs
        end = original(self, t, utterance, gain)
        performer.sang(names[id(self)], t, end, utterance.samples)
        return end

    frames = int(TICK * SR)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Mouth, "sing", sing)
        for k in range(1, int(LENGTH / TICK) + 1):
            t = k * TICK
            performer.tick(t)
            session.clock.advance_to(t)
            session.step(t, frames, performer.signal[(k - 1) * frames: k * frames])
    session.close()
    session.log.close()
    events = read_events(tmp / "events.jsonl")
    assert {e["creature"] for e in events if e["kind"] == "sound"} >= {*NULL, *BEHAVIOUR}, "every creature hears"
    for e in events:
        if e["kind"] == "selection" and e["creature"] in BEHAVIOUR:
            key = (e["creature"], e["tuple"])
            played.selected[key] = played.selected.get(key, 0) + 1
    return played


@pytest.fixture(scope="module")
def runs(tmp_path_factory, templates) -> list[Played]:
    return [play(seed, templates, tmp_path_factory.mktemp(f"seed{seed}")) for seed in SEEDS]


# -- the measures -------------------------------------------------------------------------------
def latest(said: list[tuple[float, int]], starts: np.ndarray) -> np.ndarray:
    """The kind of the latest of the performer's ``said`` (end, kind) ended before each start
    (-1: none yet)."""
    ends = np.array([end for end, _ in said])
    kinds = np.array([kind for _, kind in said])
    i = np.searchsorted(ends, starts, side="right") - 1
    return np.where(i >= 0, kinds[np.maximum(i, 0)], -1)


def words_of(played: Played) -> list[tuple[float, int]]:
    """(end, kind) of each word the performer said, calls and answers."""
    return [(end, kind) for end, kind, _ in played.words]


def calls_of(played: Played) -> list[tuple[float, int]]:
    """(end, kind) of each call."""
    return [(end, kind) for _, end, kind in played.calls]


def contingency(calls: np.ndarray, songs: np.ndarray) -> float:
    """Δp: P(song is kind 0 | latest call kind 0) − P(song is kind 0 | latest call kind 1)."""
    a, b = songs[calls == 0], songs[calls == 1]
    if len(a) == 0 or len(b) == 0:
        return np.nan
    return float(np.mean(a == 0) - np.mean(b == 0))


def learning(songs: np.ndarray) -> float:
    """Share of favoured songs in the last third of the run's songs minus in the first."""
    third = len(songs) // 3
    return float(np.mean(songs[-third:] == FAVOURITE) - np.mean(songs[:third] == FAVOURITE)) if third else np.nan


def persistence(songs: np.ndarray, rng: np.random.Generator) -> float:
    """Share of songs of the previous song's kind, above that of the same songs shuffled."""
    if len(songs) < 3:
        return np.nan
    same = float(np.mean(songs[1:] == songs[:-1]))
    shuffled = [rng.permutation(songs) for _ in range(50)]
    return same - float(np.mean([np.mean(s[1:] == s[:-1]) for s in shuffled]))


def measures(played: Played, creature: str, rng: np.random.Generator) -> dict[str, float]:
    songs = played.songs.get(creature, [])
    starts = np.array([t for t, _, _ in songs])
    kinds = np.array([k for _, k, _ in songs])
    words, calls = latest(words_of(played), starts), latest(calls_of(played), starts)
    answered = sum(bool(((starts > end) & (starts <= end + ANSWER)).any()) for _, end, _ in played.calls)
    word_ends = np.array([end for end, _, _ in played.words])
    in_kind = []
    for t, _, p in songs:
        i = np.searchsorted(word_ends, t, side="right") - 1
        if i >= 0:
            in_kind.append(float(correlations(p, played.words[i][2][None])[0]))
    repeats = [float(correlations(b, a[None])[0]) > SAME for (_, _, a), (_, _, b) in zip(songs, songs[1:])]
    return {"songs": len(songs), "answer_rate": answered / len(played.calls),
            "in_kind": float(np.mean(in_kind)) if in_kind else np.nan,
            "repetition": float(np.mean(repeats)) if repeats else np.nan,
            "contingency": contingency(words[words >= 0], kinds[words >= 0]),
            "call_contingency": contingency(calls[calls >= 0], kinds[calls >= 0]),
            "learning": learning(kinds), "persistence": persistence(kinds, rng)}


def table(runs: list[Played]) -> dict[str, dict[str, np.ndarray]]:
    """Each measure of each kind of creature, one value per creature and run."""
    rng = np.random.default_rng(0)
    out = {}
    for group, names in (("null", NULL), ("behaviour", BEHAVIOUR)):
        rows = [measures(played, c, rng) for played in runs for c in names]
        out[group] = {k: np.array([r[k] for r in rows], dtype=float) for k in rows[0]}
    return out


# -- the controls: each measure bites -----------------------------------------------------------
def test_the_null_metric_hears_the_two_word_kinds_as_one_sound(templates):
    """Why the word kinds are told apart by :func:`halves` and not by the null creatures'
    correlation: their whole-sound profiles correlate above SAME across the kinds, about as
    much as within one (the thesis: the data flow is "at too high a level … to construct any
    perceptual abilities"), while the halves class every word right."""
    rng = np.random.default_rng(77)
    words = {k: [say(kind, rng) for _ in range(20)] for k, kind in enumerate(KINDS)}
    p = {k: np.array([profile(w, SR) for w in ws]) for k, ws in words.items()}
    within = np.mean([(p[k] @ p[k].T / PROFILE)[np.triu_indices(20, 1)].mean() for k in p])
    between = float((p[0] @ p[1].T / PROFILE).mean())
    assert between > SAME and within - between < 0.05
    for k, ws in words.items():
        assert all(kind_of(w, templates) == k for w in ws), f"'{KINDS[k]}' words are classed as '{KINDS[k]}'"


def test_contingency_scores_an_echo_and_not_a_shuffle(runs):
    """On the real words and song times: a singer echoing the latest word scores 1; each
    creature's own songs shuffled among its song times score 0 (mean over runs)."""
    rng = np.random.default_rng(1)
    shuffled = []
    for played in runs:
        for songs in played.songs.values():
            starts, kinds = np.array([t for t, _, _ in songs]), np.array([k for _, k, _ in songs])
            words = latest(words_of(played), starts)
            kinds, words = kinds[words >= 0], words[words >= 0]
            if len(set(words)) == 2:
                assert contingency(words, words) == 1.0
                shuffled.append(np.nanmean([contingency(words, rng.permutation(kinds)) for _ in range(20)]))
    print("contingency of shuffled songs", round(float(np.nanmean(shuffled)), 3))
    assert len(shuffled) >= len(runs)
    assert abs(np.nanmean(shuffled)) < 0.05


def test_learning_scores_a_drift_to_the_answered_kind_and_not_a_shuffle(runs):
    """A singer whose chance of the favoured kind rises from ½ to 1 over its songs scores
    about ⅓; real songs shuffled in time score 0 (mean over creatures and runs)."""
    rng = np.random.default_rng(2)
    drifting, shuffled = [], []
    for played in runs:
        for songs in played.songs.values():
            kinds = np.array([k for _, k, _ in songs])
            rising = np.linspace(0.5, 1.0, len(kinds))
            drifting.append(learning(np.where(rng.random(len(kinds)) < rising, FAVOURITE, 1 - FAVOURITE)))
            shuffled.append(np.nanmean([learning(rng.permutation(kinds)) for _ in range(20)]))
    print("learning of a drifting singer", round(float(np.nanmean(drifting)), 3),
          "of shuffled songs", round(float(np.nanmean(shuffled)), 3))
    assert np.nanmean(drifting) > 0.25
    assert abs(np.nanmean(shuffled)) < 0.05


# -- the comparison -----------------------------------------------------------------------------
def songs_by_tuple(runs: list[Played], name: str) -> dict[str, int]:
    """How often behaviour creature ``name`` chose each kind of singing tuple over ``runs``:
    ``answer`` (any sound, before its tree had classes), an answer in kind (a class's), or a
    song into a silence (``sing``, then the tuples it refined into, one per class)."""
    counts = {"answer": 0, "in kind": 0, "into a silence": 0}
    for played in runs:
        for (creature, tuple_), n in played.selected.items():
            if creature == name and tuple_ not in ("attend", "rest"):
                kind = "answer" if tuple_ == "answer" else "in kind" if tuple_.startswith("any sound/") \
                    else "into a silence"
                counts[kind] += n
    return counts


def test_the_two_kinds_compared(runs):
    """Printed (``-s``) and recorded in README.md. Asserted: only what held on each of three
    disjoint sets of eight seeds (3–10, 11–18, 19–26). The behaviour creatures answer the
    performer's word in kind (contingency 0.20, 0.20, 0.23; the null's −0.06, 0.02, 0.07);
    against the latest call alone the difference does not hold (0.03, 0.07, 0.13 against
    −0.02, 0.02, 0.08), since a song answering the performer's answer to a song counts there
    as answering the call before it, so that is printed only."""
    measured = table(runs)
    for group, m in measured.items():
        print(group, {k: f"{np.nanmean(v):.2f}±{np.nanstd(v) / np.sqrt(np.isfinite(v).sum()):.2f}"
                      for k, v in m.items()})
    for name in BEHAVIOUR:
        print(name, "singing tuples chosen", songs_by_tuple(runs, name))
    null, behaviour = measured["null"], measured["behaviour"]
    assert (null["songs"] >= 3).all() and (behaviour["songs"] >= 3).all(), "every creature sings in every run"
    # They answer the word they heard in kind, the null creatures do not (Δp above the null's
    # by 0.26, 0.18, 0.16 over the three sets; one creature-run's Δp has a spread of ~0.2) …
    assert np.nanmean(behaviour["contingency"]) > 0.15
    assert np.nanmean(behaviour["contingency"]) > np.nanmean(null["contingency"]) + 0.1
    # … drift toward the kind of song the performer answers more than the null creatures do
    # (by 0.24, 0.18, 0.11; the room's repertoire drifts with everyone's songs, so the drift
    # of either kind alone is not reliably above 0) …
    assert np.nanmean(behaviour["learning"]) > np.nanmean(null["learning"]) + 0.05
    # … and sing more often (1.19, 1.35, 1.31×: answering what they recognise and singing
    # into silences when they want to hear, where they sang 1.7–2.1× before they answered).
    assert behaviour["songs"].mean() > 1.1 * null["songs"].mean()
