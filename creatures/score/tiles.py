"""Tiles: the small segments of precomposed music a score is built from (thesis, "(void *): a
cast of characters": "small segments of music pre-composed by a human musician were
dynamically ordered, stretched, overlaid and arranged just before it has to be played").

A tile file is TOML, one ``[tiles.NAME]`` table per tile, written in beats so that the output
layer can stretch it to any tempo::

    meter = 4                      # beats in a bar (where a layer may cut in, with cut = "bar")

    [tiles.eddie-1]
    layer = "theme"                # which layer of the score plays it (overlaid on the others)
    part = "eddie"                 # whose music it is: a channel, a timbre and a balance
    beats = 4                      # its length; the next tile of its layer starts there
    tags = ["eddie"]               # what the behaviour system may ask for ("leitmotif")
    follows = ["eddie-2"]          # the composer's own successions, favoured by the metric
    notes = [[0, "D5", 90, 1], [1, "F5", 80, 0.5]]   # [beat, pitch, velocity, length in beats]

Every problem names the file, the key and its line (and the nearest valid key or tile).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from pydantic import BaseModel, Field, field_validator, model_validator

from creatures.bounds import FINITE
from creatures.config import config_error, nearest, read_toml, validate
from creatures.runtime.input_map import Unreadable, as_pitch
from midi.fifths import fifths_vector

if TYPE_CHECKING:
    from creatures.score.spec import ScoreSpec

LONGEST_TILE = 256.0
"""Beats: the longest tile (64 bars of 4)."""

SHORTEST_TILE = 1 / 16
"""Beats: the shortest tile (a sixty-fourth note in 4/4). A layer lays tiles until it reaches
its lookahead, so one of next to no beats (1e-300: 1.0 + 1e-300 is 1.0) never got it there
and the run hung at its first tick, laying tiles until memory ran out; one of 1/16 takes at
most 16 × 64 tiles to fill the longest lookahead."""

class TileTable(BaseModel):
    """One ``[tiles.NAME]`` table."""

    model_config = FINITE

    layer: str = Field("bed", description="the layer that plays it: tiles of one layer follow each other, layers overlay")
    part: str = Field("band", description="whose music it is (a channel, timbre and balance in [creature.score.parts])")
    beats: float = Field(ge=SHORTEST_TILE, le=LONGEST_TILE, description="its length in beats")
    tags: list[str] = Field(default_factory=list, max_length=32, description="what the behaviour system may ask for")
    follows: list[str] = Field(default_factory=list, max_length=64, description="tiles the composer wrote to follow it")
    notes: list[tuple[float, int | str, int, float]] = Field(default_factory=list, max_length=4096,
                                                             description="[beat, pitch, velocity, length in beats]")

    @field_validator("notes")
    @classmethod
    def _notes(cls, notes: list) -> list[tuple[float, int, int, float]]:
        out = []
        for beat, pitch, velocity, length in notes:
            try:
                midi = as_pitch(pitch)
            except Unreadable as exc:
                raise ValueError(f"note at beat {beat}: {exc}") from None
            if not 1 <= velocity <= 127 or not length > 0 or beat < 0:
                raise ValueError(f"note at beat {beat}: velocity 1–127, a positive length and a beat ≥ 0 please")
            out.append((float(beat), midi, int(velocity), float(length)))
        return out

    @model_validator(mode="after")
    def _inside(self):
        late = [n for n in self.notes if n[0] >= self.beats]
        if late:
            raise ValueError(f"a note starts at beat {late[0][0]}, not inside the tile's {self.beats} beats")
        return self


class TileFile(BaseModel):
    """A whole tile file."""

    model_config = FINITE

    meter: int = Field(4, ge=1, le=32, description="beats in a bar")
    tiles: dict[str, TileTable] = Field(min_length=1, max_length=4096)


@dataclass(frozen=True, eq=False)
class Tile:
    """One tile, its notes as arrays in beats from its start, in time order (the node's content)."""

    name: str
    layer: str
    part: str
    beats: float
    tags: frozenset[str]
    follows: tuple[str, ...]
    onsets: np.ndarray
    pitches: np.ndarray
    velocities: np.ndarray
    lengths: np.ndarray

    @property
    def silent(self) -> bool:
        return len(self.pitches) == 0

    def opening(self) -> np.ndarray:
        """The pitches sounding at its first onset (what a predecessor must lead into)."""
        return self.pitches[self.onsets == self.onsets.min()] if len(self.onsets) else self.pitches

    def closing(self) -> np.ndarray:
        """The pitches still sounding at its end, or its last onset's (what it leads out of)."""
        if not len(self.onsets):
            return self.pitches
        held = self.pitches[self.onsets + self.lengths >= self.beats - 1e-9]
        return held if len(held) else self.pitches[self.onsets == self.onsets.max()]

    def key(self) -> np.ndarray:
        """Its place on the circle of fifths, weighted by how long each note sounds (midi/fifths.py)."""
        return fifths_vector(self.pitches, self.lengths)


@dataclass(frozen=True)
class TileSet:
    """Every tile of a file, by index, and the meter."""

    tiles: tuple[Tile, ...]
    meter: int
    file: Path
    where: dict[tuple, tuple[Path, int]] = field(default_factory=dict, compare=False, repr=False)
    """Key path → (file, line), so a problem found after loading still names the tile's line."""

    def __len__(self) -> int:
        return len(self.tiles)

    def index(self, name: str) -> int:
        return next(i for i, t in enumerate(self.tiles) if t.name == name)

    @property
    def layers(self) -> list[str]:
        return sorted({t.layer for t in self.tiles})

    def tags(self, layer: str | None = None) -> list[str]:
        return sorted({tag for t in self.tiles if layer in (None, t.layer) for tag in t.tags})

    @property
    def parts(self) -> list[str]:
        return sorted({t.part for t in self.tiles})


def load_tiles(path: str | Path) -> TileSet:
    """Read and check a tile file (raises :class:`~creatures.config.ConfigError`)."""
    path = Path(path).resolve()
    data, where = read_toml(path)
    spec = validate(TileFile, data, where, path)
    names = list(spec.tiles)
    for name, table in spec.tiles.items():
        for k, other in enumerate(table.follows):
            if other not in spec.tiles:
                raise config_error(path, where, ("tiles", name, "follows", k),
                                   f"no tile {other!r}{nearest(other, names, 'tiles')}")
            if spec.tiles[other].layer != table.layer:
                raise config_error(path, where, ("tiles", name, "follows", k),
                                   f"{other!r} is in layer {spec.tiles[other].layer!r}, not {table.layer!r}: "
                                   "only tiles of one layer follow each other")
    tiles = []
    for name, t in spec.tiles.items():
        notes = np.array(t.notes, dtype=float).reshape(-1, 4)
        notes = notes[np.argsort(notes[:, 0], kind="stable")]  # in time order: the output takes them so
        tiles.append(Tile(name, t.layer, t.part, t.beats, frozenset(t.tags), tuple(t.follows), notes[:, 0],
                          notes[:, 1].astype(np.int64), notes[:, 2].astype(np.int64), notes[:, 3]))
    return TileSet(tuple(tiles), spec.meter, path, where)


def unplayed_layers(scores: dict[str, "ScoreSpec"]) -> list[str]:
    """What to say of the layers of tile files that no score reading them plays.

    ``scores`` are the colony's ``[creature.score]`` tables by creature, their ``tiles``
    resolved. A layer no ``[creature.score.layers]`` table names is never laid, so its tiles
    never sound, and nothing at run time says so. That is no error in itself: a tile file
    shared by two scores (or by two installations) may hold layers one of them leaves out.
    So a layer is looked at across every score reading its file, and the note names the
    layer, the line of its first tile and the nearest declared layer. A file read by one
    score whose unplayed layer is near one it declares ("theem", "theme") is a typo that
    silences those tiles for the whole run: a :class:`~creatures.config.ConfigError` at the
    tile's line, as an unknown name in a config is. Returns the notes.
    """
    readers: dict[str, list[str]] = {}
    for creature, score in scores.items():
        readers.setdefault(score.tiles, []).append(creature)
    notes = []
    for file, creatures in readers.items():
        tiles = load_tiles(file)
        declared = sorted({layer for creature in creatures for layer in scores[creature].layers})
        for layer in tiles.layers:
            if layer in declared:
                continue
            dead = [t.name for t in tiles.tiles if t.layer == layer]
            loc = ("tiles", dead[0], "layer")
            default = "" if loc in tiles.where else f" (a tile with no 'layer' is in {layer!r})"
            whose = " or ".join(repr(creature) for creature in creatures)
            named = f"{', '.join(dead[:4])}{', …' if len(dead) > 4 else ''}"
            message = (f"layer {layer!r}{default} is in no [creature.score.layers] of {whose}"
                       f"{nearest(layer, declared, 'layers there')}: "
                       + (f"its {len(dead)} tiles ({named}) never play" if len(dead) > 1 else
                          f"its tile {named!r} never plays"))
            problem = config_error(tiles.file, tiles.where, loc, message)
            if len(creatures) == 1 and difflib.get_close_matches(layer, declared, n=1):
                raise problem
            notes.append(str(problem))
    return notes
