"""The compiled crowd (creatures/room/kernel.py) against the numpy crowd it compiles: the same
seed traces the same paths, for every behaviour the kernel steers by, every policy, level of
detail and a shared room's remote creatures; and it is the faster (the reason it exists)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from creatures.room.director import FlowField, Path
from creatures.room.lod import LevelOfDetail
from creatures.room.motion import Crowd
from creatures.room.recipe import Behaviour, Recipe, Surroundings
from creatures.room.space import Obstacle, Room
from creatures.room.vehicle import Vehicles

ROOM = Room(12.0, 9.0, (Obstacle(4.0, 4.0, 0.6), Obstacle(8.0, 5.0, 0.5)))
FLOCK = (Behaviour("wall_avoidance", 3.0), Behaviour("obstacle_avoidance", 3.0),
         Behaviour("flee", 3.0, params={"target": "loud", "panic": 4.0}),
         Behaviour("flee", 2.0, params={"target": "visitor", "panic": 0.8}), Behaviour("separation", 1.5),
         Behaviour("arrival", 1.5, params={"target": "player", "slowing": 2.5}), Behaviour("alignment", 1.0),
         Behaviour("cohesion", 0.6), Behaviour("wander", 0.3))

RECIPES = {
    "flock, budget": [Recipe(FLOCK, "budget", neighbours=8, reach=3.0)],
    "flock, weighted": [Recipe(FLOCK, "weighted", neighbours=5, reach=2.0)],
    "dithering": [Recipe(tuple(Behaviour(b.name, b.weight, 0.6, b.params) for b in FLOCK), "dithering")],
    "targets": [Recipe((Behaviour("seek", params={"target": "centre"}), Behaviour("pursuit", params={"target": 0}),
                        Behaviour("evasion", params={"target": "visitor", "panic": 3.0}),
                        Behaviour("arrival", params={"target": (2.0, 7.0)}),
                        Behaviour("seek", 0.5, params={"target": "note"}),
                        Behaviour("wander", params={"rate": 4.0, "radius": 0.3}),
                        Behaviour("agent_avoidance", 2.0), Behaviour("wall_avoidance")), "weighted")],
    "the director's": [Recipe((Behaviour("path_following", params={"path": "aisle"}),
                               Behaviour("flow_following", 0.5, params={"field": "round"}),
                               Behaviour("separation")), "budget"),
                       Recipe((Behaviour("leader_following", params={"target": 0, "behind": 1.5}),
                               Behaviour("leader_following", 0.5, params={"target": "visitor"}),
                               Behaviour("wall_avoidance")), "weighted")],
    "two groups": [Recipe(FLOCK[:5] + (Behaviour("wander"),), "budget"),
                   Recipe((Behaviour("agent_avoidance", 2.0), Behaviour("wander", params={"rate": 1.0}),
                           Behaviour("seek", params={"target": "visitor"}), Behaviour("wall_avoidance")),
                          "dithering"), Recipe(())],
}


def _crowd(recipes: list[Recipe], *, compiled: bool, lod: LevelOfDetail | None = None, others: int = 0,
           n: int = 24, seed: int = 5) -> Crowd:
    rng = np.random.default_rng(seed)
    v = Vehicles.at(rng.uniform(0.5, [11.5, 8.5], (n, 2)), rng.normal(size=(n, 2)), radius=0.25,
                    max_speed=rng.uniform(0.7, 1.2, n), max_turn=3.0)
    around = Surroundings(visitors=np.array([[3.0, 2.0], [9.0, 7.0]]), visitor_vel=np.array([[0.2, 0.0], [0, -0.1]]),
                          player=np.array([[6.0, 4.5]]), loud=np.array([[10.0, 2.0]]),
                          notes=np.array([[1.0, 1.0], [11.0, 8.0]]),
                          paths={"aisle": Path(np.array([[1.0, 1.0], [11.0, 1.0], [6.0, 8.0], [1.0, 5.0]]), 0.5)},
                          fields={"round": FlowField.painted(np.array([12.0, 9.0]), [">>>v", "^..v", "^<<<"])},
                          others=np.column_stack([rng.uniform(1, 8, (others, 2)), rng.normal(0, 0.3, (others, 2)),
                                                  np.ones((others, 1)), np.zeros((others, 1)),
                                                  np.full((others, 1), 0.25)]))
    groups = np.arange(n) % len(recipes)
    c = Crowd(ROOM, v, recipes, groups, seed=seed, lod=lod, around=around)
    c.gain[::3] *= 0.5  # some creatures' behaviours gated down, as a `when` does
    if not compiled:
        c.compiled = None
    return c


def _live(c: Crowd, seconds: float, tick: float) -> None:
    t = 0.0
    while t < seconds - 1e-9:
        t += tick
        if t > 2.0:  # the visitors go, the loud sound stops: targets come and go mid-run
            c.around.visitors, c.around.visitor_vel, c.around.loud = np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2))
        c.advance_to(t)


@pytest.mark.parametrize("name", sorted(RECIPES))
@pytest.mark.parametrize("lod", [None, LevelOfDetail(near=3.0, levels=2, budget=10)], ids=["every", "lod"])
def test_the_kernel_traces_the_numpy_crowds_paths(name: str, lod: LevelOfDetail | None) -> None:
    runs = []
    for compiled in (True, False):
        c = _crowd(RECIPES[name], compiled=compiled, lod=lod, others=6 if name == "flock, budget" else 0)
        assert (c.compiled is not None) == compiled
        _live(c, 4.0, 0.04)
        runs.append(c)
    a, b = runs
    moved = np.abs(a.v.pos - _crowd(RECIPES[name], compiled=True).v.pos).max()
    assert moved > 0.5, "the crowd hardly moved: the comparison would prove nothing"
    for x, y in ((a.v.pos, b.v.pos), (a.v.vel, b.v.vel), (a.v.heading, b.v.heading), (a.force, b.force),
                 (a.wander_angle, b.wander_angle), (a.around.others, b.around.others)):
        np.testing.assert_allclose(x, y, atol=1e-9, rtol=0)
    assert (a.steps, a.steered) == (b.steps, b.steered)
    assert a.rng.random() == b.rng.random()  # the same random numbers drawn, no more, no fewer


def test_every_steering_behaviour_is_compiled() -> None:
    from creatures.room.kernel import PARAMS
    from creatures.room.recipe import BEHAVIOURS

    assert set(PARAMS) == set(BEHAVIOURS)
    covered = {b.name for recipes in RECIPES.values() for r in recipes for b in r.behaviours}
    assert covered == set(BEHAVIOURS)  # and each is held to numpy's paths above


def test_a_path_the_room_does_not_have_steers_in_numpy_and_says_so() -> None:
    """The kernel compiles only what it can resolve; numpy's call names what is missing."""
    recipe = Recipe((Behaviour("path_following", params={"path": "nowhere"}),))
    c = Crowd(Room(10, 10), Vehicles.at([[1.0, 1.0]]), [recipe])
    assert c.compiled is None
    with pytest.raises(KeyError, match="nowhere"):
        c.advance_to(1.0)


def test_the_kernel_is_many_times_faster() -> None:
    """Fifteen flockers for 10 s ticked at 0.5 s (a rehearsal's tick): the numpy crowd pays
    ~0.5 ms a sub-step in dispatch; the kernel must be at least 10× cheaper."""
    cost = {}
    for compiled in (True, False):
        c = _crowd(RECIPES["flock, budget"], compiled=compiled, n=15)
        _live(c, 1.0, 0.5)  # compiled and warm
        start = time.process_time()
        t = c.t
        for _ in range(20):
            t += 0.5
            c.advance_to(t)
        cost[compiled] = time.process_time() - start
    assert cost[False] > 10 * cost[True], cost


@pytest.mark.parametrize("n", [1, 9, 300])
def test_the_kernels_grid_finds_the_kd_trees_neighbours(n: int) -> None:
    """The compiled crowd's neighbours (a grid of cells one reach wide) are the kd-tree's: the
    same k nearest within reach, in the same order, for a sparse, a small and a dense crowd."""
    from creatures.room.index import Neighbours
    from creatures.room.kernel import nearest

    rng = np.random.default_rng(n)
    pos = rng.uniform(0, [12.0, 9.0], (n, 2))
    who = np.arange(n)
    for k, reach in ((7, 3.0), (3, 0.8), (12, 20.0)):
        ours = nearest(pos, k, reach, np.array([12.0, 9.0]))
        theirs = Neighbours(pos).near(who, pos, k=k, radius=reach).index
        np.testing.assert_array_equal(ours, theirs)


def test_the_kernels_grid_has_the_crowds_size_not_the_floors() -> None:
    """A small reach over a large floor: the grid's cells stay a few per body (cells one reach
    wide made 10⁸ of them for 0.1 m in a 1000 m square room, 3.4 s a sub-step), still at least
    a reach wide, and the neighbours are still the kd-tree's, pairs within reach included."""
    from creatures.room.index import Neighbours
    from creatures.room.kernel import CELLS_PER_BODY, _layout, nearest

    for n, reach, size in ((300, 0.1, (1000.0, 1000.0)), (15, 3.0, (14.0, 10.0)), (1, 0.5, (1000.0, 50.0))):
        cell, nx, ny = _layout(reach, *size, n)
        assert cell >= reach and nx * cell >= size[0] and ny * cell >= size[1]
        assert nx * ny <= CELLS_PER_BODY * n + nx + ny + 1, (n, reach, nx, ny)
    rng = np.random.default_rng(4)
    centres = rng.uniform(1, 999, (150, 2))
    pos = np.concatenate([centres, centres + rng.uniform(-0.05, 0.05, (150, 2))])  # 150 pairs within reach
    ours = nearest(pos, 3, 0.1, np.array([1000.0, 1000.0]))
    theirs = Neighbours(pos).near(np.arange(300), pos, k=3, radius=0.1).index
    np.testing.assert_array_equal(ours, theirs)
    assert (ours[:, 0] < 300).all()  # each has its pair
