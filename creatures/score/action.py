"""The ``score`` action: a tuple steers a layer of the creature's score (thesis, "(void *): a
cast of characters": "the layout of these tiles are placed under behavior-system control";
"pattern generators → motor programs").

``{ type = "score", layer = "theme", toward = "eddie" }`` walks the layer by A* to the nearest
tile tagged ``eddie`` (a character's leitmotif); ``pattern = ["eddie-head", "eddie-end"]``
walks to each tag in turn; ``program = "eddie: getTo eddie-head; getTo eddie-end; cycle 0"`` is
a pattern generator in the motor programs' language (creatures/score/program.py), laid out as
far ahead as the score looks, so the score knows its future. Done (for ``until = { done =
true }``) once the course has been played out (a cycling program: never, until the tuple
stops); the layer then walks through its idle tiles until a tuple steers it again.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

from pydantic import Field, model_validator

from creatures.authored.actions import ActionPart
from creatures.authored.registry import ACTIONS, Params
from creatures.behaviour.action_tuple import Action, ActionTuple
from creatures.motor.programs import chosen_program
from creatures.score.program import ScoreProgram

if TYPE_CHECKING:
    from creatures.authored.creature import Authored


class _ScoreParams(Params):
    layer: str = Field(description="the layer of [creature.score] it steers")
    toward: str | None = Field(None, description="a tag: the layer goes to the nearest tile carrying it")
    pattern: list[str] = Field(default_factory=list, max_length=64, description="tags to walk to in turn")
    program: str | None = Field(None, max_length=65536, description="a pattern generator: motor programs whose "
                                                                     "labels are tags ('name: getTo a; getTo b; "
                                                                     "cycle 0')")
    run: str | None = Field(None, description="which program of the text runs (default: the first)")

    @model_validator(mode="after")
    def _one(self):
        if sum((self.toward is not None, bool(self.pattern), self.program is not None)) != 1:
            raise ValueError("give one of 'toward' (a tag), 'pattern' (tags in turn) or 'program' (a pattern generator)")
        if self.program is not None:
            chosen_program(self.program, self.run, source="score program")
        return self

    def generator(self) -> Callable[[], ScoreProgram]:
        """A maker of a fresh running program (each start of the tuple runs it anew)."""
        if self.program is None:
            tags = [self.toward] if self.toward is not None else list(self.pattern)
            return lambda: ScoreProgram.of_tags(tags)
        library, first = chosen_program(self.program, self.run, source="score program")
        return lambda: ScoreProgram.start(library, first)

    def tags(self) -> list[str]:
        """Every tag it may walk to (the loader checks them against the tiles)."""
        if self.program is None:
            return [self.toward] if self.toward is not None else list(self.pattern)
        library, _ = chosen_program(self.program, self.run, source="score program")
        return sorted({str(x) for p in library.values() for st in p.statements for x in st.targets
                       if str(x) not in library})


class Steering(Action):
    """Lays its course on the layer when the tuple starts; done once it has been played; lays
    no more of it once the tuple stops."""

    def __init__(self, name: str, creature: "Authored", layer: str, generator: Callable[[], ScoreProgram]) -> None:
        super().__init__(name)
        self.creature, self.layer, self.generator = creature, layer, generator
        self.request = 0

    def start(self, t: float, tuple_: ActionTuple) -> None:
        self.request = self.creature.score.steer(t, self.layer, self.generator())

    def done(self, t: float) -> float:
        return self.creature.score.reached(self.request, t)

    def stop(self, t: float, *, interrupted: bool) -> None:
        self.creature.score.release(self.layer, self.request)


@ACTIONS.register
class Score(ActionPart):
    """Steer a layer of the score to a tag, through tags in turn, or by a pattern generator (a
    motor program over tags); needs ``[creature.score]``."""

    ends = True
    needs = "score"
    name = "score"
    thesis = "(void *): a cast of characters"
    Params = _ScoreParams

    def build(self, params, creature, name):
        return Steering(name, creature, params.layer, params.generator())
