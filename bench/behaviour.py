"""Action-selection speed: ticks per second of one ActionGroup holding 10, 100 and 1,000
action-tuples (target ≥ 200 ticks/s at 1,000; thesis: "other extensions improve
computational efficiency of action-groups").

The tuples share 20 trigger percepts (percepts are creature-wide, so real groups share them
too) whose saliencies change every tick, values are spread so selections happen, and each
tuple lasts 0.5–3 s of simulated time at 20 ticks per simulated second: the run mixes plain
ticks, selections, interruptions and credit assignment. Baseline, side by side: the same
group evaluated the naive way (every tuple's ``expected_value(t)`` in a Python loop), which
is what a tick would cost without the vectorised gather.

The expectation machinery (surprise at every end, confidence scaling every credit assignment,
thesis "expectations about value") is measured on the same 1,000-tuple group with and without
it, in the same run and in CPU time: its cost is the extra time per tick (target ≤ 20 %).
"""

from __future__ import annotations

import time
from typing import Callable

import numpy as np

import bench
from bench import Row
from creatures.behaviour.action_group import ActionGroup
from creatures.behaviour.action_tuple import Action, ActionTuple, DoUntil
from creatures.behaviour.expectation import Expectations
from creatures.behaviour.percept import FunctionPercept

DT = 0.05
EXPECTATION_TICKS = 1000
"""Ticks a run when expectations are timed on and off (quick or not: shorter runs are noise)."""


def make_group(n: int, seed: int = 0, *, expect: bool = False) -> ActionGroup:
    rng = np.random.default_rng(seed)
    phases = rng.uniform(0, 2 * np.pi, 20)
    percepts = [FunctionPercept(f"p{k}", lambda t, ph=ph: 0.5 + 0.5 * np.sin(0.7 * t + ph)) for k, ph in enumerate(phases)]
    tuples = [
        ActionTuple(
            f"t{i}", percepts[i % 20], Action(f"a{i % 50}"), DoUntil(float(rng.uniform(0.5, 3.0))), float(rng.uniform(1, 10))
        )
        for i in range(n)
    ]
    return ActionGroup(f"bench{n}", tuples, rng=rng, alpha=0.05, multiple=1.5,
                       expectations=Expectations() if expect else None,
                       grounded_by="a benchmark of the cost of selection and credit, not of what is learnt")


def ticks_per_second(n: int, ticks: int, *, expect: bool = False,
                     clock: Callable[[], float] = time.perf_counter) -> float:
    group = make_group(n, expect=expect)
    for k in range(50):  # warm the proximity cache and the first selections
        group.tick(k * DT)

    def run() -> None:
        t0 = group.last_tick + DT
        for k in range(ticks):
            group.tick(t0 + k * DT)

    return ticks / bench.best_of(run, clock=clock)


def naive_evaluations_per_second(n: int, ticks: int) -> float:
    group = make_group(n)

    def run() -> None:
        for k in range(ticks):
            t = k * DT
            [tp.expected_value(t) for tp in group.tuples]

    return ticks / bench.best_of(run)


def run(quick: bool) -> list[Row]:
    ticks = 100 if quick else 1000
    rows = []
    for n in (10, 100, 1000):
        target = 200.0 if n == 1000 else None
        rows.append(Row(f"ticks/s, {n} action-tuples", ticks_per_second(n, ticks), "ticks/s", target))
    naive = naive_evaluations_per_second(1000, ticks // 4)
    fast = rows[-1].value
    rows.append(
        Row("1000 tuples vs naive per-tuple expected_value loop", fast, "ticks/s", None,
            baseline="naive loop", ratio=fast / naive)
    )
    # On and off interleaved in pairs, in this process's CPU time (other processes' load does
    # not count), 1,000 ticks a run even when quick, each side's fastest run against the
    # other's: the least disturbed runs. (100-tick runs and the median of the pairs' ratios
    # read anywhere from -29 % to +55 % on a loaded machine: the noise was the measurement.)
    off, on = [], []
    for _ in range(5):
        off.append(ticks_per_second(1000, EXPECTATION_TICKS, clock=time.process_time))
        on.append(ticks_per_second(1000, EXPECTATION_TICKS, expect=True, clock=time.process_time))
    return rows + expectation_rows(off, on)


def expectation_rows(off: list[float], on: list[float]) -> list[Row]:
    """What keeping expectations costs, from the ticks/s of runs without (``off``) and with
    (``on``) them, per CPU second: the fastest of each side against the other's. The ratio is
    on's speed to off's (below 1: slower); the cost row gives the same as a share of a tick. The
    rows above are wall time, so the clock is in the name: the same group reads twice the ticks
    a second here on a machine whose other work takes half its core."""
    slower = max(off) / max(on)
    return [Row("ticks per CPU second, 1000 tuples keeping expectations", float(np.median(on)), "ticks/s", None,
                baseline="expectations off", ratio=1.0 / slower),
            Row("expectations' cost per tick, 1000 tuples", 100.0 * (slower - 1.0), "% of a tick", 20.0,
                higher_is_better=False)]
