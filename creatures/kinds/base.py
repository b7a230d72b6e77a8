"""What every creature kind provides to the runtime.

A creature kind (exchange, listen, soundcreatures, …) composes behaviour, perception, motor
and voice parts; the runtime only talks to it through :class:`CreatureKind`, so live and
offline runs, tests and the inspector treat every kind alike (py_trees' lesson: one life
cycle for everything).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from pydantic import BaseModel, Field

from creatures.bounds import FINITE

if TYPE_CHECKING:
    from pathlib import Path

    from creatures.runtime.world import World
    from midi.notes import NoteEvent


class CreatureSpec(BaseModel):
    """Keys every ``[[creature]]`` table accepts; kinds subclass this with their own keys."""

    model_config = FINITE

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_\-]+$", description="unique name (letters, digits, _ and -)")
    kind: str = Field(description="which creature kind (the sections below)")
    channel: int = Field(0, ge=0, le=15, description="MIDI channel this creature plays on")
    gain: float = Field(0.8, ge=0.0, le=4.0, description="linear gain of its voice in the mix")
    pan: float = Field(0.0, ge=-1.0, le=1.0, description="stereo position of its voice")


class CreatureKind(ABC):
    """A creature in a run. Subclasses set ``Spec`` and implement :meth:`tick`.

    The runtime calls, in order, every behaviour tick: :meth:`hear` for notes that fell due,
    :meth:`listen` for audio input, :meth:`tick`; then :meth:`sound` for each audio block and
    :meth:`figure` for each video frame. Creatures play by calling ``world.play(self, note)``.
    """

    Spec: ClassVar[type[CreatureSpec]] = CreatureSpec

    def __init__(self, spec: CreatureSpec, world: "World", rng: np.random.Generator) -> None:
        self.spec = spec
        self.name = spec.name
        self.world = world
        self.rng = rng

    def hear(self, note: "NoteEvent", source: str) -> None:
        """A note played by ``source`` (another creature's name, or "input") started."""

    def played(self, note: "NoteEvent") -> None:
        """One of this creature's own notes was scheduled (e.g. to start its voice)."""

    def listen(self, t: float, block: np.ndarray, sample_rate: int) -> None:
        """A block of audio input (mono float32) ending at clock time ``t``."""

    @abstractmethod
    def tick(self, t: float) -> None:
        """Perceive, select actions, move: one behaviour tick at clock time ``t``."""

    def sound(self, out: np.ndarray, sample_rate: int) -> None:
        """Fill ``out`` (mono, preallocated) with this creature's voice; default silent."""
        out[:] = 0.0

    def figure(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Joint positions ``(J, 3)`` and parents ``(J,)`` to draw, or None for no body."""
        return None

    def marks(self) -> list[tuple[tuple[float, float, float], int]]:
        """Note objects to draw in space as ``(position, pitch)``."""
        return []

    def finish(self, out: "Path") -> dict[str, "Path"]:
        """The run is over: write any kind-specific outputs into ``out`` (e.g. an edit
        decision list) and return them by name; default none."""
        return {}

    def state(self) -> dict[str, Any]:
        """JSON-able learned state, saved periodically and on exit."""
        return {}

    def restore(self, state: dict[str, Any]) -> None:
        """Take back what :meth:`state` returned (the same kind and config)."""
