"""``[creature.score]``: a creature whose motor system lays out tiles of precomposed music
(thesis, "(void *): a cast of characters"; keys documented in docs/config.md)."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, Field

from creatures.bounds import FINITE


class ScoreLayerSpec(BaseModel):
    """``[creature.score.layers.NAME]``: one layer of the score (layers are overlaid)."""

    model_config = FINITE

    idle: str = Field(description="tag of the tiles the layer walks through when no tuple steers it "
                                  "(a tacet tile keeps it quiet)")
    cut: int = Field(1, ge=0, le=64, description="beats between the places a new course may cut in: 1 = any beat, "
                                                 "the meter = bar lines, 0 = only where a tile ends")


class ScorePartSpec(BaseModel):
    """``[creature.score.parts.NAME]``: where a part of the tiles plays and what colours it."""

    model_config = FINITE

    channel: int = Field(ge=0, le=15, description="MIDI channel of the part")
    programs: list[Annotated[int, Field(ge=0, le=127)]] = Field(default_factory=list, max_length=2,
                                description="General MIDI programs [reluctant, glad]: the stance percept picks one "
                                            "at each of the part's tiles (timbre tied to the character's stance)")
    stance: str | None = Field(None, description="percept of the character's stance toward its visitor: the program, "
                                                 "and CC 74 (brightness) every beat")
    visible: str | None = Field(None, description="percept of whether the character is seen: CC 11 (expression) "
                                                  "every beat, so what is on screen leads the balance")
    energy: str | None = Field(None, description="percept of how the character moves (a possessed dancer's kick): "
                                                 "each of the part's notes at 55 % of its written velocity at 0, "
                                                 "as written at 1")


class ScoreSpec(BaseModel):
    """``[creature.score]``: the tiles and how they are laid out."""

    model_config = FINITE

    tiles: str = Field(description="the tile file (TOML, relative to the config; creatures/score/tiles.py)")
    tempo: float = Field(96.0, ge=20, le=300, description="beats a minute while no pulse is heard, and the tempo "
                                                          "the heard pulse is matched to (a power-of-two multiple)")
    follow: bool = Field(True, description="follow the colony's heard pulse: tempo (time stretch) and phase "
                                           "(time shift)")
    lookahead: float = Field(2.0, ge=0, le=64, description="beats laid out ahead of what is committed (the pattern "
                                                           "generator's prediction of the future); laid tiles may "
                                                           "still change until committed")
    commit: float = Field(0.05, gt=0, le=2.0, description="seconds before they sound that notes are handed to the "
                                                          "output (at least a tick): just in time")
    layers: dict[str, ScoreLayerSpec] = Field(min_length=1, max_length=16, description="the layers, by the "
                                                                                       "tiles' layer names")
    parts: dict[str, ScorePartSpec] = Field(default_factory=dict, max_length=16,
                                            description="parts by the tiles' part names; a part not named "
                                                        "plays on the creature's channel")
