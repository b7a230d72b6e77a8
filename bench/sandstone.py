"""sand:stone: how fast the shipped six-rock installation runs offline, and what the soft
state costs.

Rows (``python -m bench sandstone``):

* the shipped installation (six creatures) offline, with and without audio synthesis, in ×
  real time (target ≥ 20, the runtime's goal for a 3-creature installation — here with six);
* one soft-state step of a creature's chemistry whose inputs change every step (presence ×
  boredom), with the step's (Φ, Ψ) reused from :class:`Motivation`'s cache, beside the same
  step with a fresh matrix exponential (what a cache keyed on the inputs would pay).
"""

from __future__ import annotations


import numpy as np

from bench import Row, best_of
from bench.installations import offline_speed
from creatures.behaviour.motivation import Motivation




def _chemistry() -> Motivation:
    return Motivation({"desire": 0.0, "boredom": 0.0, "breath": 1.0, "pulse": 1.0},
                      decay={"desire": 0.03, "boredom": 0.03, "breath": 0.1, "pulse": 0.5},
                      coupling={("pulse", "desire"): 0.1, ("pulse", "boredom"): -0.1}, ceiling=2.0)


def _soft_steps(steps: int, *, fresh: bool) -> None:
    m, dt = _chemistry(), 0.1
    presence = np.linspace(0.0, 1.0, steps)
    for k in range(steps):
        m.set_input(k * dt, "desire", 0.3 * presence[k] * (1.0 - m.level("boredom")))
        if fresh:
            m._propagators.clear()
        m.advance((k + 1) * dt)


def run(quick: bool) -> list[Row]:
    seconds = 20.0 if quick else 60.0
    steps = 200 if quick else 2000
    cached = best_of(lambda: _soft_steps(steps, fresh=False)) / steps
    fresh = best_of(lambda: _soft_steps(steps, fresh=True)) / steps
    return [
        Row("sand:stone 6 rocks offline, with audio", offline_speed("sandstone", seconds, audio=True), "× real time", 20.0),
        Row("sand:stone 6 rocks offline, behaviour and MIDI only", offline_speed("sandstone", seconds, audio=False),
            "× real time", 20.0),
        Row("soft-state step, inputs changing, cached (Φ, Ψ)", cached * 1e6, "µs", 100.0, higher_is_better=False,
            baseline="fresh expm every step", ratio=fresh / cached),
    ]
