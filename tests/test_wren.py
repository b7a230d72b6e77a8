"""The wren installation (installations/wren.toml): its call *meets* its peck (issue 20: an
interval constraint in a shipped piece; thesis "temporal logics", figure 12: "B starts when A
ends", made by gating Tr and Du).

The wren's call is a tuple whose Tr is "it is pecking"; the group's constraint gates that on
the peck's end, so the call starts in the tick the peck's Du is done, as the beak strikes the
note. The peck's group logs the stop at its next tick (the strike lands after the group has
read the Du), so in the events log every call starts one tick before a peck's logged stop,
and its first note sounds in the tick of the pecked note: a listener hears every pecked note
with the call on its attack.

Measured on the shipped run (seed 5, 60 s, the generated phrases for input): 16 pecks, 16
calls; every call met a peck's end and every peck's end was met (9 of them pecks longer than
a tick, where the reach's start and the strike differ); all 16 calls' first notes sounded
with a pecked note. The control, the same run with the group's constraints removed: the
call comes as the wren starts to reach, so 11 of 26 calls (the pecks of a single tick, a
note at the beak) met a peck's end and 1 of the 8 pecks longer than a tick was met. Over
seeds 1-8 with the constraint every peck and every call met (14-18 pecks); without it 4-11
of 17-26 calls did and 0-1 of 6-13 longer pecks.
"""

from __future__ import annotations

from pathlib import Path

import installations
from creatures.events import read_events
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation

Activation = tuple[float, float]


def activations(events: list[dict], name: str) -> list[Activation]:
    """The tuple's activations ``(start, logged stop)``, from its selection and stop events."""
    out, start = [], None
    for e in events:
        if e.get("tuple") != name:
            continue
        if e["kind"] == "selection" and not e.get("kept"):
            start = e["t"]
        elif e["kind"] == "stop" and start is not None:
            out.append((start, e["t"]))
            start = None
    return out


def meets(peck: Activation, call: Activation, tick: float) -> bool:
    """The call starts where the peck ends: in the tick its Du is done, at most one tick
    before the peck's logged stop (or at the stop itself, for a peck that was stopped)."""
    return -1e-6 <= peck[1] - call[0] <= tick + 1e-6


def run(tmp_path: Path, name: str, *, constrained: bool) -> tuple[list[dict], float, list[int]]:
    """(the events, the tick, the call's pitches) of the shipped wren, or of it without its
    groups' constraints."""
    inst = load_installation(installations.path("wren"))
    inst.settings.output.report = False
    inst.settings.output.wav = False
    (wren,) = inst.specs
    assert [c.relation for c in wren.groups["song"].constraints] == ["meets"]
    if not constrained:
        for group in wren.groups.values():
            group.constraints = []
    run_offline(inst, tmp_path / name)
    return (read_events(tmp_path / name / "events.jsonl"), inst.settings.tick,
            wren.tuples["call"].action.params()["pitches"])


def test_the_wrens_call_meets_every_peck_and_without_the_constraint_does_not(tmp_path):
    events, tick, pitches = run(tmp_path, "shipped", constrained=True)
    pecks, calls = activations(events, "peck"), activations(events, "call")
    assert len(calls) >= 10 and len(pecks) >= 10  # the relation is exercised
    assert all(any(meets(p, c, tick) for p in pecks) for c in calls)  # every call meets a peck …
    assert all(any(meets(p, c, tick) for c in calls) for p in pecks)  # … and every peck is met
    longer = [p for p in pecks if p[1] - p[0] > tick + 1e-6]
    assert len(longer) >= 5  # pecks whose reach began before the strike: a call at the start would not meet them
    # What is heard: each call's first note sounds in the tick of a note the beak struck.
    notes = [e for e in events if e["kind"] == "note"]
    struck = [n["time"] for n in notes if n["pitch"] not in pitches]
    firsts = [n["time"] for n in notes if n["pitch"] == pitches[0]]
    assert len(firsts) == len(calls)
    assert all(any(abs(f - s) < 1e-6 for s in struck) for f in firsts)

    # The control: the same wren without the constraint calls as it starts to reach.
    events, tick, _ = run(tmp_path, "unconstrained", constrained=False)
    pecks, calls = activations(events, "peck"), activations(events, "call")
    assert len(calls) >= 10 and len(pecks) >= 10
    meeting = sum(any(meets(p, c, tick) for p in pecks) for c in calls) / len(calls)
    assert meeting <= 0.5, meeting
    longer = [p for p in pecks if p[1] - p[0] > tick + 1e-6]
    assert longer
    met = sum(any(meets(p, c, tick) for c in calls) for p in longer) / len(longer)
    assert met <= 0.25, met


def test_the_call_ticks_after_the_peck():
    """A same-tick gate reads the peck's end only if the call's group ticks after the peck's
    (docs/authoring.md, "Interval constraints"): the call's group is a later top-level group."""
    inst = load_installation(installations.path("wren"))
    (wren,) = inst.specs
    (constraint,) = [c for g in wren.groups.values() for c in g.constraints]
    assert (constraint.relation, constraint.a, constraint.b) == ("meets", "peck", "call")
    order = list(wren.groups)
    home = {t: n for n, g in wren.groups.items() for t in g.tuples}
    assert order.index(home["call"]) > order.index(home["peck"])
