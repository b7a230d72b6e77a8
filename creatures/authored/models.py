"""The built-in duration models a Du samples (thesis: "temporal models – duration models",
"low-integer-ratio duration models"): ``until = { gaussian = [4, 1] }`` and
``until = { pulse = 2 }`` are shorthands for ``until = { model = { type = "gaussian", … } }``. Every tuple resting on the colony's pulse
samples the one :class:`~creatures.runtime.pulse.HeardPulse` of its world, so they keep one time.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pydantic import BaseModel, Field

from creatures.authored.registry import MODELS, Params, Part
from creatures.behaviour.action_tuple import DurationModel
from creatures.behaviour.models.gaussian import GaussianModel
from creatures.bounds import LONGEST_SECONDS
from creatures.runtime.pulse import PulseDuration
from creatures.temporal.durations import MAX_DURATION, LowIntegerRatioModel
from creatures.temporal.readings import Level

if TYPE_CHECKING:
    from creatures.authored.creature import Authored


class ModelPart(Part):
    """A duration model type: ``build`` makes the model a Du samples and teaches."""

    def build(self, params: BaseModel, creature: "Authored") -> DurationModel:  # pragma: no cover
        raise NotImplementedError


class _GaussianParams(Params):
    # bounded as ``until.gaussian`` is: a spread of 1e300 overflowed the first sample's update
    mean: float = Field(gt=0, le=LONGEST_SECONDS, description="seconds")
    std: float = Field(gt=0, le=LONGEST_SECONDS, description="seconds")


@MODELS.register
class Gaussian(ModelPart):
    """A Gaussian duration, learnt from how long each activation actually lasted."""

    name = "gaussian"
    thesis = "temporal models"
    Params = _GaussianParams

    def build(self, params, creature):
        return GaussianModel(params.mean, params.std)


class _PulseParams(Params):
    beats: int = Field(2, ge=1, le=64, description="durations of the heard pulse (or steps of its 'level')")
    mean: float = Field(2.0, gt=0, le=LONGEST_SECONDS, description="fallback seconds until the pulse is trusted")
    std: float = Field(0.5, gt=0, le=LONGEST_SECONDS, description="fallback spread")
    level: Level | None = Field(
        None, description="steps of this level of the heard metre's pulse tree instead of the reading's ratios: "
                          "'bar' rests a bar of four in duple, of three in triple; a 'division' step is drawn as "
                          "the colony hears the beat filled (even halves, or long-short once the music swings) "
                          "(thesis 'exotic duration models'); none: durations drawn from the best reading's "
                          "low-integer ratios")


@MODELS.register
class Pulse(ModelPart):
    """``beats`` durations sampled from the colony's heard pulse (a low-integer-ratio model of
    what it hears), or ``beats`` steps of one level of its best reading's pulse tree: rests in
    the time of the music. Learns only from hearing."""

    name = "pulse"
    thesis = "low-integer-ratio duration models"
    Params = _PulseParams

    def build(self, params, creature):
        return PulseDuration(creature.world.pulse, GaussianModel(params.mean, params.std), beats=params.beats,
                             level=params.level)


class _RatioParams(Params):
    pulse: float = Field(0.5, gt=0, le=MAX_DURATION, description="prior pulse, seconds (at most an hour: "
                                                                 "the model's longest duration)")


@MODELS.register
class Ratio(ModelPart):
    """The tuple's own low-integer-ratio model, learnt from its activations' lengths."""

    name = "ratio"
    thesis = "low-integer-ratio duration models"
    Params = _RatioParams

    def build(self, params, creature):
        return LowIntegerRatioModel(params.pulse)
