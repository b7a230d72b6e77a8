"""Bodies into an offline run's events log, so the run can be replayed and re-rendered later.

Each creature's skeleton is logged once at the start (``skeleton``), then at ``[view]
log_fps`` frames a second of clock time (a :class:`~creatures.body.frames.FrameClock`, so a
slow tick never changes the rate) every body's joints and note objects (``pose``, see
:func:`creatures.view.snapshot.pose_event`). Bounded: the poses of one run take at most
:data:`POSE_BUDGET` bytes of the log — half the size at which the log rotates, so a week-long
run can never push its own start (and its skeletons) out of ``events.jsonl`` — after which one
``poses stopped`` event says so and the run goes on without them.
"""

from __future__ import annotations

from typing import Callable

import orjson

from creatures.body.frames import FrameClock
from creatures.runtime.world import World
from creatures.view.snapshot import bodies, pose_event, skeleton_events

POSE_BUDGET = 32 * 1024 * 1024
"""Bytes of ``pose`` events one run writes at most (the events log rotates at 64 MB)."""


class PoseLog:
    """Logs the colony's skeletons now and its poses whenever a frame falls due."""

    def __init__(self, fps: float, world: World, say: Callable[[str], None]) -> None:
        self.world, self.say = world, say
        self.clock = FrameClock(fps, world.clock)
        self.written = 0  # bytes of pose events so far
        self.stopped = False
        for fields in skeleton_events(bodies(world.creatures)):
            world.emit("skeleton", **fields)

    def write(self) -> None:
        """Log every body's pose if a frame fell due (frames that fell due together are one)."""
        if self.stopped or not self.clock.due():
            return
        for creature in self.world.creatures:
            fields = pose_event(creature)
            if fields is None:
                continue
            self.written += len(orjson.dumps(fields))
            if self.written > POSE_BUDGET:
                self.stopped = True
                self.world.emit("poses stopped", bytes=self.written, budget=POSE_BUDGET)
                self.say(f"body poses stopped at {self.world.clock.now():.1f} s: {POSE_BUDGET} bytes of the "
                         "events log are theirs at most (lower [view] log_fps to keep them for longer)")
                return
            self.world.emit("pose", **fields)
