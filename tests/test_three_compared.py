"""The thesis's comparison (three creatures (performance)): the shipped
``three_creatures_compared`` room, null-hypothesis creatures and behaviour-system sound
creatures side by side, measured on one performer's input. The numbers are printed
(``-s``) and recorded in the README; the assertions hold what each measure must show for
the comparison to mean anything, not which side wins."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile

from audio.formants import word
from audio_fixtures import SR, warm_librosa  # noqa: F401
from creatures.events import read_events
from creatures.kinds.hearing_parts import Mouth
from creatures.kinds.three_creatures import SAME, correlations, profile
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation

pytestmark = pytest.mark.usefixtures("warm_librosa")

LENGTH = 45.0  # simulated seconds
ANSWER = 3.0  # a song starting this long after a performer's word ends answers it
NULL, BEHAVIOUR = ("left", "right"), ("parrot", "mynah")


def performer(rng: np.random.Generator) -> tuple[np.ndarray, list[tuple[float, np.ndarray]]]:
    """Words of two kinds ("ai", "ua"), one every 2.5–4.5 s; the signal and (end, samples)."""
    x, words, t = np.zeros(int(LENGTH * SR), np.float32), [], 1.0
    while t < LENGTH - 2:
        w = word(str(rng.choice(["ai", "ua"])), rng, SR, stretch=rng.uniform(0.9, 1.1),
                 f0=rng.uniform(110, 140), rms=0.05)
        x[int(t * SR): int(t * SR) + len(w)] += w
        words.append((t + len(w) / SR, w))
        t += len(w) / SR + rng.uniform(2.5, 4.5)
    return x, words


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    base = tmp_path_factory.mktemp("compared")
    signal, words = performer(np.random.default_rng(8))
    soundfile.write(base / "performer.wav", signal, SR, subtype="FLOAT")
    sung: dict[tuple[int, float], np.ndarray] = {}
    original = Mouth.sing

    def recording(self, t, utterance, gain=1.0):  # what each mouth sings, by (mouth, time)
        sung[(id(self), round(t, 6))] = utterance.samples
        return original(self, t, utterance, gain)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Mouth, "sing", recording)
        run_offline(load_installation(Path("installations/three_creatures_compared.toml")), base / "out",
                    audio=base / "performer.wav", duration=LENGTH)
    events = read_events(base / "out" / "events.jsonl")
    by_time: dict[float, list[np.ndarray]] = {}
    for (_, t), samples in sung.items():
        by_time.setdefault(t, []).append(samples)
    return events, words, by_time


def measures(events, words, by_time, creature: str) -> dict[str, float]:
    """Answer rate, singing in kind (correlation of a song with the performer's latest word)
    and repetition (a song of the same kind of sound as the creature's previous song)."""
    songs = [e for e in events if e["kind"] == "sing" and e["creature"] == creature]
    starts = np.array([e["start"] for e in songs])
    answered = sum(bool(((starts > end) & (starts <= end + ANSWER)).any()) for end, _ in words)
    kinds, previous, repeats = [], None, []
    for e in songs:
        candidates = by_time.get(round(e["start"], 6), [])
        if len(candidates) != 1:
            continue  # two mouths sang at one tick: which is whose is not known
        p = profile(candidates[0], SR)
        before = [w for end, w in words if end <= e["start"]]
        if before:
            kinds.append(float(correlations(p, profile(before[-1], SR)[None])[0]))
        if previous is not None:
            repeats.append(float(correlations(p, previous[None])[0]) > SAME)
        previous = p
    return {"songs": len(songs), "answer_rate": answered / len(words),
            "in_kind": float(np.mean(kinds)) if kinds else np.nan,
            "in_kind_share": float(np.mean(np.array(kinds) > SAME)) if kinds else np.nan,
            "repetition": float(np.mean(repeats)) if repeats else np.nan}


def test_both_kinds_are_measured_on_the_same_input(compared):
    events, words, by_time = compared
    table = {c: measures(events, words, by_time, c) for c in (*NULL, *BEHAVIOUR)}
    for c, m in table.items():
        print(f"{c:7s} " + " ".join(f"{k}={v:.2f}" for k, v in m.items()))
    for group in (NULL, BEHAVIOUR):
        mean = {k: np.nanmean([table[c][k] for c in group]) for k in ("answer_rate", "in_kind", "repetition")}
        print(("null" if group is NULL else "behaviour"), {k: round(float(v), 2) for k, v in mean.items()})
    for c, m in table.items():
        assert m["songs"] >= 3, f"{c} sings in the room"
        assert -1.0 <= m["in_kind"] <= 1.0 and 0.0 <= m["answer_rate"] <= 1.0
    heard = {e["creature"] for e in events if e["kind"] == "sound"}
    assert heard >= {*NULL, *BEHAVIOUR}, "every creature hears the room"
