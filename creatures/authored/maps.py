"""listen's two self-organising maps, kept in a percept (thesis "listen (installation)",
"extensions": "the most promising of these considers an internal musical space … mapped out
by the music that the creature hears and remembers").

The percept type ``maps`` (:mod:`creatures.authored.percepts`) builds one :class:`MusicPoseMaps`:

* **The music map** learns "the temporally local distribution of musical material": each
  heard note is a point of (pitch, interval from the note before, inter-onset time) in the
  units of :data:`SCALE` (an octave, an octave, a doubling of the time), so a step of a fifth
  and a tempo change of √2 weigh alike.
* **The pose map** learns "a map of body movement derived from an animation playing
  continuously in the background": every tick the body's pose trains it at its own winner,
  at the ``background`` rate.
* **Strict topology**: a heard note also trains the pose map, at the *music* map's winner,
  with the body's pose at that moment. Both of a note's updates are scaled by its salience,
  its velocity (the thesis's "current implementation": "memorable notes result in memorable
  poses").
* **Dancing on the maps.** ``dance`` and ``anticipate`` with ``poses = "<maps percept>"``
  send the body, by A*, to the motor-graph node nearest the pose the pose map holds where the
  music map places the predicted note: "the predicting population of models can now dance by
  finding (paths to) body pose clusters related to note clusters in a dynamically changing
  music-pose mapping" (:meth:`MusicPoseMaps.node_for`).

Its salience is how familiar the music is to the map: ``exp(-e)`` of the running mean
quantisation error ``e`` of the notes heard (1 for music the map knows exactly). Both errors,
and how far heard notes moved each map (``moved``, ``poses_moved``), are logged in ``maps``
events at every values snapshot, and the maps are saved with the creature's state (JSON
lists, checked on reload).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from creatures import bounds
from creatures.behaviour.percept import Percept
from creatures.behaviour.som import PoseMap, SelfOrganisingMap, pose_distances
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.authored.creature import Authored

SCALE = np.array([12.0, 12.0, 1.0])
"""Units of the music map's axes: pitch and interval in octaves, inter-onset time in doublings."""

LOW = np.array([36.0, -12.0, math.log2(0.125)]) / SCALE
HIGH = np.array([96.0, 12.0, math.log2(2.0)]) / SCALE
"""Where the music map's nodes start: pitch C2–C7 down the rows, intervals of an octave down
to an octave up across the columns, inter-onset times at their middle (0.5 s)."""

FIRST_GAP = 0.5
"""Seconds taken as the inter-onset time of a first note (none came before it)."""

LONGEST_GAP = 8.0
"""Seconds: a longer silence is a new start, heard as :data:`FIRST_GAP`."""

ERROR_MEMORY = 16
"""Notes the running mean quantisation error mostly remembers (an exponential mean)."""


def features(pitch: float, before: float | None, gap: float) -> np.ndarray:
    """A note as the music map sees it, from its pitch, the pitch before (None: none) and
    the seconds since that note's onset."""
    interval = 0.0 if before is None else float(np.clip(pitch - before, -24, 24))
    gap = FIRST_GAP if before is None or not 0.01 <= gap <= LONGEST_GAP else gap
    return np.array([pitch, interval, math.log2(gap)]) / SCALE


class MusicPoseMaps(Percept):
    """The music map and the pose map of one creature on one grid (``params``: the ``maps``
    percept's keys)."""

    def __init__(self, name: str, creature: "Authored", params: Any) -> None:
        super().__init__(name)
        self.creature = creature
        self.params = params
        rows, cols = params.size
        self.music = SelfOrganisingMap.spanning(rows, cols, params.radius, LOW, HIGH)
        # The pose map starts on poses of the body's own material, spread evenly over its
        # graph (no random draw: adding the maps changes nothing else a seed decides).
        graph = creature.body.graph
        picks = np.linspace(0, len(graph) - 1, rows * cols).round().astype(int)
        self.poses = PoseMap(rows, cols, params.radius, graph.poses.rotations[picks])
        self.last: NoteEvent | None = None
        self.heard = 0
        self.music_error = self.pose_error = 0.0  # running means (exponential over ERROR_MEMORY)
        self.posed = 0  # ticks the background has trained the pose map (its error's mean starts at the first)
        self.moved = 0.0  # how far the music map moved in all
        self.poses_moved = 0.0  # how far heard notes moved the pose map in all (not the background)
        creature.on_hear(self.hear)
        creature.each_tick(self.tick)
        creature.reporting(self.report)
        creature.keep("percepts", name, self.state, self.restore)

    def evaluate(self, t: float) -> float:
        return 0.0 if not self.heard else math.exp(-self.music_error)

    def _mean(self, mean: float, error: float) -> float:
        return error if self.heard <= 1 else mean + (error - mean) / min(self.heard, ERROR_MEMORY)

    def hear(self, note: NoteEvent, source: str) -> None:
        """One heard note trains the music map at its winner and the pose map there too, with
        the pose the body holds now, both by the note's salience."""
        before = self.last
        x = features(note.pitch, None if before is None else before.pitch,
                     0.0 if before is None else float(note.time) - float(before.time))
        self.last = note
        at, error = self.music.winner(x)
        self.heard += 1
        self.music_error = self._mean(self.music_error, error)
        rate = self.params.rate * note.velocity / 127.0
        self.moved += self.music.train(x, rate, at)
        self.poses_moved += self.poses.train(self.creature.body.pose.rotations, rate, at)

    def tick(self, t: float) -> None:
        """The background: the body's pose now trains the pose map at its own winner."""
        rotations = self.creature.body.pose.rotations
        at, error = self.poses.winner(rotations)
        self.posed += 1
        self.pose_error += (error - self.pose_error) / min(self.posed, ERROR_MEMORY)
        self.poses.train(rotations, self.params.background, at)

    def node_for(self, pitch: int, before: int | None, gap: float) -> int:
        """The motor-graph node nearest the pose the pose map holds where the music map
        places this note: where dancing it on the maps goes."""
        at, _ = self.music.winner(features(pitch, before, gap))
        return int(np.argmin(pose_distances(self.creature.body.graph.poses.rotations, self.poses.rotations[at])))

    def report(self, t: float) -> None:
        self.creature.world.emit("maps", creature=self.creature.name, percept=self.name, notes=self.heard,
                                 music_error=round(self.music_error, 6), pose_error=round(self.pose_error, 6),
                                 moved=round(self.moved, 6), poses_moved=round(self.poses_moved, 6))

    def state(self) -> dict[str, Any]:
        return {"music": self.music.vectors.tolist(), "poses": self.poses.rotations.tolist(),
                "heard": self.heard, "music error": self.music_error, "pose error": self.pose_error}

    def restore(self, state: dict[str, Any]) -> None:
        """Take the maps back; maps of another size or body are refused, naming which."""
        state = bounds.table(state, self.name)
        rows, cols = self.params.size
        if "music" in state:
            self.music = SelfOrganisingMap(rows, cols, self.params.radius,
                                           np.array(bounds.items(state["music"], f"{self.name}.music",
                                                                 longest=rows * cols, shortest=rows * cols)))
        if "poses" in state:
            poses = np.array(bounds.items(state["poses"], f"{self.name}.poses", longest=rows * cols,
                                          shortest=rows * cols), dtype=float)
            joints = self.creature.body.skeleton.joint_count
            if poses.shape[1:] != (joints, 4):
                raise ValueError(f"{self.name}.poses: saved for a body of {poses.shape[1]} joints, "
                                 f"this body has {joints}")
            self.poses = PoseMap(rows, cols, self.params.radius, poses)
        self.heard = bounds.count(state.get("heard", 0), f"{self.name}.heard")
        self.music_error = bounds.number(state.get("music error", 0.0), f"{self.name}.music error", low=0)
        self.pose_error = bounds.number(state.get("pose error", 0.0), f"{self.name}.pose error", low=0)
        self.posed = ERROR_MEMORY if "pose error" in state else 0  # a saved mean goes on as one
