"""Creatures in a room: the vehicle, the steering behaviours, their combination, the spatial
index, and the crowd's fixed sub-steps (issue 21, "Must show")."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from creatures.room.combine import prioritised_budget, prioritised_dithering, weighted_truncated_sum
from creatures.room.director import FlowField, Path
from creatures.room.index import Neighbours
from creatures.room.hearing import DistanceLaw
from creatures.room.lod import Audibility, LevelOfDetail, Sounding
from creatures.room.motion import Crowd
from creatures.room.recipe import Behaviour, Recipe, Surroundings
from creatures.room.space import Obstacle, Room
from creatures.room.steering import project
from creatures.room.vehicle import Vehicles, norms, unit


def polarisation(v: Vehicles) -> float:
    """|mean unit velocity|: 1 when all move the same way, ≈ 0 for random headings."""
    return float(norms(unit(v.vel).mean(0)))


def one(behaviour: str, start, *, room=Room(10, 10), around=None, heading=None, **params) -> Crowd:
    v = Vehicles.at([start], heading=None if heading is None else [heading])
    return Crowd(room, v, [Recipe((Behaviour(behaviour, params=params),))], around=around)


def test_separation_parts_bodies_that_stand_at_one_point():
    """Six clones of one ``at`` (and a pair the walls pushed into one corner) have no direction
    away from each other: separation pushed each along a zero offset, and they stood as one for
    ever. Now each pair parts along its own direction, compiled or in numpy, alike."""
    ends = []
    for compiled in (True, False):
        v = Vehicles.at([(5.0, 5.0)] * 6 + [(0.25, 0.25)] * 2, radius=0.25)
        c = Crowd(Room(10, 10), v, [Recipe((Behaviour("separation"),))], seed=1)
        if not compiled:
            c.compiled = None
        c.advance_to(3.0)
        assert pdist(v.pos[:6]).min() >= 0.5 and pdist(v.pos[6:]).min() >= 0.5  # two radii
        ends.append(v.pos)
    np.testing.assert_allclose(ends[0], ends[1], atol=1e-9)


def test_arrival_comes_to_rest_on_its_target():
    target = np.array([6.0, 4.0])
    c = one("arrival", (1.0, 1.0), target=(6.0, 4.0), slowing=1.0)
    approach = unit(target - c.v.pos[0])
    overshoot = 0.0
    for _ in range(2000):  # 20 s
        c.step()
        overshoot = max(overshoot, float((c.v.pos[0] - target) @ approach))
    assert norms(c.v.pos[0] - target) < 0.05
    assert c.v.speed()[0] < 0.01
    assert overshoot <= 0.05
    assert c.t == pytest.approx(20.0)


@pytest.mark.parametrize("separate", [True, False])
def test_wander_and_separation_keep_thirty_bodies_apart(separate):
    """The issue's recipe and nothing else: wander + separation (the walls' contact rule keeps
    them in). Without separation the same wanderers touch on every tick after 20 s."""
    rng = np.random.default_rng(1)
    v = Vehicles.at(rng.uniform(1, 9, (30, 2)), radius=0.25)
    recipe = Recipe(((Behaviour("separation", 3.0),) if separate else ()) + (Behaviour("wander", 1.0),))
    room = Room(10, 10)
    c = Crowd(room, v, [recipe], seed=1)
    clear, ticks, travelled = 0, 0, np.zeros(30)
    while c.t < 60.0:
        before = v.pos.copy()
        c.advance_to(c.t + 0.04)
        travelled += norms(v.pos - before)
        assert room.inside(v.pos - v.radius[:, None]).all() and room.inside(v.pos + v.radius[:, None]).all()
        if c.t > 20.0:
            ticks += 1
            clear += pdist(v.pos).min() >= 0.5  # two radii
    if separate:
        assert clear / ticks >= 0.99
    else:
        assert clear / ticks < 0.5
    assert travelled.min() > 10.0  # every one of them wandered (a still crowd is trivially apart)


def test_fifty_flockers_align():
    rng = np.random.default_rng(4)
    v = Vehicles.at(rng.uniform(6, 14, (50, 2)), rng.normal(size=(50, 2)), radius=0.2)
    names = ("wall_avoidance", "separation", "alignment", "cohesion", "wander")
    recipe = Recipe(tuple(Behaviour(n, w) for n, w in zip(names, (3.0, 1.0, 2.0, 1.0, 0.1))), reach=6.0, neighbours=12)
    c = Crowd(Room(20, 20), v, [recipe], seed=4)
    c.advance_to(0.5)
    start, reached = polarisation(v), None
    while c.t < 60.0 and reached is None:
        c.advance_to(c.t + 0.5)
        if polarisation(v) >= 0.9:
            reached = c.t
    assert start < 0.6
    assert reached is not None and reached <= 60.0


def test_nothing_leaves_the_room_or_enters_an_obstacle():
    room = Room(6, 4, (Obstacle(3.0, 2.0, 0.6), Obstacle(1.5, 1.0, 0.3)))
    rng = np.random.default_rng(3)
    v = Vehicles.at(rng.uniform(0, [6, 4], (40, 2)), rng.normal(size=(40, 2)), radius=0.2, max_speed=3.0,
                    max_force=20.0)
    # Seek a point outside the room: only the walls stop them.
    recipe = Recipe((Behaviour("wander", 1.0, params={"rate": 8.0}), Behaviour("seek", 2.0, params={"target": (30.0, -9.0)})))
    c = Crowd(room, v, [recipe], seed=3)
    for _ in range(1500):
        c.step()
        assert room.inside(v.pos).all()
        gap = norms(v.pos[:, None, :] - room.centres[None]) - room.radii[None] - v.radius[:, None]
        assert gap.min() >= -1e-9
    assert (v.pos[:, 0] > 5.7).sum() > 20  # they did press against the far wall


@pytest.mark.parametrize("lod", [None, LevelOfDetail(near=2.0, levels=3, budget=12)], ids=["full", "lod"])
def test_trajectories_do_not_depend_on_the_tick(lod):
    """Ticks of 0.02 s and 0.04 s run the same sub-steps: positions agree within 1e-9 m, with
    level of detail and a budget too (the levels planned on the sub-step grid; planned before
    each tick, one of these 20 wanderers ended 5.6 m from itself at the other tick after 10 s)."""
    def run(tick: float) -> np.ndarray:
        rng = np.random.default_rng(9)
        v = Vehicles.at(rng.uniform(1, 9, (20, 2)), radius=0.25)
        recipe = Recipe((Behaviour("wall_avoidance", 2.0), Behaviour("separation", 2.0), Behaviour("wander", 1.0),
                         Behaviour("cohesion", 0.3)))
        c = Crowd(Room(10, 10), v, [recipe], seed=9, lod=lod)
        c.listeners = np.array([[5.0, 5.0]])
        trace, t = [], 0.0
        for _ in range(int(round(10.0 / tick))):
            t += tick
            c.advance_to(t)
            if abs(t / 0.04 - round(t / 0.04)) < 1e-6:
                trace.append(v.pos.copy())
        return np.array(trace)

    fine, coarse = run(0.02), run(0.04)
    assert fine.shape == coarse.shape
    assert np.abs(fine - coarse).max() < 1e-9
    assert np.abs(fine[-1] - fine[0]).max() > 1.0  # they moved


def test_seek_flee_pursuit_and_evasion_go_the_right_way():
    c = one("seek", (2, 5), target=(8.0, 5.0))
    c.advance_to(3.0)
    assert c.v.vel[0, 0] > 0.9 and abs(c.v.vel[0, 1]) < 1e-6
    c = one("flee", (5, 5), target=(8.0, 5.0))
    c.advance_to(3.0)
    assert c.v.vel[0, 0] < -0.9
    # A quarry crossing upward: pursuit aims ahead of it, seek at it.
    around = Surroundings(visitors=np.array([[8.0, 3.0]]), visitor_vel=np.array([[0.0, 1.0]]))
    p = one("pursuit", (5, 3), around=around, target="visitor")
    s = one("seek", (5, 3), around=around, target="visitor")
    p.step(), s.step()
    assert p.v.vel[0, 1] > s.v.vel[0, 1] + 1e-3
    e = one("evasion", (5, 3), around=around, target="visitor")
    e.step()
    assert e.v.vel[0, 0] < 0 and e.v.vel[0, 1] < 0  # away from where it is going
    nobody = one("seek", (5, 3), target="visitor")
    nobody.advance_to(1.0)
    assert nobody.v.speed()[0] == 0.0  # no visitor, no pull


def test_obstacle_avoidance_goes_around_a_pillar():
    room = Room(12, 6, (Obstacle(6.0, 3.0, 0.8),))
    v = Vehicles.at([[1.0, 3.05]])
    recipe = Recipe((Behaviour("obstacle_avoidance", 2.0), Behaviour("seek", 1.0, params={"target": (11.0, 3.0)})),
                    combine="budget")
    c = Crowd(room, v, [recipe])
    closest = np.inf
    for _ in range(1500):
        c.step()
        closest = min(closest, float(norms(v.pos[0] - [6.0, 3.0])) - 0.8 - 0.25)
    assert closest > 0.0  # never touched it (the walls' contact rule never had to act)
    assert v.pos[0, 0] > 10.0  # and got past


@pytest.mark.parametrize("avoid", [False, True])
def test_agent_avoidance_lets_two_walkers_pass_head_on(avoid):
    """Two walkers seek each other's start along one line (1 cm apart sideways): without agent
    avoidance they pass through each other (their centres 1.2 cm apart at the closest); with
    it they pass two radii and its 0.1 m margin apart, and both still get where they go."""
    v = Vehicles.at([(1.0, 5.0), (9.0, 5.01)], heading=[(1.0, 0.0), (-1.0, 0.0)], radius=0.25)
    dodge = (Behaviour("agent_avoidance", 2.0),) if avoid else ()
    recipes = [Recipe((Behaviour("seek", params={"target": target}), *dodge)) for target in ((9.5, 5.0), (0.5, 5.01))]
    c = Crowd(Room(10, 10), v, recipes, np.array([0, 1]))
    closest = np.inf
    for _ in range(1200):  # 12 s
        c.step()
        closest = min(closest, float(norms(v.pos[0] - v.pos[1])))
    if avoid:
        assert closest >= 0.59
    else:
        assert closest < 0.05
    assert v.pos[0, 0] > 9.0 and v.pos[1, 0] < 1.0


@pytest.mark.parametrize("avoid", [False, True])
def test_wall_avoidance_turns_a_walker_before_the_wall(avoid):
    """A walker heading for the east wall at 0.95 m/s (and 0.3 m/s north), nothing else
    steering it: without wall avoidance it walks into the wall and stays pressed against it
    (the walls' contact rule stops it); with it, it turns along the wall while its body is
    still more than 0.4 m off, and walks on north."""
    v = Vehicles.at([(5.0, 5.0)], radius=0.25)
    v.vel[0] = (0.95, 0.3)
    c = Crowd(Room(10, 10), v, [Recipe((Behaviour("wall_avoidance"),) if avoid else ())])
    reach = 0.0  # the furthest east the body's edge got
    for _ in range(600):  # 6 s
        c.step()
        reach = max(reach, float(v.pos[0, 0] + v.radius[0]))
    if avoid:
        assert reach < 9.6
        assert v.vel[0, 0] <= 0.0 and v.vel[0, 1] > 0.25  # along the wall, northward
        assert abs(v.heading[0, 0]) < 0.1
    else:
        assert reach == pytest.approx(10.0)
        assert v.vel[0, 0] == 0.0


BENDS = {"right angle": [[1.0, 1.0], [9.0, 1.0], [9.0, 9.0]], "hairpin": [[1.0, 1.0], [9.0, 1.0], [2.0, 8.0]],
         "zigzag": [[1, 5], [3, 7], [5, 3], [7, 7], [9, 5]], "loop": [[1, 1], [5, 2], [9, 1], [9, 9], [1, 9], [1, 3]]}


@pytest.mark.parametrize("speed", [1.0, 3.0])
@pytest.mark.parametrize("radius", [0.3, 1.0])
@pytest.mark.parametrize("bends", sorted(BENDS))
def test_path_following_stays_within_the_path(bends, radius, speed):
    """A body put 0.6 m off the path joins it and from then on never strays beyond the path's
    radius, round a right angle, a hairpin, a zigzag and a loop, at walking pace and at 3 m/s,
    and comes to rest on its end (Reynolds' path following, which keeps only the predicted
    position on the path, let the body out by up to 1.2 m from a 0.5 m path)."""
    path = Path(np.array(BENDS[bends], float), radius=radius)
    v = Vehicles.at([path.points[0] + [0.0, 0.6]], max_speed=speed)
    c = Crowd(Room(10, 10), v, [Recipe((Behaviour("path_following", params={"path": "p"}),))],
              around=Surroundings(paths={"p": path}))
    joined, worst = None, 0.0
    while c.t < 45.0:
        c.step()
        at, _, _ = project(path.points, v.pos)
        off = float(norms(v.pos - at)[0])
        if joined is None and off <= radius:
            joined = c.t
        if joined is not None:
            worst = max(worst, off)
    assert joined is not None and joined < 1.0
    assert worst <= radius + 1e-9
    assert norms(v.pos[0] - path.points[-1]) < 0.01 and norms(v.vel[0]) < 0.01


def test_flow_following_takes_the_field_direction():
    field = FlowField.uniform(np.array([10.0, 10.0]), 1.0, (0.0, 1.0))
    c = one("flow_following", (5, 2), around=Surroundings(fields={"up": field}), field="up")
    c.advance_to(3.0)
    assert c.v.vel[0, 1] > 0.95 and abs(c.v.vel[0, 0]) < 0.05
    vortex = FlowField.vortex(np.array([10.0, 10.0]), 0.5)
    c = one("flow_following", (8, 5), around=Surroundings(fields={"v": vortex}), field="v")
    turned = 0.0
    for _ in range(100):
        before = np.arctan2(*(c.v.pos[0] - 5.0)[::-1])
        c.advance_to(c.t + 0.1)
        turned += (np.arctan2(*(c.v.pos[0] - 5.0)[::-1]) - before + np.pi) % (2 * np.pi) - np.pi
    assert turned > 0.75 * np.pi  # circulated anticlockwise round the centre (3 m out at 1 m/s)


def test_leader_following_trails_the_leader():
    v = Vehicles.at([[2.0, 5.0], [6.0, 7.0], [6.0, 3.0]], radius=0.2)
    lead = Recipe((Behaviour("seek", params={"target": (9.0, 5.0)}),))
    follow = Recipe((Behaviour("separation", 1.0), Behaviour("leader_following", 1.0, params={"target": 0, "behind": 1.0})))
    c = Crowd(Room(12, 10), v, [lead, follow], np.array([0, 1, 1]))
    c.advance_to(12.0)
    leader = v.pos[0]
    for i in (1, 2):
        assert v.pos[i, 0] < leader[0]  # behind it, never in its way
        assert norms(v.pos[i] - leader) < 2.0


def test_cohesion_and_alignment():
    v = Vehicles.at([[4.0, 5.0], [6.0, 5.0]])
    c = Crowd(Room(10, 10), v, [Recipe((Behaviour("cohesion"),))])
    c.step()
    assert v.vel[0, 0] > 0 and v.vel[1, 0] < 0  # toward each other
    v = Vehicles.at([[4.0, 5.0], [5.0, 5.0]])
    v.vel[1] = [0.0, 1.0]
    c = Crowd(Room(10, 10), v, [Recipe((Behaviour("alignment"),))])
    c.advance_to(2.0)
    assert unit(v.vel)[0] @ [0.0, 1.0] > 0.99


def test_policies_weigh_and_prioritise():
    avoid, seek = np.array([[3.0, 0.0]]), np.array([[0.0, 3.0]])
    limit = np.array([2.0])
    mixed = weighted_truncated_sum([avoid, seek], [1.0, 1.0], limit)
    assert norms(mixed)[0] == pytest.approx(2.0) and mixed[0, 0] == pytest.approx(mixed[0, 1])
    budget = prioritised_budget([avoid, seek], [1.0, 1.0], limit)
    assert budget[0] == pytest.approx([2.0, 0.0])  # avoidance spends the whole budget
    budget = prioritised_budget([avoid * 0.25, seek], [1.0, 1.0], limit)
    assert budget[0] == pytest.approx([0.75, 1.25])
    quiet = np.zeros((1, 2))
    assert prioritised_dithering([quiet, seek], [1, 1], limit, [1.0, 1.0], np.zeros((2, 1)))[0, 1] == pytest.approx(2.0)
    assert prioritised_dithering([avoid, seek], [1, 1], limit, [0.5, 1.0], np.array([[0.7], [0.0]]))[0, 1] > 0


def test_heading_turns_at_a_bounded_rate():
    v = Vehicles.at([[5.0, 5.0]], heading=[[1.0, 0.0]], max_turn=np.pi / 2)
    v.vel[0] = [-1.0, 0.0]
    v.face(0.5)
    assert np.degrees(np.arctan2(v.heading[0, 1], v.heading[0, 0])) == pytest.approx(45.0, abs=1e-6) or \
        np.degrees(np.arctan2(v.heading[0, 1], v.heading[0, 0])) == pytest.approx(-45.0, abs=1e-6)


def test_neighbours_match_brute_force():
    rng = np.random.default_rng(5)
    pos = rng.uniform(0, 10, (300, 2))
    who = np.arange(0, 300, 7)
    near = Neighbours(pos).near(who, pos[who], k=5, radius=1.5)
    for row, i in enumerate(who):
        d = norms(pos - pos[i])
        d[i] = np.inf
        want = np.sort(d[d < 1.5])[:5]
        got = near.distance[row][near.mask[row]]
        assert got == pytest.approx(want)
    assert (near.index[~near.mask] == 300).all()


def test_level_of_detail_steers_distant_creatures_less_often_within_a_budget():
    rng = np.random.default_rng(2)
    v = Vehicles.at(rng.uniform(0, 40, (400, 2)))
    around = Surroundings(visitors=np.array([[5.0, 5.0]]), visitor_vel=np.zeros((1, 2)))
    lod = LevelOfDetail(near=5.0, levels=3, budget=120)
    c = Crowd(Room(40, 40), v, [Recipe((Behaviour("wander"),))], lod=lod, around=around)
    counts = np.zeros(400)
    for _ in range(80):
        before = c.force.copy()
        c.step()
        counts += np.any(c.force != before, axis=1)
    near = norms(v.pos - 5.0) < 5.0
    assert counts[near].min() >= 75  # every sub-step (a force unchanged by chance aside)
    assert counts[~near].mean() < 45
    assert c.steered <= 80 * 120


def test_an_unheard_creature_is_ranked_further_than_its_distance():
    """unheard = 2 with the inverse law and a -60 dB threshold: near the listener, the silent
    creature is at level 2 and the sounding one at 0; 12 m off (level 2 by distance), a note
    at -40 dB arrives at -61.6 dB, unheard (level 4, clipped to 3), one at 0 dB is heard (2)."""
    lod, audibility = LevelOfDetail(near=5.0, levels=3, unheard=2), Audibility(DistanceLaw("inverse"), -60.0)
    pos = np.array([[1.0, 0.0], [1.0, 0.0], [12.0, 0.0], [12.0, 0.0]])
    listener = np.zeros((1, 2))
    loudness = np.array([-np.inf, -10.0, -40.0, 0.0])
    assert lod.level(pos, listener, loudness, audibility).tolist() == [2, 0, 3, 2]
    assert lod.level(pos, listener).tolist() == [0, 0, 2, 2]  # loudness not asked: by distance


def test_sounding_is_the_latest_note_while_it_lasts():
    sounding = Sounding(2)
    sounding.play(0, 1.0, 1.5, -6.0)
    assert sounding.loudness(0.9).tolist() == [-np.inf, -np.inf]  # not yet started
    assert sounding.loudness(1.2).tolist() == [-6.0, -np.inf]
    assert sounding.loudness(1.5).tolist() == [-np.inf, -np.inf]  # over


def test_a_full_steering_budget_starves_no_creature():
    """100 creatures all near the visitor (each due every sub-step) and a budget of 30: they
    take turns, so each steers about 30 sub-steps in 100 (ranked by index, the last 70 never did)."""
    rng = np.random.default_rng(3)
    v = Vehicles.at(rng.uniform(4, 6, (100, 2)))
    around = Surroundings(visitors=np.array([[5.0, 5.0]]), visitor_vel=np.zeros((1, 2)))
    c = Crowd(Room(10, 10), v, [Recipe((Behaviour("wander"),))], lod=LevelOfDetail(near=5.0, budget=30),
              around=around)
    counts = np.zeros(100)
    for _ in range(100):
        before = c.force.copy()
        c.step()
        counts += np.any(c.force != before, axis=1)
    assert c.steered == 100 * 30
    assert counts.min() >= 28 and counts.max() <= 31
