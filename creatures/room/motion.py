"""The crowd on clock time: fixed sub-steps, so that behaviour does not depend on the tick
(DESIGN.md, "Time"; the WavesWorld lesson that machine-dependent time makes behaviour run
faster on faster machines applies to ticks as much as to machines).

:meth:`Crowd.advance_to` runs as many sub-steps of ``substep`` seconds as fit before the
clock's time, carrying the remainder: a run ticked at 0.02 s and one ticked at 0.04 s take
the same sub-steps and draw the same random numbers, so they trace the same paths (up to
what their decisions, made at ticks, change). Levels of detail are planned on the same grid
(:attr:`LevelOfDetail.replan` sub-steps apart), not per tick: planned per tick, a level changed
on a different sub-step at each tick, and eight wanderers ticked at 0.02 s and at 0.04 s ended up
to 9.2 m apart after 10 s.
"""

from __future__ import annotations

import numpy as np

from creatures.room.combine import POLICIES
from creatures.room.index import Neighbours
from creatures.room.kernel import Program, draws, substeps
from creatures.room.lod import Audibility, LevelOfDetail
from creatures.room.recipe import BEHAVIOURS, Recipe, Step, Surroundings
from creatures.room.space import Room
from creatures.room.steering import Scene
from creatures.room.vehicle import Vehicles

SUBSTEP = 0.01
"""Default sub-step, seconds: short enough for arrival's spring and for separation at 1 m/s
to act before two 0.25 m bodies meet (0.01 m of travel per sub-step)."""


class Crowd:
    """Vehicles in a room, each in a ``group`` whose :class:`Recipe` steers it."""

    def __init__(self, room: Room, vehicles: Vehicles, recipes: list[Recipe], groups: np.ndarray | None = None,
                 *, substep: float = SUBSTEP, seed: int = 0, lod: LevelOfDetail | None = None,
                 around: Surroundings | None = None) -> None:
        self.room, self.v, self.recipes = room, vehicles, recipes
        self.groups = np.zeros(len(vehicles), dtype=np.intp) if groups is None else np.asarray(groups, np.intp)
        self.substep, self.lod = substep, lod
        self.around = around or Surroundings()
        # Where the levels are planned from (None: the visitors), and how loud each creature
        # sounds now (dB, -inf silent) and how that is heard (None: levels by distance alone);
        # the caller sets them (listeners and loudness each tick).
        self.listeners: np.ndarray | None = None
        self.loudness: np.ndarray | None = None
        self.audibility: Audibility | None = None
        self.rng = np.random.default_rng(seed)
        self.wander_angle = np.zeros(len(vehicles))
        self.force = np.zeros((len(vehicles), 2))
        # Each creature's own multiplier of each behaviour's weight (a percept-gated `when`).
        self.gain = np.ones((len(vehicles), max((len(r.behaviours) for r in recipes), default=0)))
        self.t = 0.0
        self.steps = 0
        self.steered = 0  # creature-steerings done, for the level-of-detail budget's accounting
        self._level = np.zeros(len(vehicles), dtype=np.int64)
        self._last = np.zeros(len(vehicles), dtype=np.int64)  # the sub-step each last steered
        self._next_plan = 0  # the sub-step on which the levels are planned next
        self.compiled = Program.of(recipes, self.around)  # None: a recipe the kernel cannot run (numpy)
        room.contain(vehicles.pos, vehicles.vel, vehicles.radius)

    def skip_to(self, t: float) -> None:
        """The clock jumped to ``t`` (a clock gap between two ticks, ``creatures.clock.clock_gap``:
        a suspended machine, a fast-forwarded offline clock): the crowd stands where it was and
        the gap's sub-steps are skipped, not run. A night is 8.6 million sub-steps, which a
        machine waking from suspend would spend hours catching up on (the thirty-day test could
        not live the flock for them)."""
        self.steps = max(self.steps, int(np.floor(t / self.substep + 1e-9)))
        self.t = self.steps * self.substep

    def advance_to(self, t: float) -> int:
        """Run every sub-step that ends by ``t``; returns how many ran."""
        ran = 0
        while (self.steps + ran) * self.substep + self.substep <= t + 1e-9:
            ran += 1
        if self.compiled is None:
            for _ in range(ran):
                self.step()
        else:
            self._run(ran)
        return ran

    def _run(self, count: int) -> None:
        """``count`` sub-steps compiled (:mod:`.kernel`), in runs between two plannings of the
        levels of detail: the same sub-steps, levels and random numbers as :meth:`step`."""
        v, p, room, around = self.v, self.compiled, self.room, self.around
        for name in ("pos", "vel", "heading"):  # the kernel writes the rows in place
            setattr(v, name, np.ascontiguousarray(getattr(v, name), dtype=float))
        if len(around.others):
            around.others = np.ascontiguousarray(around.others, dtype=float)
        surroundings = [np.ascontiguousarray(x, dtype=float).reshape(-1, 2)
                        for x in (around.visitors, around.visitor_vel, around.player, around.loud, around.notes)]
        while count:
            run = count
            if self.lod is None:
                steer = np.ones((run, len(v)), dtype=bool)
                self._last[:] = self.steps + run - 1
            else:
                if self.steps >= self._next_plan:
                    self._plan()
                run = min(run, self._next_plan - self.steps)
                steer = np.zeros((run, len(v)), dtype=bool)
                for s in range(run):
                    who = self.lod.due(self.steps + s, self._level, self._last)
                    self._last[who] = self.steps + s
                    steer[s, who] = True
            self.steered += int(steer.sum())
            substeps(self.substep, steer, draws(p, self.groups, steer, self.rng), v.pos, v.vel, v.heading, v.mass,
                     v.max_force, v.max_speed, v.radius, v.max_turn, self.force, self.wander_angle, self.gain,
                     self.groups, around.others, room.size, room.centres, room.radii, p.start, p.count, p.policy,
                     p.k, p.reach, p.wanders, p.code, p.weight, p.probability, p.target, p.creature, p.point, p.par,
                     p.ordinal, p.data, p.paths, p.fields, *surroundings)
            self.steps += run
            self.t = self.steps * self.substep
            count -= run

    @property
    def level(self) -> np.ndarray:
        """Each creature's level of detail as last planned (0 without one)."""
        return self._level

    def _plan(self) -> None:
        """Choose levels of detail from where the creatures and the :attr:`listeners` stand now,
        on every sub-step that is a multiple of :attr:`LevelOfDetail.replan` (and on the first
        after a clock gap): on the clock's grid, whatever the tick, so the levels, and with
        them who steers when, are the same at any tick."""
        assert self.lod is not None
        listeners = self.around.visitors if self.listeners is None else self.listeners
        self._level = self.lod.level(self.v.pos, listeners, self.loudness, self.audibility)
        self._next_plan = (self.steps // self.lod.replan + 1) * self.lod.replan

    def step(self) -> None:
        """One sub-step: who steers, their neighbours, their forces, then everyone moves."""
        v = self.v
        if self.lod is None:
            who = np.arange(len(v))
        else:
            if self.steps >= self._next_plan:
                self._plan()
            who = self.lod.due(self.steps, self._level, self._last)
        self._last[who] = self.steps
        others = self.around.others
        if len(others):  # a shared room's remote creatures move on by their velocity (dead reckoning)
            others[:, :2] += others[:, 2:4] * self.substep
        if len(who):
            # The crowd's rows, then the remote creatures' (neighbours too, after every own
            # index, so a creature's own index still names it), then one zero row, where
            # padded neighbours point.
            mine = (v.pos, v.vel, v.radius)
            theirs = (others[:, :2], others[:, 2:4], others[:, 6])
            rows = tuple(np.concatenate([x, y, np.zeros((1, *x.shape[1:]))]) for x, y in zip(mine, theirs))
            index = Neighbours(rows[0][:-1])
            for g, recipe in enumerate(self.recipes):
                members = who if len(self.recipes) == 1 else who[self.groups[who] == g]
                if len(members):
                    self.force[members] = self._steer(index, rows, recipe, members)
            self.steered += len(who)
        v.step(self.force, self.substep)
        self.room.contain(v.pos, v.vel, v.radius)
        self.t = (self.steps + 1) * self.substep  # by count, so no rounding drift over a night
        self.steps += 1

    def _steer(self, index: Neighbours, rows: tuple[np.ndarray, ...], recipe: Recipe, who: np.ndarray) -> np.ndarray:
        v = self.v
        if not recipe.behaviours:  # a creature that stands where it was put
            return np.zeros((len(who), 2))
        # Rows gathered with take: numpy's fancy indexing of whole rows costs several times more
        # for the same copy (14 against 1 µs for 200 creatures' 7 neighbours), every sub-step.
        here = v.pos.take(who, axis=0)
        near = index.near(who, here, k=recipe.neighbours, radius=recipe.reach)
        pos, vel, radius = (x.take(near.index, axis=0) for x in rows)
        scene = Scene(who, here, v.vel.take(who, axis=0), v.heading.take(who, axis=0), v.max_speed[who],
                      v.radius[who], near, pos, vel, radius, self.room, v.max_force[who] / v.mass[who])
        step = Step(scene, v.pos, v.vel, v.heading, self.around, self.substep, self.rng, self.wander_angle)
        gain = self.gain.take(who, axis=0)  # each creature's multiplier of each behaviour's weight
        forces = [BEHAVIOURS[b.name](step, b.params) * gain[:, k:k + 1] for k, b in enumerate(recipe.behaviours)]
        weights = [b.weight for b in recipe.behaviours]
        policy = POLICIES[recipe.combine]
        if recipe.combine == "dithering":
            uniform = self.rng.random((len(forces), len(who)))
            return policy(forces, weights, v.max_force[who], [b.probability for b in recipe.behaviours], uniform)
        return policy(forces, weights, v.max_force[who])
