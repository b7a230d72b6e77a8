"""``[input.trainer]``: a simulated clicker trainer for offline runs, and its checks.

Thesis, *Duncan* ("clicker training"): a trainer says a cue, watches the dog, and clicks when
it does what the cue asked. Offline there is no person, so this section describes one: the
words it says (spoken by the project's formant voices), what each asks for, how long it
waits, and how it shapes a graded trick. The trainer itself is
:mod:`creatures.runtime.trainer`.

A cue is said as one formant word of its vowels (:func:`audio.formants.vowels_of`: "lie
down" is "ieo"). The ear that hears it takes each sound's mean spectrum out (cepstral mean
normalisation, :mod:`audio.cepstrum`), so a word of one vowel is a steady spectrum with
nothing left to tell it from another: measured with duncan's ear (ten of each, pitch,
stretch and level drawn from the defaults' ranges), formant "sit", "down" and "beg" (i, o, e)
lay 0.32–0.98 from their own repeats and 0.32–1.06 from each other: no classes at all. A cue
therefore needs at least two vowels, and two cues must not be the same word. ("seated", "lie
down", "paws up" — eae, ieo, au — lay 0.11–0.34 from their own repeats and 0.92–1.72 from
each other; the ear's radius is 0.36.)
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

from pydantic import BaseModel, Field, field_validator, model_validator

from audio.formants import vowels_of
from creatures.bounds import FINITE
from creatures.config import config_error, nearest

if TYPE_CHECKING:
    from creatures.kinds.base import CreatureKind, CreatureSpec
    from creatures.runtime.input_routes import Route

LONGEST_CUE = 1.0
"""Seconds a cue may last (three vowels at the longest stretch, 1.5, take 0.71 s): the shortest
gap between two cues leaves this before the first cue's window."""


Window = Annotated[float, Field(gt=0, le=60)]
Every = Annotated[float, Field(ge=0.5, le=3600.0)]
Pitch = Annotated[float, Field(ge=50.0, le=400.0)]
Stretch = Annotated[float, Field(ge=0.5, le=1.5)]
Level = Annotated[float, Field(ge=0.001, le=0.5)]
"""The ranges' ends, each bounded as every number of the schema is (tests/test_reliability_numbers.py)."""


LIVE = ("[input.trainer] is for offline runs: live, a person says the cues into the microphone and clicks "
        "(OSC, MIDI); the simulated trainer is left out")
"""What a live run says of a config with a trainer."""


def _span(value: tuple[float, float]) -> tuple[float, float]:
    if value[0] > value[1]:
        raise ValueError(f"a range [low, high]: {value[0]:g} is above {value[1]:g}")
    return value


class TrainerSection(BaseModel):
    """A simulated clicker trainer, offline runs only (a live run says it leaves it out): it says
    cues into the audio a creature hears and clicks, through the input maps, when the creature
    holds the cued trick soon after (`creatures/runtime/trainer.py`)."""

    model_config = FINITE

    creature: str = Field(description="the creature it trains (a kind that does tricks: duncan)")
    cues: dict[str, str] = Field(min_length=1, max_length=32,
                                 description="spoken cue → the trick it asks for, e.g. {\"lie down\" = \"lie down\"}; "
                                             "a cue is said as one formant word of its vowels, so it needs two or "
                                             "more that change (\"sit\", one vowel, is heard as no word in "
                                             "particular: say \"seated\")")
    every: tuple[Every, Every] = Field((6.0, 8.0), description="seconds from one cue to the next, drawn from "
                                                               "this range, within 0.5..3600 (the first comes as long "
                                                               "after the start)")
    window: float = Field(2.0, gt=0, le=60, description="seconds after a cue has been said within which the trick "
                                                        "held is clicked")
    windows: dict[str, Window] = Field({"beg": 4.0}, description="tricks that take longer to get to, with their "
                                                                "own window (the default's tricks no cue asks for "
                                                                "are dropped)")
    shaping: str | None = Field("beg", description="the graded trick it shapes (Galbicka's percentile schedule): "
                                                   "clicked only if held at least as high as the median of the "
                                                   "last `bar` offered after its cue; none = clicked at any height")
    bar: int = Field(5, ge=1, le=100, description="offers of the shaped trick whose median height is the bar")
    click: str = Field("/click", pattern=r"^/[^\s#*,?\[\]{}]*$",
                       description="the OSC address its clicks send through the [[input]] maps (the same path "
                                   "as a real clicker's; a map with to = \"reward\" must take it)")
    pitch: tuple[Pitch, Pitch] = Field((100.0, 150.0), description="its voice's pitch range, Hz, within 50..400 "
                                                                   "(each cue's drawn from it by the run's seed)")
    stretch: tuple[Stretch, Stretch] = Field((0.85, 1.2), description="how much slower or faster it says a cue, "
                                                                  "a range within 0.5..1.5 (1 = a vowel in 0.15 s)")
    level: tuple[Level, Level] = Field((0.05, 0.12), description="loudness of a cue, RMS, a range within 0.001..0.5")

    @field_validator("every", "pitch", "stretch", "level")
    @classmethod
    def _ranges(cls, value: tuple[float, float]) -> tuple[float, float]:
        return _span(value)

    @field_validator("cues")
    @classmethod
    def _words(cls, cues: dict[str, str]) -> dict[str, str]:
        said: dict[str, str] = {}
        for cue in cues:
            vowels = vowels_of(cue)
            if len(vowels) < 2:
                raise ValueError(f"{cue!r} is said as the one vowel {vowels!r}: the ear takes out a sound's mean "
                                 "spectrum, so one steady vowel is heard as no word in particular; choose a cue "
                                 "whose vowels change (\"seated\", \"lie down\", \"paws up\")")
            if vowels in said:
                raise ValueError(f"{cue!r} and {said[vowels]!r} are said as one formant word ({vowels!r}): the "
                                 "creature could not tell them apart")
            said[vowels] = cue
        return cues

    @model_validator(mode="after")
    def _gaps(self) -> "TrainerSection":
        if "windows" not in self.model_fields_set:  # the default's entries for tricks no cue asks for
            self.windows = {trick: w for trick, w in self.windows.items() if trick in self.cues.values()}
            self.model_fields_set.discard("windows")
        longest = max([self.window, *self.windows.values()]) + LONGEST_CUE
        if self.every[0] < longest:
            raise ValueError(f"every: cues {self.every[0]:g} s apart overlap the windows (a cue and its longest "
                             f"window take up to {longest:g} s): a trick held for one cue would be clicked "
                             f"for the next")
        return self

    def window_of(self, trick: str) -> float:
        """Seconds after its cue a ``trick`` is clicked within."""
        return self.windows.get(trick, self.window)


def check_trainer(section: TrainerSection, specs: list["CreatureSpec"], kinds: dict[str, type["CreatureKind"]],
                  path: Path, where: dict) -> None:
    """What ``[input.trainer]`` names must be this installation's: its creature (a kind that
    does tricks), each cue's trick, each window's and the shaped trick (a graded one).
    Raises :class:`ConfigError` at the key's line, with the nearest name."""
    at = ("input", "trainer")
    by_name = {spec.name: spec for spec in specs}
    spec = by_name.get(section.creature)
    if spec is None:
        raise config_error(path, where, (*at, "creature"), f"no creature named {section.creature!r}"
                                                           + nearest(section.creature, sorted(by_name), "creatures"))
    kind = kinds[spec.kind]
    tricks = kind.tricks(spec)
    if not tricks:
        raise config_error(path, where, (*at, "creature"), f"{spec.name!r} is a {spec.kind!r} creature, which does "
                                                           "no tricks to train (a duncan does)")
    for cue, trick in section.cues.items():
        if trick not in tricks:
            raise config_error(path, where, (*at, "cues", cue), f"{spec.name!r} has no trick {trick!r}"
                                                                + nearest(trick, tricks, "its tricks"))
    for trick in section.windows:
        if trick not in section.cues.values():
            raise config_error(path, where, (*at, "windows", trick), f"no cue asks for {trick!r}"
                                                                     + nearest(trick, sorted(set(section.cues.values())),
                                                                               "the cues' tricks"))
    shaped = section.shaping
    if shaped is not None and shaped not in section.cues.values() and "shaping" in section.model_fields_set:
        raise config_error(path, where, (*at, "shaping"), f"no cue asks for {shaped!r}"
                                                          + nearest(shaped, sorted(set(section.cues.values())),
                                                                    "the cues' tricks"))
    if shaped is not None and shaped in section.cues.values() and shaped not in kind.graded_tricks(spec):
        raise config_error(path, where, (*at, "shaping"), f"{spec.name!r} holds {shaped!r} at no height to shape"
                                                          + nearest(shaped, kind.graded_tricks(spec), "graded tricks"))


def unrewarded(section: TrainerSection, routes: list["Route"]) -> str | None:
    """What loading says (a note, not an error: rehearsing a piece without its clicker is a
    choice) when no ``[[input]]`` map turns the trainer's click into a reward."""
    if any(route.spec.to == "reward" and route.matches_osc(section.click, ()) for route in routes):
        return None
    return (f"[input.trainer] clicks {section.click!r}, and no [[input]] map with to = \"reward\" takes it: "
            "its clicks reward nothing")
