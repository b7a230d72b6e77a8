"""exchange: notes fed to one creature reach the others in the shipped colony, whose creatures
are authored (installations/creatures/exchange.toml); what a creature plays is tested for
recognisable transformations (retrograde, swapped sub-segments) of what it heard against a
shuffle of the same notes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import installations
from creatures.clock import SimulatedClock
from creatures.config import ConfigError
from creatures.events import EventLog, read_events
from creatures.kinds import KINDS
from creatures.kinds.note_world import NoteWorld, Vary
from creatures.kinds.parts import shared_graph
from creatures.motor.graph import MotorGraph
from creatures.motor.metric import ratio_curve, source_lengths, successors
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from creatures.runtime.world import World
from midi.files import write_notes
from midi.notes import NoteEvent
from midi.scheduler import NoteScheduler
from midi.sinks import MemorySink

PHRASE = [60, 62, 64, 67, 69, 72, 74, 76]


SHUFFLES = 200
"""Seeded reorderings of a creature's output that its transformation score must beat."""


def fragments(heard: list[int], played: list[int]) -> list[tuple[int, int, int]]:
    """Runs of three or more consecutive ``played`` notes that are a sub-segment of ``heard``
    (each pair followed each other in what was heard: direction +1) or its retrograde (each
    pair in reverse: −1), as ``(direction, first index in played, length)``."""
    follows = set(zip(heard, heard[1:]))
    found = []
    for direction in (1, -1):
        run = 1
        for i in range(1, len(played) + 1):
            pair = (played[i - 1], played[i]) if i < len(played) else None
            if pair is not None and (pair if direction == 1 else pair[::-1]) in follows:
                run += 1
                continue
            if run >= 3:
                found.append((direction, i - run, run))
            run = 1
    return sorted(found, key=lambda f: f[1])


def _heard_at(heard: list[int], segment: list[int]) -> int:
    """Where ``segment`` first occurs contiguously in ``heard`` (fragments always do)."""
    return next(i for i in range(len(heard)) if heard[i : i + len(segment)] == segment)


def swapped(heard: list[int], played: list[int]) -> int:
    """Pairs of forward fragments played in the opposite order to the one they were heard in
    (swapped sub-segments: ...B...A played where A...B was heard, A and B not overlapping)."""
    forward = [(i, n) for d, i, n in fragments(heard, played) if d == 1]
    at = [(_heard_at(heard, played[i : i + n]), n) for i, n in forward]
    return sum(b + nb <= a for k, (a, _) in enumerate(at) for b, nb in at[k + 1 :])


def score(heard: list[int], played: list[int]) -> int:
    """Notes of ``played`` inside a fragment (sub-segment or retrograde) of ``heard``."""
    return sum(n for _, _, n in fragments(heard, played))


def recognisable(heard: list[int], played: list[int], seed: int = 0) -> bool:
    """``played`` is a recognisable transformation of ``heard``: it holds a retrograde or a
    swapped pair of sub-segments, and more of its notes lie in fragments of ``heard`` than
    in 99 % of seeded reorderings of the very same notes (so a shuffle, which has the same
    notes, cannot pass, and silence has none)."""
    if not any(d == -1 for d, _, _ in fragments(heard, played)) and not swapped(heard, played):
        return False
    rng = np.random.default_rng(seed)
    chance = [score(heard, list(rng.permutation(played))) for _ in range(SHUFFLES)]
    return score(heard, played) > np.percentile(chance, 99)


def test_transformation_detector():
    """Retrogrades and swapped sub-segments are found; the phrase unchanged, shuffles of a
    varied passage (all but a chance few) and silence are not recognisable transformations."""
    assert fragments(PHRASE, PHRASE[::-1]) == [(-1, 0, 8)]
    assert swapped(PHRASE, PHRASE[4:7] + PHRASE[0:3]) == 1 and swapped(PHRASE, PHRASE) == 0
    varied = PHRASE[4:8] + PHRASE[0:4] + PHRASE[::-1] + PHRASE[2:6][::-1] + PHRASE[5:] + PHRASE[:3]
    assert recognisable(PHRASE, varied)
    shuffles = np.random.default_rng(3)  # a shuffle passes by chance on about 1 % of draws
    assert sum(recognisable(PHRASE, list(shuffles.permutation(varied))) for _ in range(100)) <= 3
    assert not recognisable(PHRASE, [])
    assert not recognisable(PHRASE, PHRASE)  # the passage passed on unchanged is no variation


def hearing_ada(heard: list[tuple[float, str, int]], **space) -> tuple[SimulatedClock, NoteWorld]:
    """The shipped colony's first creature alone, its copies never transposed, having heard
    ``(time, player, pitch)``; its notes in space (``space``: other ``[creature.space]`` keys)."""
    spec = load_installation(installations.path("exchange")).specs[0]
    spec.space = spec.space.model_copy(update={"mutation": 0.0, **space})
    clock = SimulatedClock()
    world = World(clock, EventLog(None), NoteScheduler(MemorySink(), clock))
    ada = KINDS["authored"](spec, world, np.random.default_rng(7))
    world.add(ada)
    for t, player, pitch in heard:
        clock.advance_to(t)
        ada.hear(NoteEvent(t, pitch, 96, 0, 0.25), player)
    return clock, ada.notes


def test_passages_are_each_players_notes_until_a_silence():
    """Two players heard at once are two passages, and a player's silence longer than
    ``space.passage_gap`` ends its passage; notes that left the space leave their passage."""
    phrase = [(1.0 + 0.3 * i, "input", p) for i, p in enumerate(PHRASE)]
    answer = [(1.15 + 0.6 * i, "bo", p) for i, p in enumerate([48, 50, 52])]  # between the phrase's notes
    later = [(8.0 + 0.3 * i, "input", p) for i, p in enumerate([79, 81, 83])]  # after 5 s of silence
    _, notes = hearing_ada(sorted(phrase + answer + later))
    assert [[o.pitch for o in p] for p in notes.passages()] == [[48, 50, 52], PHRASE, [79, 81, 83]]
    notes.fade(8.0 + notes.spec.note_lifetime - 3.0)  # the first two passages fade, the last stays
    assert [[o.pitch for o in p] for p in notes.passages()] == [[79, 81, 83]]


def test_a_renewed_note_is_fresh_when_the_full_space_forgets_its_oldest():
    """Hearing a pitch already in space renews its note, and "the oldest fade first" counts
    from the renewal, as ``note_lifetime`` does. With ``max_notes = 3``, 60, 62 and 64 heard, 60
    heard again and then 65, the space forgot the renewed 60 (its first placing was the
    oldest) and kept 62, heard 2 s before: 60 was lost from the latest passage it had just
    been heard in."""
    _, notes = hearing_ada([(1.0, "input", 60), (2.0, "input", 62), (3.0, "input", 64),
                            (4.0, "input", 60), (5.0, "input", 65)], max_notes=3)
    assert sorted(o.pitch for o in notes.space.objects) == [60, 64, 65]
    assert [[o.pitch for o in p] for p in notes.passages()] == [[64, 60, 65]]
    assert notes.remembered() <= 2 * len(notes.space)


@pytest.mark.parametrize("transform", ["retrograde", "swap"])
def test_vary_strikes_the_heard_passage_backwards_or_swapped(transform):
    """``vary`` walks the hand to each note object of the passage in turn and strikes it, no
    note it passes on the way: the phrase backwards, or its two halves about a cut that leaves
    each at least ``segment`` notes swapped."""
    clock, notes = hearing_ada([(1.0 + 0.3 * i, "input", p) for i, p in enumerate(PHRASE)])
    struck = []
    real = notes.strike
    notes.strike = lambda t, obj, strength: (struck.append((t, obj.pitch)), real(t, obj, strength))
    action = Vary(notes, transform, transform=transform, segment=3)
    action.start(clock.now(), None)
    while not action.done(clock.now()) and clock.now() < 60.0:
        clock.advance(0.04)
        action.update(clock.now())
    times, played = zip(*struck)
    expected = [PHRASE[::-1]] if transform == "retrograde" else [PHRASE[c:] + PHRASE[:c] for c in range(3, 6)]
    assert list(played) in expected, played
    assert min(np.diff(times)) >= notes.spec.strike_interval


def run_exchange(tmp_path: Path, duration: float = 45.0) -> list[dict]:
    """The shipped exchange, its first creature fed the phrase three times."""
    inst = load_installation(installations.path("exchange"))
    inst.settings.output.wav = inst.settings.output.report = False
    phrase = tmp_path / "phrase.mid"
    write_notes(phrase, [NoteEvent(1.0 + 0.3 * i + 6.0 * r, p, 96, 0, 0.25)
                         for r in range(3) for i, p in enumerate(PHRASE)])
    run_offline(inst, tmp_path / "out", midi=phrase, duration=duration)
    return read_events(tmp_path / "out" / "events.jsonl")


def played_by(events: list[dict], creature: str) -> list[int]:
    return [e["pitch"] for e in events if e["kind"] == "note" and e["creature"] == creature]


def test_notes_fed_to_one_creature_reach_another(tmp_path: Path):
    events = run_exchange(tmp_path)
    placed = {}
    for e in events:
        if e["kind"] == "placed":
            placed.setdefault(e["creature"], []).append(e["source"])
    # Only the first creature hears the input; the others hear only the colony.
    assert set(placed["ada"]) >= {"input"}
    assert "input" not in set(placed.get("bo", [])) | set(placed.get("cy", []))
    others = played_by(events, "bo") + played_by(events, "cy")
    shared = set(others) & set(PHRASE)
    assert len(shared) >= 3, f"too little of the phrase reached the others: {sorted(set(others))}"


@pytest.mark.parametrize("output", ["shuffle", "silence"])
def test_a_shuffling_or_silent_creature_plays_no_variation(tmp_path: Path, monkeypatch, output):
    """The detector bites in a real run: an exchange creature whose every strike plays a
    random note of those in its space (a random shuffle of what it heard), or plays nothing,
    is not heard to transform the phrase."""
    if output == "silence":
        monkeypatch.setattr(NoteWorld, "strike", lambda self, t, obj, strength: None)
    else:
        real = NoteWorld.strike

        def shuffling(self, t, obj, strength):
            real(self, t, self.space.objects[int(self.rng.integers(len(self.space)))], strength)
        monkeypatch.setattr(NoteWorld, "strike", shuffling)
    played = played_by(run_exchange(tmp_path), "ada")
    assert (len(played) >= 10) == (output == "shuffle")
    assert not recognisable(PHRASE, played)


def test_the_first_creature_plays_recognisable_variations_of_the_phrase(tmp_path: Path):
    """The thesis's claim ("exchange (installation)": "retrograde variations, repeated
    subsegments are swapped back and forth"): what the creature hearing the phrase plays
    is a retrograde or a swap of its sub-segments beyond what a shuffle of its notes gives.

    The creature's ``vary`` tuples (retrograde, swap), chosen beside its wander, make it so.
    Measured over 90 s, seeds 7–11: 110–146 notes, 22–45 consecutive pairs adjacent in the
    phrase (either way round) against 9–17 for shuffles of the same notes, 1–6 retrograde
    fragments (shuffles 0.3–0.6) and 0–4 swapped pairs (shuffles ≤ 0.02), a fragment score of
    21–47 against a shuffle 99th percentile of 9–12. With the wander and hunger alone (issue
    20): 37–41 notes, 1–6 adjacent pairs against 2.6–3.9, no retrograde, a score of 0–3."""
    assert recognisable(PHRASE, played_by(run_exchange(tmp_path, 90.0), "ada"))


def test_ratio_metric_gives_a_body_on_the_exchange_graph():
    plain, ratios = shared_graph(False), shared_graph(True)
    assert not plain.weights.ratios and ratios.weights.ratios
    assert plain.edges() != ratios.edges()  # the perturbed time metric reshapes the topology
    inst = load_installation(installations.path("exchange"))
    cy = next(spec for spec in inst.specs if spec.name == "cy")
    assert cy.ratio_metric


VARIATIONS = ("retrograde", "swap")
"""The exchange creature's tuples that play a heard passage varied (``vary``)."""


def run_colony(out: Path, *, ratio_metric: bool | None = None, graded: bool | None = None,
               manner: bool = True, vary: bool = True, seed: int | None = None) -> list[dict]:
    """The shipped exchange, unfed, for 60 s, with every creature's body on the ratio metric or
    not, and its wander and rest Du graded or not (where given); without its manner layer
    (looking, the bored adverb) when not ``manner``, nor its variations when not ``vary``; on
    another seed than the config's where given."""
    inst = load_installation(installations.path("exchange"))
    inst.settings.output.wav = inst.settings.output.report = False
    if seed is not None:
        inst.settings.seed = seed
    for spec in inst.specs:
        if not manner:
            del spec.groups["manner"], spec.tuples["look"], spec.tuples["bored manner"]
        if not vary:
            spec.groups["main"].tuples = [name for name in spec.groups["main"].tuples if name not in VARIATIONS]
            for name in VARIATIONS:
                del spec.tuples[name]
        if ratio_metric is not None:
            spec.ratio_metric = ratio_metric
        if graded is not None:
            for name in ("wander", "rest"):
                spec.tuples[name].until.graded = graded
    run_offline(inst, out, duration=60.0)
    return read_events(out / "events.jsonl")


def steps_taken(events: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    """The steps ``a → b`` the colony's bodies took: each body's consecutive reached nodes
    (every ``motor`` event's ``reached``, which graph edges always join)."""
    a, b = [], []
    for name in ("ada", "bo", "cy"):
        nodes = [n for e in events if e["kind"] == "motor" and e["creature"] == name for n in e["reached"]]
        a += nodes[:-1]
        b += nodes[1:]
    return np.array(a, dtype=np.int64), np.array(b, dtype=np.int64)


def ratio_favour(a: np.ndarray, b: np.ndarray) -> tuple[int, float]:
    """Of the steps ``a → b`` that are time jumps within one source animation (to a node that
    is not the next frame), how many, and the mean share of its jump penalty the *exchange*
    metric's ratio curve forgives each (:func:`~creatures.motor.metric.ratio_curve`: all of it
    at a low-integer ratio of the animation's length, none from ``ratio_tolerance`` away).
    Graded, so a jump counts as much as the metric favours it: a count of jumps within the
    tolerance hinged on rounding at its edge, where the metric forgives nothing."""
    poses, weights = shared_graph(False).poses, shared_graph(True).weights
    lengths, after = source_lengths(poses), successors(poses)
    inside = (after[a] != b) & (poses.source_ids[a] == poses.source_ids[b])
    a, b = a[inside], b[inside]
    curve = ratio_curve(poses.times[b] - poses.times[a], lengths[poses.source_ids[a]], weights.ratios,
                        weights.ratio_tolerance)
    return int(inside.sum()), float(np.mean(1.0 - curve)) if inside.any() else 0.0


def random_walk(graph: MotorGraph, steps: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``steps`` steps along out-edges of ``graph`` drawn uniformly: a path no metric chose."""
    adjacency, node, path = graph.adjacency, int(rng.integers(len(graph))), []
    for _ in range(steps):
        path.append(node)
        node = int(adjacency.indices[rng.integers(adjacency.indptr[node], adjacency.indptr[node + 1])])
    path.append(node)
    return np.array(path[:-1]), np.array(path[1:])


def test_ratio_metric_favours_low_integer_ratio_jumps_on_the_paths_taken(tmp_path: Path):
    """The thesis's twist ("exchange (installation)": the animator can "carve the temporal
    equivalent of note triads out of animation material"): the shipped colony, whole (wander,
    hunger, rest, its variations and its manner layer), same seed, with every body on the
    ratio metric (the piece puts cy alone on it) takes within-animation time jumps nearer
    low-integer ratios of the animation's length than on the plain metric, on all the paths
    its bodies take.

    Measured as the share of the jump penalty the ratio curve forgives (``ratio_favour``),
    60 s each, ratio metric against plain: seed 7 12.5 against 5.0 %, 8 10.1/5.8, 9 14.6/8.4,
    10 14.8/7.1, 11 13.4/6.7 (pooled 13.0 against 6.6 % of some 3200 and 3450 jumps); seeds
    12-16 lean the same way, by 0.8 to 8.3 points (pooled 12.6 against 9.0). By the tuple
    running when each node was reached (seeds 7-16 pooled): the wander 17.3 against 11.1 % (of
    some 1600 jumps each), hunger's seeks 24.1/9.5, the variations' short reaches from one
    passage note to the next 8.4/5.0 (retrograde) and 6.9/4.2 (swap), rests 26.6/25.7 (they head
    for the nearest low-energy pose, the same few goals on either metric). Walks of uniformly
    drawn edges (100,000 steps, seeds 0-4) score 8.8-9.6 % on the ratio graph (8.5 on the
    test's seed 7) and 7.1-7.8 on the plain one: the ratio graph's edges carry a little of the
    lean, the bodies' choices of path the rest, and the plain metric's bodies walk as a random
    walk would.

    Counted instead as jumps within ``ratio_tolerance`` of a ratio, the same runs (seeds 7-11)
    pooled 27.6 against 23.8 % with seeds 8 and 11 a little behind, and the variations looked
    unmoved: 475 of the ratio arm's jumps and 664 of the plain arm's lie at the tolerance's very
    edge (the reach animation's near-repeats 4.6 s and 2.4 s into its 12 s: |0.383 − 1/3| =
    |0.2 − 1/4| = 0.05), where the metric forgives nothing and rounding counted 298 and 455 of
    them in. Counted within half the tolerance (no edge for rounding to decide) the lean shows
    again: 14.1 against 8.1 % pooled over seeds 7-16, every seed ahead but 13 (10.7/12.0).

    One seed is not enough (a run's path is chaotic in the metric's last bits), so the test
    pools five and asks every one to lean the same way; the pooled margin asked (3 points)
    exceeds the 2.5 points between the plain metric's pools over seeds 7-11 and 12-16. Both
    arms on the plain metric fail it, and so does a uniform random walk on the ratio graph."""
    counts = {True: [0, 0.0], False: [0, 0.0]}
    for seed in range(7, 12):
        favour = {}
        for ratios in (True, False):
            jumps, favour[ratios] = ratio_favour(*steps_taken(run_colony(tmp_path / f"{seed}-{ratios}",
                                                                         ratio_metric=ratios, seed=seed)))
            assert jumps >= 300, "the bodies should have jumped often enough to count"
            counts[ratios][0] += jumps
            counts[ratios][1] += favour[ratios] * jumps
        assert favour[True] > favour[False], (seed, favour)
    pooled = {ratios: forgiven / jumps for ratios, (jumps, forgiven) in counts.items()}
    assert pooled[True] >= pooled[False] + 0.03, pooled
    _, walked = ratio_favour(*random_walk(shared_graph(True), 100_000, np.random.default_rng(7)))
    assert pooled[True] >= walked + 0.025, (pooled, walked)  # a path no metric chose does not pass


def test_a_graded_du_lets_hunger_interrupt_wandering_and_resting_more(tmp_path: Path):
    """``until.graded``: a wander's or rest's expected value declines as its planned time runs
    out, so hunger for notes interrupts it more often (measured over 60 s, seed 7: 71
    interruptions against 22; seed 8: 67 against 26). The variations are left out: every note
    they strike feeds the hunger that would interrupt, and they fill most of the time a wander
    or rest would (with them, seed 7: 36 against 18, but seed 8: 14 against 18)."""
    counts = {}
    for graded in (False, True):
        events = run_colony(tmp_path / str(graded), graded=graded, manner=False, vary=False)  # the main group's own Du
        counts[graded] = sum(e["kind"] == "interruption" and e["tuple"] in ("wander", "rest") for e in events)
    assert counts[True] >= 2 * counts[False] > 0, counts


@pytest.mark.parametrize("space, key", [("max_notes = 5", r"exchange\.toml:\d+.*percepts\.passage\.notes"),
                                        ("max_notes = 8\n[creature.tuples.swap]\naction = { type = \"vary\", "
                                         "transform = \"swap\", segment = 5 }", r"small\.toml:\d+.*tuples\.swap\.action\.segment")])
def test_a_passage_longer_than_the_space_remembers_is_a_config_error(tmp_path, space, key):
    """The space remembers at most ``max_notes`` heard notes (NoteWorld.heard), so a passage
    percept or a vary asking for more is never satisfied. Accepted, exchange with max_notes = 5
    (its passage percept and swap need 6) selected retrograde and swap 0 times in 120 s of the
    generated phrases (9 and 8 at the default 48)."""
    config = tmp_path / "small.toml"
    config.write_text(f'title = "small"\n[[creature]]\nname = "ex"\nkind = "exchange"\n[creature.space]\n{space}\n')
    with pytest.raises(ConfigError, match=rf"{key}.*remembers at most \d+ \(space\.max_notes\)"):
        load_installation(config)
