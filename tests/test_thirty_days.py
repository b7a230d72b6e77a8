"""Thirty simulated days of every shipped installation, reduced (issue 15, "no silent decay"):
every creature still selects actions on the last day, and its authored values hold.

A run of 30 × 24 h at a 0.05 s tick is 52 million ticks per piece; the test keeps what can
go wrong over those days and drops the ticks in between. Every behaviour advances from
elapsed clock time (drives integrate exactly over any interval, Du compare clock times,
credit assignment happens only when a tuple changes), so the clock fast-forwards one day at a
time and the colony lives a ``WINDOW`` of ordinary ticks at the start of each day, a visitor
playing the generated fragments into it (the soak, bench/soak.py, runs whole hours). What the
test asserts on day 30:

* every creature selected an action in the last window (nothing underflowed to no selection);
* in every group that keeps its values as authored (``alpha = 0``) each value is exactly as
  written, so its ratios hold; in a group that learns, every non-plastic value (the reward
  that grounds it) is exactly as written and every authored tuple is still worth at least
  ``FLOOR`` of the most valuable one (credit with nothing grounding it shrank lis's values
  geometrically, 3.0 → 7e-8 in one hour, before the loader refused such groups).

What it found, and what was fixed (seed 15): curve's Du models learnt each fast-forwarded day
as a duration (bow's 4 ± 1 s mirror had a mean of 70469 s by day 30 and held one mirror all
the last day); an activation across a clock gap no longer teaches its model
(``creatures.clock.CLOCK_GAP``). Ozymandias, grounded only by clicks that
stop after the first minute, let ``read`` and ``listen`` fall to 1.8e-4 of the click's value;
its ``listen`` is now a ground too (``creatures.kinds.ozymandias``). soundcreatures' ``sing``
fell to 0.014 (under 1 % of ``attend``) because both were deaf from the second day: their ears
dated sound by counting samples, so after the first night every utterance was a night old and
``attend``, the reward, never ran again; an ear now skips the gap (``Segmenter.skip``,
``creatures.clock.clock_gap``), as the colony's transcription does.
"""

from __future__ import annotations

import numpy as np
import pytest

import installations
from creatures.behaviour.action_group import ActionGroup
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.inputs import phrase_notes, render_notes
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from creatures.runtime.speech_input import spoken_poem
from midi.sinks import MemorySink

DAYS = 30
DAY = 86400.0
WINDOW = 20.0
"""Seconds of ordinary ticks lived at the start of each day …"""

LAST = 120.0
"""… and on the last, long enough for every creature to finish a long tuple and choose again."""

FLOOR = 1e-2
"""Least fraction of its group's most valuable tuple an authored tuple of a learning group keeps."""


def groups_of(creature) -> list[ActionGroup]:
    """Every action-group of a creature: an authored one's by name, a class's own."""
    named = getattr(creature, "groups", None)
    if isinstance(named, dict):
        return list(named.values())
    return [g for g in (getattr(creature, "group", None), *creature.reward_groups()) if isinstance(g, ActionGroup)]


def values(group: ActionGroup) -> dict[str, tuple[float, bool]]:
    """Each tuple's learned value (a chained value's scalar, not modulated by the drives its
    goals serve: a month of moods must not read as drift) and whether it is fixed."""
    return {tp.name: (tp.value.to_dict()["value"], getattr(tp.value, "plasticity", 1.0) == 0.0)
            for tp in group.tuples}


SHORTER = {"flock": (3.0, 30.0)}
"""Pieces that live shorter days (seconds each day, seconds on the last): fifteen singers
steering in a room cost ~0.4 s of CPU per simulated second here, so 20 s a day would add four
minutes to this test (before the crowd skipped clock gaps, each night cost 8.6 million
sub-steps and the month more than 20 minutes). Their values are as authored (``alpha = 0``);
what a month can break in them — drives, Du models, the crowd's and the ears' clocks across
each night — is crossed every night however short the day, and 30 s is long enough for every
singer to finish a tuple and choose again (a call lasts at most 4 s, a rest 1.5 ± 0.5 s)."""


@pytest.mark.parametrize("name", installations.names())
def test_thirty_days_on_every_creature_still_selects_and_its_values_hold(name):
    inst = load_installation(installations.path(name))
    inst.settings.output.wav = inst.settings.output.report = False
    clock, log = SimulatedClock(), EventLog()
    session = Session(inst, clock, log, MemorySink())
    tick = inst.settings.tick
    authored = {c.name: {id(g): (g, values(g)) for g in groups_of(c)} for c in session.creatures}
    rng = np.random.default_rng(15)
    sr = inst.settings.audio.sample_rate
    frames = int(round(tick * sr))
    sound = {"phrase": lambda: render_notes(phrase_notes(start=1.0, rng=rng), sr, LAST),  # what the offline
             "speech": lambda: spoken_poem(LAST, sr, rng)}.get(inst.settings.input.generate)  # run would hear
    heard = None if sound is None else sound()
    window, last = SHORTER.get(name, (WINDOW, LAST))
    for day in range(DAYS + 1):
        start = day * DAY
        log.records.clear()
        for note in phrase_notes(start=start + 1.0, rng=rng):  # a visitor plays, as the soak's does
            session.world.inject(note)
        for step in range(1, int((last if day == DAYS else window) / tick) + 1):
            t = round(start + step * tick, 6)
            clock.advance_to(t)
            if heard is None:
                session.step(t, 0, None, audio=False)
            else:  # the hearing pieces hear the room each day (their own voices through the air too)
                session.step(t, frames, heard[(step - 1) * frames:step * frames])
    chose = {e["creature"] for e in log.records if e["kind"] == "selection"}
    assert chose >= {c.name for c in session.creatures}, f"{name}: no selection on day {DAYS} by " \
        f"{sorted({c.name for c in session.creatures} - chose)}"
    for creature in session.creatures:
        for group, before in authored[creature.name].values():
            now = {n: v for n, (v, _) in values(group).items()}
            assert all(np.isfinite(v) for v in now.values()), (name, creature.name, group.name, now)
            if group.alpha == 0.0:
                assert now == {n: v for n, (v, _) in before.items()}, (name, creature.name, group.name)
                continue
            top = max(now.values())
            for tuple_name, (value, fixed) in before.items():
                if tuple_name not in now:
                    continue  # learning may fuse away a hypothesis; authored tuples are not removed
                if fixed:
                    assert now[tuple_name] == value, (name, creature.name, tuple_name)
                else:
                    assert now[tuple_name] >= FLOOR * top, (name, creature.name, group.name, now)
