"""Utterance percept trees: a creature's growing, persistent model of the sounds it hears.

Thesis, "aural models – cepstral models": the aural branch of the percept tree starts with
an "any sound" percept that responds to the presence of sound. Its model collects the
utterances heard just before rewarded action-tuples, and when a tuple attached to it becomes
important it clusters them (fixed cluster radius, time-warped cepstral distance) into child
``UtterancePercept``'s: one per distinct sound, each of which the action-group can turn into
new, more specific hypotheses. Children fuse back when they stop being distinct.

Thesis, "soundcreatures": the same tree serves the *Tr* side (what sound triggers a tuple)
and the *Ac* side (what sound to sing): cepstra cannot be turned back into sound, so each
utterance also keeps its raw samples, and :meth:`UtterancePercept.draw` hands one to the
singing action. Trees save and load (:func:`save_aural_model`), so a persistent aural model
can seed another creature with musical material.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from audio.cepstrum import cepstra, distance_matrix, distances_to, dtw_distance
from audio.segment import SoundEvent
from creatures.behaviour.percept import Percept
from creatures.persist import StateFileError, load_json, load_npz, save_json, save_npz

DEFAULT_RADIUS = 250.0
"""Cluster radius in :func:`audio.cepstrum.dtw_distance` units (liftered, CMN'd MFCCs).

Measured on the synthetic words of the tests (gain ±12 dB, stretch 0.8–1.25×, 20 dB SNR):
the same word lies within 225 of itself, different words at least 320 apart. Re-measured
(``python -m bench sound_classes``, docs/hearing.md): it also holds a sampled instrument's
phrase at three velocities and tempi (67 % in class; 284 would give 100 %), but not one
word said by three espeak-ng voices (550–930 apart, so each is a class of its own); no radius
separates words across speakers with these features (best 67 %)."""

KIND = "aural-model"


@dataclass(eq=False)
class Utterance:
    """A heard sound kept whole: cepstra to recognise it, samples to sing it back."""

    samples: np.ndarray  # float32, as heard
    samplerate: int
    features: np.ndarray  # cepstra(samples), (frames, coefficients)
    time: float  # when the sound ended, on the creature's clock

    @classmethod
    def from_event(cls, event: SoundEvent) -> "Utterance":
        return cls(
            samples=np.asarray(event.samples, dtype=np.float32),
            samplerate=event.samplerate,
            features=cepstra(event.samples, event.samplerate),
            time=event.end,
        )


def cluster_medoids(
    distances: np.ndarray, radius: float, *, max_clusters: int, min_members: int
) -> list[np.ndarray]:
    """Fixed-radius clustering of a distance matrix; each cluster's medoid comes first.

    Repeatedly takes the item with the most neighbours within ``radius``, makes those
    neighbours a cluster and removes them, until ``max_clusters`` are made or no item has
    ``min_members`` neighbours left (the rest stays unclustered). The medoid is the member
    with the smallest summed distance to the others.
    """
    remaining = np.arange(len(distances))
    clusters: list[np.ndarray] = []
    while len(remaining) and len(clusters) < max_clusters:
        near = distances[np.ix_(remaining, remaining)] <= radius
        counts = near.sum(axis=1)
        centre = int(np.argmax(counts))
        if counts[centre] < min_members:
            break
        members = remaining[near[centre]]
        order = np.argsort(distances[np.ix_(members, members)].sum(axis=1), kind="stable")
        clusters.append(members[order])
        remaining = remaining[~near[centre]]
    return clusters


class UtterancePercept(Percept):
    """A percept whose model is a set of utterances (exemplars) and their medoid.

    The root ("any sound") says 1 while a sound was heard within ``memory`` seconds; a child
    says how much the latest sound resembles its exemplars: ``2 ** (−d / radius)`` for the
    smallest time-warped distance ``d`` (1 for an exact match, ½ at the cluster radius).
    """

    def __init__(
        self,
        name: str = "any sound",
        *,
        radius: float = DEFAULT_RADIUS,
        max_children: int = 8,
        min_members: int = 3,
        max_members: int = 200,
        memory: float = 1.0,
        parent: "UtterancePercept | None" = None,
    ) -> None:
        super().__init__(name, parent=parent)
        self.radius = float(radius)
        self.max_children = int(max_children)
        self.min_members = int(min_members)
        self.max_members = int(max_members)
        self.memory = float(memory)
        self.members: list[Utterance] = []
        self.latest: Utterance | None = None  # only the root's is used
        self._similarity: tuple[Utterance, float] | None = None
        self._born = 0  # children made so far, for unique names

    # -- hearing and evaluating -------------------------------------------------------------

    def root(self) -> "UtterancePercept":
        node: Percept = self
        while isinstance(node.parent, UtterancePercept):
            node = node.parent
        return node  # type: ignore[return-value]

    def hear(self, utterance: Utterance) -> None:
        """The creature heard ``utterance`` (at ``utterance.time``); every node can now judge it."""
        self.root().latest = utterance

    def heard(self, t: float) -> Utterance | None:
        """The latest utterance if it was heard within ``memory`` seconds before ``t``."""
        latest = self.root().latest
        if latest is None or not 0.0 <= t - latest.time <= self.memory:
            return None
        return latest

    def evaluate(self, t: float) -> float:
        utterance = self.heard(t)
        if utterance is None:
            return 0.0
        if self.parent is None or not self.members:
            return 1.0
        return self.similarity(utterance)

    def similarity(self, utterance: Utterance) -> float:
        """``2 ** (−d / radius)`` for the nearest exemplar; cached per heard utterance."""
        if self._similarity is None or self._similarity[0] is not utterance:
            d = distances_to(utterance.features, [m.features for m in self.members]).min()
            self._similarity = (utterance, float(2.0 ** (-d / self.radius)))
        return self._similarity[1]

    # -- learning: collection, fission, fusion ----------------------------------------------

    def update(self, t: float, value: float) -> None:
        """A tuple using this percept earned ``value`` at ``t``: keep the sound that led to it."""
        utterance = self.heard(t)
        if value <= 0.0 or utterance is None or any(m is utterance for m in self.members):
            return
        self.members.append(utterance)
        del self.members[: -self.max_members]
        self._similarity = None

    def fission(self, value: float, innovation_threshold: float) -> list["UtterancePercept"]:
        """If ``value`` exceeds the threshold, cluster the collected utterances into children.

        Returns the children made now (for new action-tuple hypotheses). Clusters that match
        an existing child (medoids within ``radius``) refresh that child instead, so tuples
        that refer to it keep their meaning. A single cluster with no children yet is not
        split off: one kind of sound is what the parent already stands for. Afterwards
        children that are no longer distinct fuse (:meth:`fusion`); a fused-away child is
        detached (its ``parent`` becomes None) so tuples holding it can notice.

        Clustering costs n²/2 time warps of the n collected utterances (200: ~0.26 s here),
        which is why it waits for a tuple to become important rather than running per sound.
        """
        if value <= innovation_threshold or len(self.members) < self.min_members:
            return []
        clusters = cluster_medoids(
            distance_matrix([m.features for m in self.members]),
            self.radius,
            max_clusters=self.max_children,
            min_members=self.min_members,
        )
        if len(clusters) < 2 and not self.children:
            return []
        born = []
        for cluster in clusters:
            group = [self.members[i] for i in cluster]
            child = self._matching_child(group[0])
            if child is None:
                if len(self.children) >= self.max_children:
                    continue
                child = self._new_child()
                born.append(child)
            child.members = group
            child._similarity = None
        self.fusion()
        return [c for c in born if c.parent is self]

    def fusion(self) -> list["UtterancePercept"]:
        """Merge children whose medoids are closer than ``radius``; returns those removed."""
        removed = []
        while (pair := self._indistinct_pair()) is not None:
            keep, lose = pair
            keep.members = _by_medoid(keep.members + lose.members)
            keep._similarity = None
            self.remove_child(lose)
            removed.append(lose)
        return removed

    def _indistinct_pair(self) -> "tuple[UtterancePercept, UtterancePercept] | None":
        kids = self.utterance_children()
        for i, a in enumerate(kids):
            for b in kids[i + 1 :]:
                if dtw_distance(a.medoid.features, b.medoid.features) < self.radius:
                    return a, b
        return None

    def _matching_child(self, medoid: Utterance) -> "UtterancePercept | None":
        kids = self.utterance_children()
        if not kids:
            return None
        d = distances_to(medoid.features, [k.medoid.features for k in kids])
        i = int(np.argmin(d))
        return kids[i] if d[i] < self.radius else None

    def _new_child(self) -> "UtterancePercept":
        self._born += 1
        return UtterancePercept(
            f"{self.name}/{self._born}",
            radius=self.radius,
            max_children=self.max_children,
            min_members=self.min_members,
            max_members=self.max_members,
            memory=self.memory,
            parent=self,
        )

    def utterance_children(self) -> list["UtterancePercept"]:
        return [c for c in self.children if isinstance(c, UtterancePercept)]

    # -- singing (the Ac side) --------------------------------------------------------------

    @property
    def medoid(self) -> Utterance:
        """The most typical exemplar (members are kept medoid first)."""
        if not self.members:
            raise LookupError(f"percept {self.name!r} has no exemplars yet")
        return self.members[0]

    def draw(self, rng: np.random.Generator) -> Utterance:
        """An exemplar to sing back: what an *Ac* on this percept plays."""
        if not self.members:
            raise LookupError(f"percept {self.name!r} has no exemplars to sing")
        return self.members[int(rng.integers(len(self.members)))]

    def to_dict(self) -> dict[str, Any]:
        return {
            **super().to_dict(),
            "radius": self.radius,
            "members": len(self.members),
        }


def _by_medoid(members: list[Utterance]) -> list[Utterance]:
    d = distance_matrix([m.features for m in members])
    return [members[i] for i in np.argsort(d.sum(axis=1), kind="stable")]


# -- persistence ------------------------------------------------------------------------------


def _arrays_path(path: Path) -> Path:
    return path.with_suffix(".npz")


def save_aural_model(root: UtterancePercept, path: str | os.PathLike) -> None:
    """Save a tree as ``path`` (JSON structure) + ``path`` with ``.npz`` (samples, cepstra).

    Utterances shared between nodes are stored once; nodes list them by index.
    """
    path = Path(path)
    pool: dict[int, int] = {}
    table: list[Utterance] = []

    def index(u: Utterance) -> int:
        if id(u) not in pool:
            pool[id(u)] = len(table)
            table.append(u)
        return pool[id(u)]

    def node(p: UtterancePercept) -> dict[str, Any]:
        return {
            "name": p.name,
            "radius": p.radius,
            "max_children": p.max_children,
            "min_members": p.min_members,
            "max_members": p.max_members,
            "memory": p.memory,
            "born": p._born,
            "members": [index(u) for u in p.members],
            "children": [node(c) for c in p.utterance_children()],
        }

    tree = node(root)
    if root.latest is not None:
        tree["latest"] = index(root.latest)
    utterances = [
        {
            "samplerate": u.samplerate,
            "time": u.time,
            "n_samples": len(u.samples),
            "n_frames": u.features.shape[0],
        }
        for u in table
    ]
    if table:
        samples = np.concatenate([u.samples for u in table])
        features = np.concatenate([u.features for u in table])
    else:
        samples, features = np.zeros(0, np.float32), np.zeros((0, 0))
    save_npz(_arrays_path(path), {"samples": samples, "features": features})
    save_json(path, {"tree": tree, "utterances": utterances}, kind=KIND)


def load_aural_model(path: str | os.PathLike) -> UtterancePercept:
    """Rebuild a tree saved by :func:`save_aural_model` (another creature's, perhaps)."""
    path = Path(path)
    doc = load_json(path, kind=KIND)
    arrays = load_npz(_arrays_path(path))
    try:
        meta, tree = doc["utterances"], doc["tree"]
        samples, features = arrays["samples"], arrays["features"]
        sample_ends = np.cumsum([u["n_samples"] for u in meta], dtype=int)
        frame_ends = np.cumsum([u["n_frames"] for u in meta], dtype=int)
        if (sample_ends[-1:] != len(samples)).any() or (frame_ends[-1:] != len(features)).any():
            raise StateFileError(
                f"{_arrays_path(path)}: arrays do not match the {len(meta)} utterances in {path}"
            )
        table = [
            Utterance(
                samples=samples[s_end - u["n_samples"] : s_end],
                samplerate=int(u["samplerate"]),
                features=features[f_end - u["n_frames"] : f_end],
                time=float(u["time"]),
            )
            for u, s_end, f_end in zip(meta, sample_ends, frame_ends)
        ]

        def build(d: dict[str, Any], parent: UtterancePercept | None) -> UtterancePercept:
            p = UtterancePercept(
                d["name"],
                radius=d["radius"],
                max_children=d["max_children"],
                min_members=d["min_members"],
                max_members=d["max_members"],
                memory=d["memory"],
                parent=parent,
            )
            p._born = d["born"]
            p.members = [table[i] for i in d["members"]]
            for c in d["children"]:
                build(c, p)
            return p

        root = build(tree, None)
        if "latest" in tree:
            root.latest = table[tree["latest"]]
    except (KeyError, IndexError, TypeError) as exc:
        raise StateFileError(
            f"{path}: malformed aural model ({type(exc).__name__}: {exc})"
        ) from None
    return root
