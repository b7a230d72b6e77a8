"""Pattern generators: motor programs that lay tiles out (thesis, "(void *)", figure 36:
"pattern generators can act as intermediaries between behavior system and tile layout. These
can encode simple sequencing tasks better than Scoot's reactive behaviors ... pattern
generators can be used to predict the future"; and its mapping "pattern generators → motor
programs").

A score's program is written in the body's motor-program language (creatures/motor/programs.py)
with tags for labels::

    eddie: getTo eddie-head; getTo eddie-end; cycle 0

``getTo``/``getToClosest``/``forcedGetTo`` walk the layer by A* to the nearest tile carrying
any of the tags, ``getToFurthest`` to the furthest reachable; ``wait`` is the order a layout
already keeps; ``cycle n`` goes on from statement ``n``; ``end`` ends; a target naming another
program of the text runs it first. Each step lays one leg, so the layout asks for legs only as
far ahead as it looks: a cycling program predicts its layer's future ``lookahead`` beats at a
time, and a tuple that stops it leaves the rest unlaid.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from creatures.motor.programs import MotorProgram, Statement

STEPS_PER_LEG = 256
"""Statements stepped in search of one leg before a program is judged to lay nothing (a
cycle of waits)."""


@dataclass
class ScoreProgram:
    """A running program: the stack of (program, statement) cursors into a library."""

    library: dict[str, MotorProgram]
    stack: list[tuple[MotorProgram, int]] = field(default_factory=list)

    @classmethod
    def start(cls, library: dict[str, MotorProgram], name: str) -> "ScoreProgram":
        return cls(library, [(library[name], 0)])

    @classmethod
    def of_tags(cls, tags: list[str]) -> "ScoreProgram":
        """A pattern written as a list of tags: one ``getTo`` each, then the end."""
        program = MotorProgram("pattern", [Statement("getTo", (tag,)) for tag in tags])
        return cls.start({"pattern": program}, "pattern")

    def next_leg(self) -> Statement | None:
        """The next statement that lays tiles (a ``getTo`` of tags), or None at the end."""
        for _ in range(STEPS_PER_LEG):
            if not self.stack:
                return None
            program, cursor = self.stack[-1]
            stmt = program.statement(cursor)
            after = program.advance(cursor, None, 0.0)  # a linear program's flow needs no motor
            if after is None:
                self.stack.pop()
                continue
            self.stack[-1] = (program, after)
            if stmt.op in ("wait", "cycle"):
                continue
            called = [t for t in stmt.targets if isinstance(t, str) and t in self.library]
            if called:
                self.stack.append((self.library[called[0]], 0))
                continue
            return stmt
        return None
