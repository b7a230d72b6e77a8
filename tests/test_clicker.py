"""The thesis's dog learns "sit" on cue (thesis: "credit assignment", the clicker-training
scenario; must-show of the foundation issue).

A scripted trainer says "sit" at random times and puts food down if a sit is *selected*
within 2 s of the cue. Nothing rewards the dog directly: food makes the consummatory
``food | eat`` tuple (V = 100, not plastic: value grounded in food) win, and credit assignment
carries β·100 back to every "sit" tuple in proportion to its trigger at the time the sit
began. ``cue | sit`` only learns when the cue was heard; ``whatever | sit`` learns from every
rewarded sit but is also pulled down by every unrewarded one (the following idle behaviour is
worth little), so spontaneous sitting stays rare.

Modelling choices, each thesis machinery: the heard command is a salient percept (saliency 4
for 1 s: saliencies above 1 are allowed on purpose, like the click); the food is salient
(saliency 5) so eating interrupts whatever the dog is doing; the idle repertoire is innate
(plasticity 0); selection uses the Boltzmann extension with T = 10. Probe trials afterwards
freeze learning (α = 0) so the measurement reads what 50 rewarded trials taught.
"""

from __future__ import annotations

import numpy as np

from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.percept import FunctionPercept, WhateverPercept
from creatures.behaviour.value import ScalarValue
from creatures.clock import SimulatedClock

DT = 0.1
WINDOW = 2.0
IDLE = ["wander", "lie down", "sniff", "scratch", "look around", "yawn", "stretch", "roll over"]


class Trainer:
    """Says "sit" and rewards a sit that starts within ``WINDOW`` seconds of the cue."""

    def __init__(self) -> None:
        self.cue_at = -np.inf
        self.food_until = -np.inf
        self.rewarding = True
        self.sat_at: list[float] = []

    def cue_saliency(self, t: float) -> float:
        return 4.0 if 0.0 <= t - self.cue_at < 1.0 else 0.0

    def food_saliency(self, t: float) -> float:
        return 5.0 if t < self.food_until else 0.0

    def watch(self, event: dict) -> None:
        """The trainer sees the dog start to sit (a selection of any "sit" tuple)."""
        if event["event"] == "selection" and event["tuple"].endswith("|sit"):
            t = event["t"]
            self.sat_at.append(t)
            if self.rewarding and 0.0 <= t - self.cue_at <= WINDOW and t > self.food_until:
                self.food_until = t + 1.5

    def sat_within(self, start: float) -> bool:
        return any(start <= t <= start + WINDOW for t in self.sat_at)


def make_dog(rng: np.random.Generator, trainer: Trainer) -> ActionGroup:
    whatever = WhateverPercept()
    cue = FunctionPercept("heard 'sit'", trainer.cue_saliency)
    food = FunctionPercept("food", trainer.food_saliency)
    tuples = [
        ActionTuple("whatever|sit", whatever, Action("sit"), DoUntil(1.0), 10.0),
        ActionTuple("cue|sit", cue, Action("sit"), DoUntil(1.0), 10.0),
        ActionTuple("food|eat", food, Action("eat"), DoUntil(1.0), ScalarValue(100.0, plasticity=0.0)),
    ]
    tuples += [
        ActionTuple(f"whatever|{name}", whatever, Action(name), DoUntil(2.0), ScalarValue(5.0, plasticity=0.0))
        for name in IDLE
    ]
    return ActionGroup("dog", tuples, rng=rng, alpha=0.1, discount=0.8, temperature=10.0, on_event=trainer.watch)


def live(dog: ActionGroup, clock: SimulatedClock, seconds: float) -> None:
    end = clock.now() + seconds
    while clock.now() < end:
        dog.tick(clock.now())
        clock.advance(DT)


def test_dog_learns_to_sit_on_cue():
    rng = np.random.default_rng(2001)
    clock = SimulatedClock()
    trainer = Trainer()
    dog = make_dog(rng, trainer)
    sit_before = {n: dog.find(n).value.to_float() for n in ("whatever|sit", "cue|sit")}

    rewarded = 0
    while rewarded < 50:  # training: long pauses, then a cue
        live(dog, clock, rng.uniform(120.0, 240.0))
        trainer.cue_at = clock.now()
        live(dog, clock, WINDOW)
        rewarded += trainer.sat_within(trainer.cue_at)
    live(dog, clock, rng.uniform(120.0, 240.0))

    # Probe trials: learning frozen, alternating cue / matched no-cue windows.
    dog.alpha = 0.0
    trainer.rewarding = False
    cued, uncued = [], []
    for k in range(200):
        live(dog, clock, rng.uniform(5.0, 10.0))
        start = clock.now()
        if k % 2 == 0:
            trainer.cue_at = start
        live(dog, clock, WINDOW)
        (cued if k % 2 == 0 else uncued).append(trainer.sat_within(start))

    p_cued, p_uncued = np.mean(cued), np.mean(uncued)
    print(f"P(sit | cue) = {p_cued:.2f} over {len(cued)}, P(sit | no cue) = {p_uncued:.2f} over {len(uncued)}")
    assert len(cued) >= 100 and len(uncued) >= 100
    assert p_cued >= 0.8
    assert p_uncued <= 0.3
    # The cue tuple learned (toward β·100 = 80); the untriggered sit stayed low.
    assert dog.find("cue|sit").value.to_float() > 70.0 > sit_before["cue|sit"]
    assert dog.find("whatever|sit").value.to_float() < 20.0


def test_without_reward_nothing_is_learned():
    """Control: the same dog and cues, but the trainer never feeds it — sit on cue does
    not appear, so the result above is the reward's doing, not the cue's saliency alone."""
    rng = np.random.default_rng(2001)
    clock = SimulatedClock()
    trainer = Trainer()
    trainer.rewarding = False
    dog = make_dog(rng, trainer)
    for _ in range(20):
        live(dog, clock, rng.uniform(120.0, 240.0))
        trainer.cue_at = clock.now()
        live(dog, clock, WINDOW)
    assert dog.find("cue|sit").value.to_float() <= 10.0
