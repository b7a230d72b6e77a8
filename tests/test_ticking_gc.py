"""The live loop's garbage collection (creatures/runtime/ticking.py): automatic full
collections held off while a run lasts, young ones in the waits between ticks, a full one
every FULL_COLLECT_EVERY seconds, and none in a wait too short for it."""

from __future__ import annotations

import gc
from types import SimpleNamespace

import pytest

from creatures.clock import SimulatedClock
from creatures.runtime import ticking
from creatures.runtime.ticking import IDLE_COLLECT, IdleCollections, TickLoop, setup_kept


@pytest.fixture
def collections(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls: list[int] = []
    monkeypatch.setattr(ticking.gc, "collect", lambda generation=2: calls.append(generation) or 0)
    return calls


def test_setup_kept_holds_full_collections_off_and_gives_them_back() -> None:
    before = gc.get_threshold()
    with setup_kept() as collect:
        assert gc.get_threshold()[:2] == before[:2]
        assert gc.get_threshold()[2] == ticking.HELD_OFF
        assert isinstance(collect, IdleCollections)
    assert gc.get_threshold() == before


def test_young_generations_once_a_wait_and_a_full_collection_on_its_cadence(collections: list[int]) -> None:
    collect = IdleCollections(full_every=1.0)
    collect(0.000, 0.040)  # a whole tick's wait: the young generations
    collect(0.001, 0.040)  # the same wait: nothing more
    collect(0.037, 0.040)  # a wait too short for any collection
    assert collections == [1]
    for k in range(1, 30):
        collect(k * 0.04, k * 0.04 + 0.04)
    assert collections.count(2) == 1 and collections.index(2) == 25  # at 1.0 s, not before
    assert collections.count(1) == len(collections) - 1


def test_the_loop_collects_only_in_waits_long_enough(collections: list[int]) -> None:
    wall = SimulatedClock(0.0)
    world = SimpleNamespace(listeners=[], deliver=lambda t: 0)
    session = SimpleNamespace(world=world, scheduler=SimpleNamespace(pump=lambda: 0))
    inputs = SimpleNamespace(poll=lambda t: 0)
    waits: list[float] = []

    def wait(seconds: float) -> None:
        waits.append(seconds)
        wall.advance_to(wall.now() + seconds)

    loop = TickLoop(session, inputs, wall, SimulatedClock(0.0), 0.04, wait=wait)
    loop.collect = IdleCollections()
    ticks: list[float] = []
    loop.run(ticks.append, until=lambda t: t > 0.2)
    assert len(ticks) == 5
    assert collections == [1] * 5  # one young collection in each tick's wait, no full one
    short = IdleCollections()
    short(0.04 - IDLE_COLLECT, 0.04)
    assert collections == [1] * 5
