"""Utterance percept trees: collection, fission, fusion, evaluation, persistence
(audio/utterance.py)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from audio.cepstrum import N_CEPSTRA, WARPS
from audio.segment import SoundEvent
from audio.sources import load_audio
from audio.utterance import (
    UtterancePercept,
    Utterance,
    cluster_medoids,
    load_aural_model,
    save_aural_model,
)
from audio_fixtures import SR, WORDS, Recorder, recording, word, warm_librosa  # noqa: F401
from creatures.persist import StateFileError

pytestmark = pytest.mark.usefixtures("warm_librosa")


@dataclass
class Speaker:
    """Says words into the ear through WAV files, as a recording would bring them."""

    rng: np.random.Generator
    record: Recorder


@pytest.fixture
def speaker(rng: np.random.Generator, record: Recorder) -> Speaker:
    return Speaker(rng, record)


def heard(name: str, speaker: Speaker, t: float) -> Utterance:
    """An utterance of ``name`` that ended at ``t``, as the segmenter would deliver it."""
    rng = speaker.rng
    x = word(name, rng, stretch=rng.uniform(0.8, 1.25), f0=rng.uniform(100.0, 160.0))
    x = (x * 10 ** (rng.uniform(-12, 12) / 20)).astype(np.float32)
    x += np.float32(np.sqrt(np.mean(x**2)) * 0.1) * rng.standard_normal(len(x)).astype(np.float32)
    x = load_audio(speaker.record(x, subtype="FLOAT"))  # float WAV: +12 dB goes past full scale
    return Utterance.from_event(SoundEvent(t - len(x) / SR, t, x, SR, -20.0))


def rewarded(
    root: UtterancePercept, names: list[str], speaker: Speaker, *, start: float = 0.0
) -> dict[int, str]:
    """Hear each word, then reward the tuple that followed it 0.3 s later.

    Returns which word each collected utterance was (by object id), the test's ground truth.
    """
    truth = {}
    for i, name in enumerate(names):
        t = start + 2.0 * (i + 1)
        u = heard(name, speaker, t)
        truth[id(u)] = name
        root.hear(u)
        root.update(t + 0.3, 1.0)
    return truth


def grown_tree(speaker: Speaker, names: list[str]) -> tuple[UtterancePercept, dict[int, str]]:
    root = UtterancePercept()
    return root, rewarded(root, names, speaker)


def word_of(u: Utterance, truth: dict[int, str]) -> str:
    return truth[id(u)]


def test_root_responds_to_any_recent_sound(speaker: Speaker) -> None:
    root = UtterancePercept(memory=1.0)
    assert root.evaluate(0.0) == 0.0
    root.hear(heard("ai", speaker, 5.0))
    assert root.evaluate(5.5) == 1.0
    assert root.evaluate(6.5) == 0.0  # forgotten after `memory` seconds
    assert root.evaluate(4.0) == 0.0  # not heard yet


def test_only_rewarded_recent_sounds_are_collected(speaker: Speaker) -> None:
    root = UtterancePercept(memory=1.0)
    root.hear(heard("ai", speaker, 1.0))
    root.update(1.5, 0.0)  # no reward
    root.update(3.0, 1.0)  # rewarded, but the sound is too old to have led to it
    assert root.members == []
    root.update(1.5, 1.0)
    root.update(1.6, 1.0)  # the same sound is kept once
    assert len(root.members) == 1


def test_distinct_words_grow_one_child_each(speaker: Speaker) -> None:
    names = [WORDS[i % 3] for i in range(18)]
    root, truth = grown_tree(speaker, names)
    assert root.fission(value=0.4, innovation_threshold=0.5) == []  # not yet important
    born = root.fission(value=0.9, innovation_threshold=0.5)
    assert len(born) == 3 and root.children == born
    for child in born:
        assert len({word_of(u, truth) for u in child.members}) == 1, child.members
        assert len(child.members) == 6
    # A fresh utterance of each word is most like its own child.
    for name in WORDS[:3]:
        u = heard(name, speaker, 100.0)
        root.hear(u)
        scores = [c.evaluate(100.2) for c in born]
        best = born[int(np.argmax(scores))]
        assert word_of(best.medoid, truth) == name
        assert 0.5 < max(scores) <= 1.0 and sorted(scores)[-2] < 0.5


def test_a_nearest_tree_hears_each_sound_as_one_class_or_none(speaker: Speaker) -> None:
    """``nearest``: only the class a sound is nearest is salient (as much as without it), and
    only if the sound lies within the class's radius of an exemplar; a word of no class is
    heard by the root alone. Graded, the same words make every class somewhat salient."""
    root, truth = grown_tree(speaker, [WORDS[i % 3] for i in range(18)])
    born = root.fission(value=0.9, innovation_threshold=0.5)
    for t, name in enumerate([*WORDS[:3], "eao"], start=100):
        root.hear(heard(name, speaker, float(t)))
        root.nearest = False
        graded = [c.evaluate(t + 0.2) for c in born]
        root.nearest = True
        classified = [c.evaluate(t + 0.2) for c in born]
        assert root.evaluate(t + 0.2) == 1.0 and all(s > 0.0 for s in graded)
        if name == "eao":
            assert classified == [0.0, 0.0, 0.0] and max(graded) < 0.5
        else:
            own = next(k for k, c in enumerate(born) if word_of(c.medoid, truth) == name)
            assert classified == [graded[own] if k == own else 0.0 for k in range(3)]


def test_one_word_does_not_split(speaker: Speaker) -> None:
    root, _ = grown_tree(speaker, ["ieu"] * 15)
    assert root.fission(value=1.0, innovation_threshold=0.5) == []
    assert root.children == []


def test_a_recurring_word_is_a_class_at_the_root_and_no_new_class_below_it(speaker: Speaker) -> None:
    """One word heard again and again among others heard once: the root splits it off, a
    class of the same sounds does not split off its core (a chain of ever tighter cores grew
    16 classes deep in a rehearsed week of ozymandias)."""
    names = ["ai"] * 6 + ["ua", "ieu", "eao"]
    root, truth = grown_tree(speaker, names)
    (born,) = root.fission(1.0, 0.5)
    assert {word_of(u, truth) for u in born.members} == {"ai"}
    rewarded(born, names[6:] * 2, speaker, start=100.0)  # the class hears the other words too
    assert len(born.members) == 12
    assert born.fission(1.0, 0.5) == [] and born.children == []


def test_a_full_tree_grows_no_new_class_and_refreshes_those_it_has(speaker: Speaker) -> None:
    """``max_classes`` bounds the whole tree: three words make two classes, and a later
    clustering refreshes them but adds none."""
    root = UtterancePercept(max_classes=2)
    rewarded(root, [WORDS[i % 3] for i in range(18)], speaker)
    born = root.fission(value=0.9, innovation_threshold=0.5)
    assert len(born) == 2 and root.children == born
    rewarded(root, [WORDS[i % 3] for i in range(9)], speaker, start=100.0)
    assert root.fission(value=0.9, innovation_threshold=0.5) == [] and root.children == born
    assert [len(c.members) for c in born] == [9, 9]  # each class took its word's 3 new sounds


def test_new_word_adds_a_child_and_old_children_keep_identity(speaker: Speaker) -> None:
    root, truth = grown_tree(speaker, ["ai", "oe"] * 5)
    first = root.fission(1.0, 0.5)
    assert len(first) == 2
    rewarded(root, ["eao"] * 5, speaker, start=100.0)
    second = root.fission(1.0, 0.5)
    assert len(second) == 1 and len(root.children) == 3
    assert all(c in root.children for c in first)


def test_a_class_whose_medoid_moves_keeps_its_identity() -> None:
    """A class may span twice the radius, so re-clustering can make a sound farther than the
    radius from the old medoid the new one: the class is still the child most of whose
    exemplars it holds. (Sounds here are points on a line: one frame, every warp alike.)"""

    def sound(x: float) -> Utterance:
        features = np.zeros((len(WARPS), 1, N_CEPSTRA))
        features[:, :, 0] = x
        return Utterance(np.zeros(64, np.float32), SR, features, 0.0)

    root = UtterancePercept(radius=1.0)
    root.members = [sound(x) for x in (0.0, 0.2, 0.4, 10.0, 10.2, 10.4)]
    near, far = root.fission(1.0, 0.5)
    old_medoid = near.medoid
    root.members += [sound(x) for x in (1.2, 1.4, 1.6, 1.8)]
    assert root.fission(1.0, 0.5) == [] and root.children == [near, far]
    assert len(near.members) == 7 and near.medoid.features[0, 0, 0] == 1.2  # 1.0 from the old one
    assert old_medoid in near.members


def test_children_fuse_when_no_longer_distinct(speaker: Speaker) -> None:
    root, _ = grown_tree(speaker, ["ai", "ua"] * 6)
    assert len(root.fission(1.0, 0.5)) == 2
    root.radius = 1e6  # the creature's notion of "the same sound" widens
    removed = root.fusion()
    assert len(removed) == 1 and len(root.children) == 1
    assert len(root.children[0].members) == 12


def test_draw_gives_raw_samples_to_sing(speaker: Speaker) -> None:
    root, truth = grown_tree(speaker, ["ai", "oe"] * 4)
    child = root.fission(1.0, 0.5)[0]
    u = child.draw(speaker.rng)
    assert u in child.members and u.samples.dtype == np.float32 and len(u.samples) > SR // 4
    with pytest.raises(LookupError, match="no exemplars"):
        UtterancePercept("empty").draw(speaker.rng)


def test_cluster_medoids_on_a_known_matrix() -> None:
    points = np.array([0.0, 0.1, 0.2, 5.0, 5.1, 5.2, 5.3, 20.0])
    d = np.abs(points[:, None] - points[None, :])
    clusters = cluster_medoids(d, 0.5, max_clusters=5, min_members=2)
    assert [sorted(c.tolist()) for c in clusters] == [[3, 4, 5, 6], [0, 1, 2]]
    assert clusters[1][0] == 1  # the medoid comes first
    assert len(cluster_medoids(d, 0.5, max_clusters=1, min_members=2)) == 1


def test_save_and_reload_is_exact(speaker: Speaker, tmp_path: Path) -> None:
    root, _ = grown_tree(speaker, ["ai", "ua", "oe"] * 4)
    root.fission(1.0, 0.5)
    probe = heard("ua", speaker, 50.0)
    root.hear(probe)
    path = tmp_path / "ear.json"
    save_aural_model(root, path)
    again = load_aural_model(path)
    assert again.describe() == root.describe()
    for a, b in zip(root.walk(), again.walk()):
        assert (a.name, a.radius, a.memory) == (b.name, b.radius, b.memory)
        assert len(a.members) == len(b.members)
        for u, v in zip(a.members, b.members):
            np.testing.assert_array_equal(u.samples, v.samples)
            np.testing.assert_array_equal(u.features, v.features)
            assert (u.samplerate, u.time) == (v.samplerate, v.time)
        assert a.evaluate(50.1) == b.evaluate(50.1)
    # Shared utterances stay shared: the root's members are the children's objects.
    assert {id(u) for c in again.children for u in c.members} <= {id(u) for u in again.members}
    # A reloaded model seeds another creature that keeps learning.
    rewarded(again, ["eao"] * 4, speaker, start=100.0)
    assert len(again.fission(1.0, 0.5)) == 1


def test_an_empty_model_round_trips(tmp_path: Path) -> None:
    save_aural_model(UtterancePercept("quiet", radius=123.0), tmp_path / "blank.json")
    again = load_aural_model(tmp_path / "blank.json")
    assert (again.name, again.radius, again.members, again.children) == ("quiet", 123.0, [], [])


def test_a_model_saved_with_another_analysis_is_refused(speaker: Speaker, tmp_path: Path) -> None:
    """Distances and radii are in the units of the analysis that made them: a model saved with
    the MFCC analysis (no "features" key) or any other is refused, saying why."""
    root, _ = grown_tree(speaker, ["ai"] * 3)
    path = tmp_path / "ear.json"
    save_aural_model(root, path)
    doc = json.loads(path.read_text())
    for features in (None, "mfcc13-l22"):
        if features is None:
            doc.pop("features")
        else:
            doc["features"] = features
        path.write_text(json.dumps(doc))
        with pytest.raises(StateFileError, match="another cepstral analysis.*other units"):
            load_aural_model(path)


def test_damaged_model_files_are_named(speaker: Speaker, tmp_path: Path) -> None:
    root, _ = grown_tree(speaker, ["ai"] * 3)
    path = tmp_path / "ear.json"
    save_aural_model(root, path)
    doc = json.loads(path.read_text())
    doc["utterances"][0]["n_samples"] += 1
    path.write_text(json.dumps(doc))
    with pytest.raises(StateFileError, match="ear.npz.*do not match"):
        load_aural_model(path)
    path.with_suffix(".npz").unlink()
    with pytest.raises(StateFileError, match="ear.npz.*not found"):
        load_aural_model(path)


def test_pair_distances_warp_each_pair_once_and_keep_only_what_the_tree_holds(speaker, monkeypatch):
    """The cache of warped pairs gives distance_matrix's numbers, warps a pair seen before no
    more, and forgets pairs of sounds the tree no longer holds once it has grown (here at
    once: no slack)."""
    import audio.utterance as utterance
    from audio.cepstrum import distance_matrix

    sounds = [heard(name, speaker, 1.0 + k) for k, name in enumerate(["ai", "oe", "ai", "ieu", "oe"])]
    warped: list[int] = []
    pair_distances = utterance.pair_distances
    monkeypatch.setattr(utterance, "pair_distances",
                        lambda items, pairs: warped.append(len(pairs)) or pair_distances(items, pairs))
    cache = utterance.PairDistances(slack=0)
    first = cache.matrix(sounds[:4], set(sounds))
    np.testing.assert_array_equal(first, distance_matrix([s.features for s in sounds[:4]]))
    again = cache.matrix(sounds, set(sounds))  # one new sound: its 4 pairs only
    np.testing.assert_array_equal(again, distance_matrix([s.features for s in sounds]))
    assert warped == [6, 4]
    cache.matrix(sounds[1:3], set(sounds[1:]))  # the first sound is gone from the tree
    assert warped == [6, 4]  # kept (20 pairs) until the cache passes twice what it kept (12)
    later = heard("ua", speaker, 7.0)
    cache.matrix([*sounds[1:], later], {*sounds[1:], later})  # 4 new pairs: 28, forgotten now
    assert warped == [6, 4, 4] and all(sounds[0] not in pair for pair in cache._known)
    assert len(cache._known) == 20  # the 10 pairs of the 5 sounds held, both ways


def test_a_heard_sound_is_warped_once_against_each_exemplar_of_the_tree(speaker, monkeypatch):
    """Every class of a tree judges a heard sound against its exemplars, and a class holds
    exemplars of the class above: each exemplar is warped against the sound once, and each
    class's similarity is the one its own exemplars give (as :func:`distances_to` alone would)."""
    import audio.utterance as utterance
    from audio.cepstrum import distances_to

    root, _ = grown_tree(speaker, [WORDS[i % 3] for i in range(18)])
    born = root.fission(value=0.9, innovation_threshold=0.5)
    inner = born[0]._new_child()  # a refinement of the first class: half its exemplars
    inner.members = born[0].members[:3]
    warped: list[int] = []
    monkeypatch.setattr(utterance, "distances_to",
                        lambda q, ts: warped.append(len(ts)) or distances_to(q, ts))
    for t, name in enumerate(WORDS[:3], start=100):
        sound = heard(name, speaker, float(t))
        root.hear(sound)
        for node in [inner, *born]:
            nearest = distances_to(sound.features, [m.features for m in node.members]).min()
            assert node.evaluate(t + 0.2) == 2.0 ** (-nearest / node.radius)
    members = {m for c in born for m in c.members}
    assert sum(warped) == 3 * len(members)  # never the same exemplar twice for one sound


def test_a_model_whose_arrays_are_another_saves_is_refused(speaker: Speaker, tmp_path: Path) -> None:
    """The .json and .npz are written one after the other: a save cut between them (the .npz
    of a later save of the same model beside the .json of an earlier one) loaded whenever the
    counts agreed, each utterance with other sound and cepstra. The JSON knows its arrays now;
    a model saved before it did still loads."""
    path = tmp_path / "ear.json"
    save_aural_model(grown_tree(speaker, ["ai", "ua"] * 2)[0], path)
    npz = path.with_suffix(".npz")
    own = npz.read_bytes()
    with np.load(npz) as arrays:
        later = {"samples": arrays["samples"] * 0.5, "features": arrays["features"] + 1.0}  # same shapes
    np.savez(npz, **later)
    with pytest.raises(StateFileError, match=r"ear.npz: not the arrays ear.json was saved with"):
        load_aural_model(path)
    npz.write_bytes(own)
    doc = json.loads(path.read_text())
    doc.pop("arrays_sha256")
    path.write_text(json.dumps(doc))
    assert len(load_aural_model(path).members) == 4
