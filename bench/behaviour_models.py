"""Behaviour models: the vectorised activation-model event update and state-object recall,
each against a plain-Python version of the same computation measured in the same process."""

from __future__ import annotations

import numpy as np

from bench import Row, best_of
from creatures.behaviour.models.activation import ActivationModel
from creatures.behaviour.state_object import StateObject


def _loop_activation_event(d: list[list[float]], met: list[list[bool]], active: list[bool], t_act: list[float],
                           t_inact: list[float], alpha: float, m: float, dt: float) -> None:
    """The same D_ij update as ActivationModel._integrate, one pair at a time: distances
    ``d`` (updated in place) between tuples that have ``met``, given which are ``active`` and
    their mean active/inactive times, with decay ``alpha``, separation ``m`` and step ``dt``."""
    n = len(active)
    for i in range(n):
        ratio = min(max((t_inact[i] + 1e-9) / (t_act[i] + 1e-9), 0.01), 100.0)
        keep = alpha ** ((ratio if active[i] else 1.0 / ratio) * dt)
        row = d[i]
        for j in range(n):
            if i != j and met[i][j]:
                target = m if active[i] != active[j] else 0.0
                row[j] = keep * row[j] + (1.0 - keep) * target


def _activation_rows(quick: bool) -> list[Row]:
    n = 100 if quick else 300
    events = 20 if quick else 50
    rng = np.random.default_rng(1)
    names = [f"t{k}" for k in range(n)]
    model = ActivationModel(names)
    model.observe(0.0, names)  # every pair tracked: the full N² update
    patterns = [list(rng.choice(names, n // 3, replace=False)) for _ in range(events)]

    def vectorised() -> None:
        for k, on in enumerate(patterns):
            model.observe(model.last_event + 0.5 + 0.01 * k, on)

    d = model.distances.tolist()
    met = model.met.tolist()
    active = [bool(a) for a in rng.random(n) < 0.3]
    t_act, t_inact = [1.0] * n, [2.0] * n

    def loop() -> None:
        for _ in range(events):
            _loop_activation_event(d, met, active, t_act, t_inact, 0.9, 10.0, 0.5)

    fast = best_of(vectorised) / events
    slow = best_of(loop, repeat=1) / events
    return [
        Row(f"activation event, {n} tuples", fast * 1e3, "ms", target=5.0,
            higher_is_better=False, baseline="python loop", ratio=slow / fast),
    ]


def _state_rows(quick: bool) -> list[Row]:
    pushes = 20_000 if quick else 100_000
    state = StateObject("level", history=1024)
    xs = np.random.default_rng(2).random(pushes).tolist()

    def push_all() -> None:
        t0 = state.times_array[-1] + 1.0 if len(state) else 0.0
        for k, x in enumerate(xs):
            state.push(t0 + 0.001 * k, x)

    rate = pushes / best_of(push_all)

    times, sal = state.times_array.copy(), state.saliencies_array.copy()
    start, end, reach = times[0], times[-1], 0.05

    def masked() -> None:
        state.masked_saliencies(start, end, reach=reach)

    def loop() -> None:
        for ti, si in zip(times, sal):
            masker = max(s * max(0.0, 1 - abs(ti - tj) / reach) for tj, s in zip(times, sal))
            _ = si if si >= masker else 0.0

    fast = best_of(masked)
    slow = best_of(loop, repeat=1)
    return [
        Row("state object push", rate, "pushes/s", target=50_000.0),
        Row("acausal masking, 1024-sample history", fast * 1e3, "ms", target=20.0,
            higher_is_better=False, baseline="python loop", ratio=slow / fast),
    ]


def run(quick: bool) -> list[Row]:
    return [*_activation_rows(quick), *_state_rows(quick)]
