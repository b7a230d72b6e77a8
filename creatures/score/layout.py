"""The output layer: tiles laid out in time under behaviour control, just in time to be played
(thesis, "(void *)", figure 36: "tiles get laid out in time, under behavior-system direction
... just in time to get played"; "the behavior-system can also modulate the contents of the
tiles (changing volume, and MIDI controllers)"; "pattern generators can be used to predict the
future. Therefore conflicts can be 'reacted' to well before they get played").

Each layer of the score is a walk through the tile graph, laid out in beats ahead of the clock:
what a tuple asks for (:meth:`ScoreLayout.steer`: a tag, or a pattern of tags in order — a
motor program as the thesis's pattern generator) is laid out at once, as far as it goes, so the
score knows its future; between courses a layer walks through its ``idle`` tiles. Notes are
handed to the output only ``commit`` seconds before they sound; until then a new course may
replace the laid tiles from the next place the layer may cut (a beat, a bar line, a tile's
end) after the layer's last committed note: a layer resting in a tacet has committed nothing,
so a cue cuts in on the very next beat, and a visitor's controller changes the score within
one beat (what the thesis's "just in time" is for). Every tile starts on a beat of the :class:`~creatures.score.grid.Grid`, which follows the
colony's heard pulse from the first beat not yet committed.

Balance and timbre (thesis: "a character's stance towards the user's control is connected to
the timbre of the characters' music"; "thematic balance is biased to take into account what
characters are visible on screen"): each part's stance percept picks its program at each of its
tiles and sets CC 74 every beat; its visibility percept sets CC 11 every beat; its energy
percept (how the character moves) sets the velocity its notes are played at. The creature's
own sound (``out.wav``, live audio) plays each part in a voice of its own that follows the same
CC 74 and CC 11 (:mod:`creatures.score.band`), so stance and balance are heard there too.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import mido
import numpy as np

from creatures.clock import clock_gap
from creatures.motor.search import NoPath
from creatures.runtime.world import INPUT
from creatures.score.band import PartVoices
from creatures.score.grid import BeatFollower, Grid, nearest_multiple
from creatures.score.program import ScoreProgram
from creatures.score.spec import ScoreSpec
from creatures.score.tile_graph import TileGraph
from creatures.score.tiles import TileSet
from midi.notes import NoteEvent

if TYPE_CHECKING:
    from creatures.authored.creature import Authored

SHIFT_TOLERANCE = 0.001
"""Seconds: a heard beat this close to the grid's is left alone (no churn of the anchor)."""


@dataclass
class Laid:
    """A tile laid on a layer from beat ``start`` to ``end`` (a cut shortens it); ``sent``: how
    many of its notes went to the output; ``request``: the course that laid it (0: idling)."""

    tile: int
    start: float
    end: float
    request: int = 0
    sent: int = 0
    begun: bool = False


@dataclass
class Layer:
    """One layer's laid tiles (in beat order) and what it is asked for."""

    name: str
    idle: str
    cut: int
    laid: list[Laid] = field(default_factory=list)
    request: int = 0
    program: ScoreProgram | None = None  # the pattern generator steering it, if any
    committed: float = -math.inf  # clock time of the latest note handed to the output

    @property
    def end(self) -> float:
        return self.laid[-1].end if self.laid else -math.inf


class ScoreLayout:
    """A creature's score: its tiles, their graph, the grid and the layers laid out on it."""

    def __init__(self, spec: ScoreSpec, tiles: TileSet, creature: "Authored", rng: np.random.Generator) -> None:
        self.spec, self.tiles, self.creature, self.rng = spec, tiles, creature, rng
        self.graph = TileGraph(tiles)
        self.beat_length = 60.0 / spec.tempo
        self.grid: Grid | None = None
        self.follower = BeatFollower()
        self.layers = {name: Layer(name, ls.idle, ls.cut) for name, ls in spec.layers.items()}
        self._requests = itertools.count(1)
        self._goal_end: dict[int, float] = {}  # request → the beat its course ends
        self._programs: dict[str, int] = {}
        self._controls: dict[tuple[int, int], int] = {}
        self._modulated = -math.inf  # the last beat whose controllers were sent
        self._followed = -math.inf  # the last beat the heard pulse moved
        self._seen = -math.inf  # the clock time of the last tick or course (to see a clock gap)
        self.band = PartVoices(creature.spec.voice, spec.parts) if spec.parts else None  # the parts as heard

    # -- the behaviour system's side ------------------------------------------------------
    def steer(self, t: float, layer: str, program: ScoreProgram) -> int:
        """Let ``program`` lay ``layer`` out from the next place it may cut (legs as far ahead
        as the layout looks, more as time goes on); returns the course's number (for
        :meth:`reached`)."""
        grid = self._grid(t)
        lay = self.layers[layer]
        cut = self._cut_beat(lay, grid.beat(max(t, lay.committed)) + 1e-6)
        if lay.request in self._goal_end:  # a course it replaces ends where this one cuts in
            self._goal_end[lay.request] = min(self._goal_end[lay.request], cut)
        request = lay.request = next(self._requests)
        kept = []
        for laid in lay.laid:
            if laid.start < cut:
                laid.end = min(laid.end, cut)
                kept.append(laid)
        lay.laid = kept
        lay.program = program
        self._goal_end[request] = math.inf
        self._extend(t, lay, cut, grid.beat(t + self.spec.commit) + self.spec.lookahead)
        return request

    def _leg(self, t: float, lay: Layer, begin: float) -> bool:
        """Lay the program's next leg from ``begin``; False once the program has ended."""
        stmt = lay.program.next_leg() if lay.program is not None else None
        if stmt is None:
            self._goal_end[lay.request] = max(begin, lay.end)
            lay.program = None
            return False
        start = lay.laid[-1].tile if lay.laid else None
        tags = [str(x) for x in stmt.targets]
        try:
            walk = self.graph.walk(start, lay.name, tags, furthest=stmt.op == "getToFurthest")
        except NoPath as exc:  # the program cannot go on from here: it ends, the layer idles
            self.creature.world.log.emit(t, "score", creature=self.creature.name, layer=lay.name, problem=str(exc))
            self._goal_end[lay.request] = max(begin, lay.end)
            lay.program = None
            return False
        for node in walk:
            end = begin + self.tiles.tiles[node].beats
            lay.laid.append(Laid(node, begin, end, lay.request))
            begin = end
        return True

    def _extend(self, t: float, lay: Layer, frontier: float, ahead: float) -> None:
        """Lay ``lay`` out to ``ahead``: its program's legs, else its idle tiles."""
        while lay.end < ahead:
            begin = max(lay.end, frontier) if lay.laid else math.ceil(frontier - 1e-9)
            if lay.program is not None:
                if self._leg(t, lay, begin):
                    continue
            if not self._idle(t, lay, frontier):
                return

    def reached(self, request: int, t: float) -> float:
        """1 once course ``request`` has been played out (or replaced by another), else 0."""
        end = self._goal_end.get(request)
        if end is None or self.grid is None:
            return 1.0
        if self.grid.beat(t) < end - 1e-9:
            return 0.0
        del self._goal_end[request]  # played out: forgotten (a course a tile, over a month of runs)
        return 1.0

    def release(self, layer: str, request: int) -> None:
        """Course ``request``'s tuple has stopped: its program lays no more legs (what is laid
        plays out, then ``layer`` idles; a cycling program went on for good), and nothing asks
        any more whether it was played out (a course cut short was kept here for good)."""
        lay = self.layers[layer]
        if lay.request == request:
            lay.program = None
        self._goal_end.pop(request, None)

    def _cut_beat(self, lay: Layer, frontier: float) -> float:
        """The first beat at or after ``frontier`` where ``lay`` may change course."""
        if lay.cut == 0:
            playing = [laid for laid in lay.laid if laid.start < frontier]
            return max([frontier, *(laid.end for laid in playing)])
        return math.ceil(frontier / lay.cut - 1e-9) * lay.cut

    # -- every tick ------------------------------------------------------------------------
    def hear(self, note: NoteEvent, source: str) -> None:
        if source == INPUT:
            self.follower.hear(note.time)

    def tick(self, t: float) -> None:
        """Follow the heard beat, lay out what is due, commit what sounds soon, modulate."""
        grid = self._grid(t)
        horizon = t + self.spec.commit
        if self.spec.follow:
            self._follow(t, grid, horizon)
        ahead = grid.beat(horizon) + self.spec.lookahead
        for lay in self.layers.values():
            self._extend(t, lay, grid.beat(horizon), ahead)
        self._modulate(t, grid, horizon)
        for lay in self.layers.values():
            self._commit(t, grid, lay, horizon)

    def _grid(self, t: float) -> Grid:
        if self.grid is None:
            self.grid = Grid(self.beat_length, t + self.spec.commit)
        elif clock_gap(self._seen, t):
            self._resume(t)
        self._seen = t
        return self.grid

    def _resume(self, t: float) -> None:
        """Across a clock gap (a closed night, a suspended machine) the score goes on from now,
        not through the gap: what was laid is abandoned (each layer's walk goes on from its last
        tile) and the next beat after it sounds ``commit`` from now. Played through, a night's
        tiles would all be committed on the morning's first tick (sand:stone's songs once sent
        97,050 notes so)."""
        beat = math.ceil(max([lay.end for lay in self.layers.values() if lay.laid], default=0.0) - 1e-9)
        for lay in self.layers.values():
            if lay.laid:
                last = lay.laid[-1]
                last.begun, last.sent = True, len(self.tiles.tiles[last.tile].onsets)
                lay.laid = [last]
        self.grid.change(beat, self.grid.period, t + self.spec.commit)
        self.creature.world.log.emit(t, "score grid", creature=self.creature.name, beat=beat,
                                     time=t + self.spec.commit, period=self.grid.period, resumed=True)

    def _follow(self, t: float, grid: Grid, horizon: float) -> None:
        """Move the grid onto the heard pulse from the first beat not yet committed: the
        tempo at once (time stretch), the phase by at most a quarter of a beat a beat (time
        shift; a phase-locked loop, so no beat is squeezed and none moves into the past)."""
        beat = math.ceil(grid.beat(horizon) + 1e-9)
        if beat <= self._followed:  # each beat is moved once
            return
        pulse = self.creature.world.pulse
        found = self.follower.fit(t, pulse.model.pulse) if pulse.ready else None
        if found is None:
            return
        period = nearest_multiple(found[0], self.beat_length)
        was = grid.time(beat)
        heard = found[1] + period * round((was - found[1]) / period)
        at = was + min(max(heard - was, -period / 2), period / 2)
        if at <= horizon:
            return
        if abs(at - was) > SHIFT_TOLERANCE or abs(period - grid.period) > SHIFT_TOLERANCE / 8:
            self._followed = beat
            grid.change(beat, period, at)
            self.creature.world.log.emit(t, "score grid", creature=self.creature.name, beat=beat, time=at,
                                         period=period)

    def _idle(self, t: float, lay: Layer, frontier: float) -> bool:
        """Lay the layer's next idle tile (a successor with its idle tag, chosen in proportion
        to how smoothly it joins; else the idle tile just laid again, when it is the only one;
        else the way to the nearest one)."""
        if not lay.laid:
            try:
                node = self.graph.entry(lay.name, lay.idle)
            except NoPath:
                return False
            begin = math.ceil(frontier - 1e-9)
            lay.laid.append(Laid(node, begin, begin + self.tiles.tiles[node].beats))
            return True
        last = lay.laid[-1]
        options = [s for s in self.graph.successors[last.tile] if lay.idle in self.tiles.tiles[s].tags]
        if options:
            cost = self.graph.cost[last.tile, options]
            weight = np.exp(-(cost - cost.min()) / 0.25)
            walk = [int(self.rng.choice(options, p=weight / weight.sum()))]
        elif lay.idle in self.tiles.tiles[last.tile].tags:
            walk = [last.tile]  # the layer's one idle tile (no tile follows itself unless written to): held on
        else:
            try:
                walk = self.graph.walk(last.tile, lay.name, [lay.idle])
            except NoPath:
                return False
        begin = last.end
        for node in walk:
            lay.laid.append(Laid(node, begin, begin + self.tiles.tiles[node].beats))
            begin += self.tiles.tiles[node].beats
        return True

    def _commit(self, t: float, grid: Grid, lay: Layer, horizon: float) -> None:
        """Hand the notes that sound before ``horizon`` to the output; drop played tiles."""
        for laid in lay.laid:
            start_time = grid.time(laid.start)
            if start_time > horizon:
                break
            tile = self.tiles.tiles[laid.tile]
            if not laid.begun:
                laid.begun = True
                self._begin(t, grid, lay, laid, start_time)
            part = self.spec.parts.get(tile.part)
            while laid.sent < len(tile.onsets):
                beat = laid.start + tile.onsets[laid.sent]
                if beat >= laid.end - 1e-9:
                    laid.sent = len(tile.onsets)
                    break
                at = grid.time(beat)
                if at > horizon:
                    break
                length = min(tile.lengths[laid.sent], laid.end - beat)
                velocity = int(tile.velocities[laid.sent])
                if part is not None and part.energy is not None:  # the character's movement in the music
                    velocity = max(1, round(velocity * (0.55 + 0.45 * min(max(self._saliency(part.energy, t), 0.0), 1.0))))
                self.creature.play(int(tile.pitches[laid.sent]), velocity, grid.seconds(beat, length), at=at,
                                   channel=None if part is None else part.channel)
                lay.committed = max(lay.committed, at)
                laid.sent += 1
        # Played tiles go, but the last stays: the walk goes on from it.
        while len(lay.laid) > 1 and lay.laid[0].begun and grid.time(lay.laid[0].end) <= t:
            lay.laid.pop(0)

    def _begin(self, t: float, grid: Grid, lay: Layer, laid: Laid, at: float) -> None:
        """A tile starts: log it, and set its part's program from the stance."""
        tile = self.tiles.tiles[laid.tile]
        self.creature.world.log.emit(t, "tile", creature=self.creature.name, layer=lay.name, tile=tile.name,
                                     part=tile.part, tags=sorted(tile.tags), beat=laid.start, time=at,
                                     period=grid.period, steered=laid.request != 0)
        part = self.spec.parts.get(tile.part)
        if part is None or len(part.programs) < 1 or tile.silent:
            return
        glad = part.stance is not None and self._saliency(part.stance, t) >= 0.5
        program = part.programs[min(int(glad), len(part.programs) - 1)]
        if self._programs.get(tile.part) != program:
            self._programs[tile.part] = program
            self.creature.world.scheduler.send_at(at, mido.Message("program_change", channel=part.channel,
                                                                  program=program))

    def _modulate(self, t: float, grid: Grid, horizon: float) -> None:
        """CC 74 from each part's stance and CC 11 from its visibility, once a beat."""
        beat = math.floor(grid.beat(horizon) + 1e-9)
        if beat <= self._modulated:
            return
        self._modulated = beat
        at = max(t, grid.time(beat))
        for part in self.spec.parts.values():
            for control, percept, low, high in ((74, part.stance, 20, 120), (11, part.visible, 50, 127)):
                if percept is None:
                    continue
                value = int(round(low + (high - low) * min(max(self._saliency(percept, t), 0.0), 1.0)))
                if abs(self._controls.get((part.channel, control), -99) - value) >= 2:
                    self._controls[(part.channel, control)] = value
                    self.creature.world.scheduler.send_at(at, mido.Message("control_change", channel=part.channel,
                                                                          control=control, value=value))
                    if self.band is not None:
                        self.band.control(at, part.channel, control, value)

    def _saliency(self, percept: str, t: float) -> float:
        return float(self.creature.percept(percept).evaluate(t))
