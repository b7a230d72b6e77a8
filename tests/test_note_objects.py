"""Note objects in space: placing heard notes, striking, perturbing, sticking, decaying."""

from __future__ import annotations

import numpy as np
import pytest

from midi.note_objects import NoteObject, NoteSpace
from midi.notes import NoteEvent
from midi.scheduler import NoteScheduler
from midi.sinks import MemorySink


@pytest.fixture
def space(clock) -> NoteSpace:
    return NoteSpace(NoteScheduler(MemorySink(), clock), clock, half_life=1.0, ring_on=0.5)


def test_nearest_and_within_agree_with_brute_force(space, rng):
    points = rng.uniform(-5, 5, (200, 3))
    for i, p in enumerate(points):
        space.place(NoteEvent(0.0, 40 + i % 40, 100), p)
    for query in rng.uniform(-6, 6, (50, 3)):
        distances = np.linalg.norm(points - query, axis=1)
        assert space.nearest(query) is space.objects[int(np.argmin(distances))]
        near = space.within(query, 2.0)
        assert [space.objects.index(o) for o in near] == [int(i) for i in np.argsort(distances, kind="stable") if distances[i] <= 2.0]
    assert NoteSpace(space.scheduler, space.clock).nearest([0, 0, 0]) is None


def test_placed_copy_of_a_heard_note_plays_when_struck(space, clock):
    heard = NoteEvent(3.0, 62, 80, 2, 0.4)
    note = space.place(heard, [1.0, 0.0, 0.0])
    clock.advance_to(10.0)
    space.strike(note)
    space.tick()
    clock.advance(0.5)
    space.tick()
    notes = space.scheduler.sink.notes()
    assert [(n.time, n.pitch, n.velocity, n.channel, n.duration) for n in notes] == [(10.0, 62, 80, 2, pytest.approx(0.4))]
    assert note.handle is None  # it has stopped sounding


def test_striking_a_sounding_note_perturbs_it_instead_of_retriggering(space, clock):
    note = space.add(NoteObject([0, 0, 0], pitch=60, velocity=64, duration=1.0))
    space.strike(note, 0.5)
    space.tick()
    clock.advance(0.5)
    space.strike(note, 1.0)  # still sounding: swell and ring on, no second note-on
    space.tick()
    clock.advance(10.0)
    space.tick()
    messages = space.scheduler.sink.messages
    assert [m.type for _, m in messages if m.type == "note_on" and m.velocity > 0] == ["note_on"]
    touch = [m for _, m in messages if m.type == "polytouch"]
    assert len(touch) == 1 and touch[0].note == 60 and touch[0].value > 64
    (played,) = space.scheduler.sink.notes()
    assert played.velocity == 32  # first strike at half strength
    assert played.duration == pytest.approx(1.0 + 0.5 * 1.0 * 1.0)  # rang on by ring_on × duration


def test_stuck_note_sounds_until_released(space, clock):
    note = space.add(NoteObject([0, 0, 0], pitch=48, duration=0.1, stuck=True))
    space.strike(note)
    space.tick()
    clock.advance(30.0)
    space.tick()
    assert space.is_sounding(note)
    space.strike(note)  # perturbs, never ends it
    clock.advance(30.0)
    space.tick()
    assert space.is_sounding(note)
    space.release(note)
    space.tick()
    assert not space.is_sounding(note)
    (played,) = space.scheduler.sink.notes()
    assert played.duration == pytest.approx(60.0)


def test_energy_halves_every_half_life_of_clock_time(space, clock):
    note = space.add(NoteObject([0, 0, 0], pitch=70))
    space.strike(note, 1.0)
    assert note.energy == pytest.approx(1.0)
    for _ in range(4):  # tick rate must not matter, only elapsed time
        clock.advance(0.25)
        space.tick()
    assert note.energy == pytest.approx(0.5)
    clock.advance(2.0)
    space.tick()
    assert note.energy == pytest.approx(0.125)


def test_removed_note_is_silenced_and_forgotten(space, clock):
    a = space.add(NoteObject([0, 0, 0], pitch=60, duration=5.0))
    b = space.add(NoteObject([3, 0, 0], pitch=67))
    space.strike(a)
    space.tick()
    space.remove(a)
    assert space.nearest([0, 0, 0]) is b and len(space) == 1
    assert not space.scheduler.sounding


def test_invalid_note_object_is_refused():
    with pytest.raises(ValueError, match="pitch must be an int in 0..127"):
        NoteObject([0, 0, 0], pitch=130)
    with pytest.raises(ValueError):
        NoteObject([0, 0], pitch=60)
