"""Utterance percept trees: a creature's growing, persistent model of the sounds it hears.

Thesis, "aural models – cepstral models": the aural branch of the percept tree starts with
an "any sound" percept that responds to the presence of sound. Its model collects the
utterances heard just before rewarded action-tuples, and when a tuple attached to it becomes
important it clusters them (fixed cluster radius, time-warped cepstral distance:
:func:`cluster_medoids`) into child ``UtterancePercept``'s: one per distinct sound, each of
which the action-group can turn into new, more specific hypotheses. Children fuse back when
they stop being distinct.

Thesis, "soundcreatures": the same tree serves the *Tr* side (what sound triggers a tuple)
and the *Ac* side (what sound to sing): cepstra cannot be turned back into sound, so each
utterance also keeps its raw samples, and :meth:`UtterancePercept.draw` hands one to the
singing action. Trees save and load (:func:`save_aural_model`), so a persistent aural model
can seed another creature with musical material.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy.cluster.hierarchy
import scipy.spatial.distance

from audio.cepstrum import FEATURES, N_CEPSTRA, WARPS, cepstra, distances_to, pair_distances, utterance_distance
from audio.segment import SoundEvent
from creatures.behaviour.percept import Percept
from creatures.persist import StateFileError, load_json, load_npz, save_json, save_npz

DEFAULT_RADIUS = 0.36
"""Cluster radius in :func:`audio.cepstrum.utterance_distance` units: a class spans at most
twice this (:func:`cluster_medoids`), and a sound this far from a class's nearest exemplar is
½ like it.

Chosen on tuning corpora and checked on held-out ones (``python -m bench sound_classes``;
docs/hearing.md, "Sound classes on real voices"): 0.357 is the geometric centre of the radii
0.32–0.40 that keep ≥ 90 % of every tuning corpus in its class — twelve espeak-ng words said
by six voices at two speeds and pitches each (93 % at 0.36), the five synthetic words (gain
±12 dB, stretch 0.8–1.25×, 20 dB SNR; 100 %), and five sampled instruments playing two
phrases at three velocities and tempi (100 %). Held out, at 0.36: the same words by three
other voices 97 % (≥ 90 % from 0.30 to 0.40), twelve other words by the six voices 92 %
(from 0.35 to 0.45), synthetic words of another seed and the instruments' third phrase 100 %.
Not held: twelve more words by the three other voices, 75 % at best 86 % — near-rhymes
("purple"/"turtle" lie closer, 0.40, than "purple" said by two voices, 0.70) — and voices in
other accents or by the Klatt synthesiser, 69 %."""

MAX_CLASSES = 24
"""Most classes a tree holds below its root (:meth:`UtterancePercept.fission`): a spoken
poem's tree in ozymandias held 9–14 after its first rehearsed hours, a gallery week's
soundcreatures far fewer."""

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

    Complete linkage cut at twice ``radius``: no two members of a cluster lie more than
    2 × ``radius`` apart. The largest clusters of at least ``min_members`` are kept, at most
    ``max_clusters`` (the rest stays unclustered); the medoid is the member with the smallest
    summed distance to the others.

    Why complete linkage (docs/hearing.md, "Sound classes on real voices"): the thesis's fixed
    radius was first read as "the neighbours within ``radius`` of the sound with most
    neighbours", and that centre gathers the near edge of the next word as readily as the far
    voices of its own. On twelve espeak-ng words said by three voices, the best such radius put
    89 % of other words and 85 % of other voices' words in their class, complete linkage 100 %
    of both (average and single linkage kept them over narrower ranges of radii, or not at all).
    """
    if len(distances) < 2:
        labels = np.ones(len(distances), dtype=int)
    else:
        tree = scipy.cluster.hierarchy.linkage(
            scipy.spatial.distance.squareform(distances, checks=False), method="complete"
        )
        labels = scipy.cluster.hierarchy.fcluster(tree, t=2.0 * radius, criterion="distance")
    groups = [np.flatnonzero(labels == k) for k in np.unique(labels)]
    kept = sorted((g for g in groups if len(g) >= min_members), key=lambda g: (-len(g), g[0]))
    return [
        g[np.argsort(distances[np.ix_(g, g)].sum(axis=1), kind="stable")]
        for g in kept[:max_clusters]
    ]


class PairDistances:
    """Time-warped distances between utterances, each pair warped once.

    Clustering asks for the distance matrix of a node's members at every fission, and most of
    its pairs were in the last one's (a rehearsed hour of ozymandias spent a third of its CPU
    warping the same pairs again). Pairs are keyed by the utterances themselves (compared by
    identity, and kept alive by the key, so no freed id is ever another sound's). Pairs of
    sounds the tree no longer holds are forgotten once the cache has grown past twice what it
    kept the last time, plus ``slack`` pairs: so it stays within about twice the pairs of the
    sounds the tree holds, bounded by the tree's ``max_members``, and the forgetting costs
    little a matrix. (Forgetting after every matrix took a sixth of ozymandias's CPU by the
    second rehearsed day, its tree holding some 10,000 pairs.) The numbers are the ones
    :func:`audio.cepstrum.distance_matrix` gives."""

    def __init__(self, slack: int = 4096) -> None:
        self._known: dict[tuple[Utterance, Utterance], float] = {}
        self.slack = slack
        self._limit = slack

    def matrix(self, members: list[Utterance], held: set[Utterance]) -> np.ndarray:
        """The symmetric distance matrix of ``members``; ``held``: every sound the tree holds now."""
        n = len(members)
        out = np.zeros((n, n))
        todo: list[tuple[int, int]] = []
        for i in range(n):
            for j in range(i + 1, n):
                d = self._known.get((members[i], members[j]))
                if d is None:
                    todo.append((i, j))
                else:
                    out[i, j] = out[j, i] = d
        found = pair_distances([m.features for m in members], todo) if todo else []
        for (i, j), d in zip(todo, found):
            out[i, j] = out[j, i] = d
            self._known[members[i], members[j]] = self._known[members[j], members[i]] = float(d)
        if len(self._known) > self._limit:
            self._known = {pair: d for pair, d in self._known.items() if pair[0] in held and pair[1] in held}
            self._limit = 2 * len(self._known) + self.slack
        return out


class UtterancePercept(Percept):
    """A percept whose model is a set of utterances (exemplars) and their medoid.

    The root ("any sound") says 1 while a sound was heard within ``memory`` seconds; a child
    says how much the latest sound resembles its exemplars: ``2 ** (−d / radius)`` for the
    smallest time-warped distance ``d`` (1 for an exact match, ½ at the cluster radius, half
    the widest a class may span). A tree whose root is ``nearest`` classifies instead: a
    child says so only while the sound resembles it more than any of its sibling classes and
    lies within the radius of one of its exemplars (½ or more; 0 otherwise), so each sound is
    heard as one class of each level, or as none ("sounds they hear are classified into trees
    by the percept tree mechanism", soundcreatures), and a tuple of another class does not
    answer it. (In the busy room of three_creatures_compared, where most sounds heard mix two
    voices and lie far from every class, a soundcreature answering the nearest class alone
    sang the other word kind for a third of the performer's words it heard; within the radius,
    for 2 of the 40 sounds it answered.)
    """

    def __init__(
        self,
        name: str = "any sound",
        *,
        radius: float = DEFAULT_RADIUS,
        max_children: int = 8,
        min_members: int = 3,
        max_members: int = 200,
        max_classes: int = MAX_CLASSES,
        memory: float = 1.0,
        parent: "UtterancePercept | None" = None,
    ) -> None:
        super().__init__(name, parent=parent)
        self.radius = float(radius)
        self.max_children = int(max_children)
        self.min_members = int(min_members)
        self.max_members = int(max_members)
        self.max_classes = int(max_classes)  # only the root's is used (see :meth:`fission`)
        self.memory = float(memory)
        self.members: list[Utterance] = []
        self.latest: Utterance | None = None  # only the root's is used
        self.nearest = False  # only the root's is used: its children classify (see the class docstring)
        self._similarity: tuple[Utterance, float] | None = None
        self._born = 0  # children made so far, for unique names
        self._pairs = PairDistances()  # only the root's is used
        self._heard_distances: tuple[Utterance, dict[Utterance, float]] | None = None  # the root's

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
        similarity = self.similarity(utterance)
        if self.root().nearest and (similarity < 0.5 or any(other.similarity(utterance) > similarity
                                                            for other in self.parent.utterance_children()
                                                            if other.members)):
            return 0.0
        return similarity

    def similarity(self, utterance: Utterance) -> float:
        """``2 ** (−d / radius)`` for the nearest exemplar; cached per heard utterance."""
        if self._similarity is None or self._similarity[0] is not utterance:
            d = min(self.distances_from(utterance, self.members))
            self._similarity = (utterance, float(2.0 ** (-d / self.radius)))
        return self._similarity[1]

    def distances_from(self, utterance: Utterance, members: list[Utterance]) -> list[float]:
        """The warped distance from ``utterance`` to each of ``members``, each warped once a
        heard sound (the tree keeps them at its root). A class holds exemplars of the class
        above it, so a tree judging one sound would warp it against the same exemplar at every
        level. (Ozymandias's rehearsed gallery hours, once its trees were 4–6 classes deep, cost
        a fifth less CPU with each exemplar warped once a sound.)"""
        root = self.root()
        if root._heard_distances is None or root._heard_distances[0] is not utterance:
            root._heard_distances = (utterance, {})
        known = root._heard_distances[1]
        todo = [m for m in members if m not in known]
        if todo:
            known.update(zip(todo, distances_to(utterance.features, [m.features for m in todo])))
        return [known[m] for m in members]

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

        Returns the children made now (for new action-tuple hypotheses). A cluster that
        continues an existing child (:meth:`_matching_child`) refreshes that child instead, so
        tuples that refer to it keep their meaning. A single cluster with no children yet is not
        split off when the sounds it leaves out are too few to make a class: one kind of sound is
        what the parent already stands for. (One sound that recurs among many that do not is a
        class: with complete linkage the words of a spoken poem gather that way.) Below the
        root a lone cluster is never split off: the node is a class already, and its tighter
        core is not a new one. (Allowed, a reading of ozymandias refined itself into the core
        of its class, and that core into its own, every few minutes: a chain 16 classes deep
        after two rehearsed gallery days, each holding nearly its parent's exemplars, and each
        hour's CPU growing with it.) Afterwards
        children that are no longer distinct fuse (:meth:`fusion`); a fused-away child is
        detached (its ``parent`` becomes None) so tuples holding it can notice.

        A tree that holds its root's ``max_classes`` classes grows no new one: its clusters
        refresh the classes they continue. A creature's hypotheses pair the classes it hears
        with those it sings, so they grow as the square of the tree, and each tick's choice
        and credit with them: in a rehearsed gallery week ozymandias's tree went on growing
        (30 classes and 800 tuples by the second day, each hour costing more than the last),
        as sounds at the edge of a class drew new ones in beside it.

        Clustering costs n²/2 comparisons of the n collected utterances, five time warps each
        (200 synthetic words: ~0.7 s here; the 60 the hearing keeps by default: ~0.08 s), which
        is why it waits for a tuple to become important rather than running per sound.
        """
        if value <= innovation_threshold or len(self.members) < self.min_members:
            return []
        clusters = cluster_medoids(
            self._distances(self.members),
            self.radius,
            max_clusters=self.max_children,
            min_members=self.min_members,
        )
        if not self.children and (not clusters or len(clusters) == 1 and (
                isinstance(self.parent, UtterancePercept)
                or len(self.members) - len(clusters[0]) < self.min_members)):
            return []
        born = []
        root = self.root()
        room = root.max_classes - (sum(1 for _ in root.walk()) - 1)
        for cluster in clusters:
            group = [self.members[i] for i in cluster]
            child = self._matching_child(group)
            if child is None:
                if len(self.children) >= self.max_children or len(born) >= room:
                    continue
                child = self._new_child()
                born.append(child)
            child.members = group
            child._similarity = None
        self.fusion()
        return [c for c in born if c.parent is self]

    def _distances(self, members: list[Utterance]) -> np.ndarray:
        """The distance matrix of ``members``, through the root's cache of warped pairs."""
        root = self.root()
        held: set[Utterance] = set()
        stack: list[UtterancePercept] = [root]
        while stack:
            node = stack.pop()
            held.update(node.members)
            stack += node.utterance_children()
        return root._pairs.matrix(members, held)

    def _by_medoid(self, members: list[Utterance]) -> list[Utterance]:
        d = self._distances(members)
        return [members[i] for i in np.argsort(d.sum(axis=1), kind="stable")]

    def fusion(self) -> list["UtterancePercept"]:
        """Merge children whose medoids are closer than ``radius``; returns those removed.

        Half the widest a class may span: two classes whose most typical sounds are that close
        could not have been kept apart by :func:`cluster_medoids`."""
        removed = []
        while (pair := self._indistinct_pair()) is not None:
            keep, lose = pair
            keep.members = self._by_medoid(keep.members + lose.members)
            keep._similarity = None
            self.remove_child(lose)
            removed.append(lose)
        return removed

    def _indistinct_pair(self) -> "tuple[UtterancePercept, UtterancePercept] | None":
        kids = self.utterance_children()
        for i, a in enumerate(kids):
            for b in kids[i + 1 :]:
                if utterance_distance(a.medoid.features, b.medoid.features) < self.radius:
                    return a, b
        return None

    def _matching_child(self, group: list[Utterance]) -> "UtterancePercept | None":
        """The child a new cluster (medoid first) continues: the one most of whose exemplars
        it holds, else (a child whose exemplars are no longer collected) the nearest one whose
        medoid lies within ``radius`` of the cluster's.

        Exemplars first, because a class of several voices may span twice the radius: a
        re-clustering can make another of its voices the medoid, farther than the radius from
        the one before.
        """
        kids = self.utterance_children()
        if not kids:
            return None
        held = {id(u) for u in group}
        for kid in kids:
            if 2 * sum(id(u) in held for u in kid.members) > len(kid.members):
                return kid
        d = distances_to(group[0].features, [k.medoid.features for k in kids])
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
            max_classes=self.max_classes,
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


def aural_model_of(sounds: list[np.ndarray], samplerate: int) -> UtterancePercept:
    """A tree whose memory is ``sounds``, one utterance each, in order: pre-selected samples
    made into an aural model (three creatures' score computer flushed the creatures' memories
    with "pre-selected samples"; a persistent aural model seeds a creature). Each is stamped
    with the time it would end were the sounds played one after another from 0 s."""
    tree = UtterancePercept()
    ends = np.cumsum([len(s) for s in sounds]) / samplerate
    for sound, end in zip(sounds, ends):
        sound = np.ascontiguousarray(sound, dtype=np.float32)
        tree.members.append(Utterance(sound, samplerate, cepstra(sound, samplerate), float(end)))
    return tree


# -- persistence ------------------------------------------------------------------------------


def _arrays_path(path: Path) -> Path:
    return path.with_suffix(".npz")


def _digest(samples: np.ndarray, features: np.ndarray) -> str:
    """What the JSON half of a model records of its arrays, to know them for its own: the two
    files are each written atomically but not together, so a save cut between them (or a
    ``.npz`` copied from another model) left a pair that loaded when the counts agreed, every
    utterance's sound and cepstra another's."""
    h = hashlib.sha256()
    for a in (samples, features):
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def save_aural_model(root: UtterancePercept, path: str | os.PathLike) -> None:
    """Save a tree as ``path`` (JSON structure) + ``path`` with ``.npz`` (samples, cepstra).

    Utterances shared between nodes are stored once; nodes list them by index. The file names
    the cepstral analysis (:data:`audio.cepstrum.FEATURES`): its radii are in that analysis's
    units.
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
            "max_classes": p.max_classes,
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
            "n_frames": u.features.shape[1],
        }
        for u in table
    ]
    if table:
        samples = np.concatenate([u.samples for u in table])
        features = np.concatenate([u.features for u in table], axis=1)
    else:
        samples, features = np.zeros(0, np.float32), np.zeros((len(WARPS), 0, N_CEPSTRA))
    save_npz(_arrays_path(path), {"samples": samples, "features": features})
    save_json(path, {"tree": tree, "utterances": utterances, "features": FEATURES,
                     "arrays_sha256": _digest(samples, features)}, kind=KIND)


def load_aural_model(path: str | os.PathLike) -> UtterancePercept:
    """Rebuild a tree saved by :func:`save_aural_model` (another creature's, perhaps).

    A model saved with another cepstral analysis is refused (:class:`StateFileError`): its
    radii and cepstra are in other units, which no conversion makes right.
    """
    path = Path(path)
    doc = load_json(path, kind=KIND)
    if doc.get("features") != FEATURES:
        raise StateFileError(
            f"{path}: saved with another cepstral analysis ({doc.get('features', 'MFCC')!r}, this build"
            f" hears with {FEATURES!r}): its radii and cepstra are in other units; grow the model again"
        )
    arrays = load_npz(_arrays_path(path))
    try:
        meta, tree = doc["utterances"], doc["tree"]
        samples, features = arrays["samples"], arrays["features"]
        if doc.get("arrays_sha256", _digest(samples, features)) != _digest(samples, features):  # older: no digest
            raise StateFileError(
                f"{_arrays_path(path)}: not the arrays {path.name} was saved with (a save cut between the two "
                f"files, or one copied from another model): copy the pair together, or make the model again"
            )
        sample_ends = np.cumsum([u["n_samples"] for u in meta], dtype=int)
        frame_ends = np.cumsum([u["n_frames"] for u in meta], dtype=int)
        if features.shape[::2] != (len(WARPS), N_CEPSTRA) or (sample_ends[-1:] != len(samples)).any() \
                or (frame_ends[-1:] != features.shape[1]).any():
            raise StateFileError(
                f"{_arrays_path(path)}: arrays do not match the {len(meta)} utterances in {path}"
            )
        table = [
            Utterance(
                samples=samples[s_end - u["n_samples"] : s_end],
                samplerate=int(u["samplerate"]),
                features=np.ascontiguousarray(features[:, f_end - u["n_frames"] : f_end]),
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
                max_classes=d.get("max_classes", MAX_CLASSES),  # files saved before the bound: the default
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
