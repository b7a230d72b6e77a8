"""The ``score`` action: a tuple steers a layer of the creature's score (thesis, "(void *): a
cast of characters": "the layout of these tiles are placed under behavior-system control";
"pattern generators → motor programs").

``{ type = "score", layer = "theme", toward = "eddie" }`` walks the layer by A* to the nearest
tile tagged ``eddie`` (a character's leitmotif); ``pattern = ["eddie", "eddie", "cadence"]``
lays a whole sequence out at once, so the score knows its future (a pattern generator). Done
(for ``until = { done = true }``) once the course has been played out; the layer then walks
through its idle tiles until a tuple steers it again.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pydantic import Field, model_validator

from creatures.authored.actions import ActionPart
from creatures.authored.registry import ACTIONS, Params
from creatures.behaviour.action_tuple import Action, ActionTuple

if TYPE_CHECKING:
    from creatures.authored.creature import Authored


class _ScoreParams(Params):
    layer: str = Field(description="the layer of [creature.score] it steers")
    toward: str | None = Field(None, description="a tag: the layer goes to the nearest tile carrying it")
    pattern: list[str] = Field(default_factory=list, max_length=64,
                               description="tags laid out in order at once (a pattern generator); instead of toward")

    @model_validator(mode="after")
    def _one(self):
        if (self.toward is None) == (not self.pattern):
            raise ValueError("give either 'toward' (a tag) or 'pattern' (tags in order)")
        return self

    def tags(self) -> list[str]:
        return [self.toward] if self.toward is not None else list(self.pattern)


class Steering(Action):
    """Lays its course on the layer when the tuple starts; done once it has been played."""

    def __init__(self, name: str, creature: "Authored", layer: str, tags: list[str]) -> None:
        super().__init__(name)
        self.creature, self.layer, self.tags = creature, layer, tags
        self.request = 0

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.request = self.creature.score.steer(t, self.layer, self.tags)

    def done(self, t: float) -> float:
        return self.creature.score.reached(self.request, t)


@ACTIONS.register
class Score(ActionPart):
    """Steer a layer of the score to a tag, or through a pattern of tags (needs ``[creature.score]``)."""

    ends = True
    needs = "score"
    name = "score"
    thesis = "(void *): a cast of characters"
    Params = _ScoreParams

    def build(self, params, creature, name):
        return Steering(name, creature, params.layer, params.tags())
