"""(void*): how fast the shipped installation runs offline, and what laying out a tile costs.

Rows (``python -m bench void``):

* the shipped installation (three characters with bodies, a camera, the score) offline with
  its rehearsal visitors, without frames, with and without audio synthesis: target ≥ 20×
  real time (issue 22);
* one course laid out on the theme layer (:meth:`ScoreLayout.steer`: A* on the tile graph to
  a leitmotif's head, then to its end, the laid future replaced from the next beat): target
  ≤ 1 ms, beside the same course found by Dijkstra from scratch over the tile graph (what a
  layout without the graph's distance table would pay).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

import installations
from bench import Row
from bench.installations import offline_speed
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from creatures.score.program import ScoreProgram
from midi.sinks import MemorySink




def _steer_cost(courses: int) -> tuple[float, float]:
    """CPU seconds per course laid by the score, and per the same walk found by plain Dijkstra (CPU
    time: the cost of the work, not what another process took of the core meanwhile)."""
    clock = SimulatedClock()
    session = Session(load_installation(installations.path("void")), clock, EventLog(keep_in_memory=0),
                      MemorySink())
    score = next(c for c in session.creatures if c.name == "score").score
    for _ in range(10):
        session.step(clock.advance(0.02), 0, None, audio=False)
    names = ("eddie", "elliot", "earl")
    t0 = time.process_time()
    for k in range(courses):
        score.steer(clock.now(), "theme", ScoreProgram.of_tags([f"{names[k % 3]}-head", f"{names[k % 3]}-end"]))
    laid = (time.process_time() - t0) / courses
    graph = score.graph
    rows, cols = np.nonzero(np.isfinite(graph.cost))
    matrix = csr_matrix((graph.cost[rows, cols], (rows, cols)), shape=graph.cost.shape)
    t0 = time.process_time()
    for k in range(courses):
        dijkstra(matrix, indices=k % len(graph.tiles))
    return laid, (time.process_time() - t0) / courses


def run(quick: bool) -> list[Row]:
    seconds = 30.0 if quick else 180.0
    laid, plain = _steer_cost(300 if quick else 3000)
    return [
        Row("(void*) offline, with audio (no frames)", offline_speed("void", seconds, audio=True), "× real time", 20.0),
        Row("(void*) offline, behaviour and MIDI only", offline_speed("void", seconds, audio=False), "× real time", 20.0),
        Row("(void*) a course laid on the theme layer (A*, layout)", laid * 1e3, "ms", 1.0, higher_is_better=False,
            baseline="Dijkstra from scratch, one source", ratio=plain / laid),
    ]
