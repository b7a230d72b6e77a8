"""Benchmarks (not timed tests): ``python -m bench [NAME ...]``.

Each module ``bench/<name>.py`` defines ``run(quick: bool) -> list[Row]``. A row carries the
measured number, its target, and, where one applies, a baseline measured side by side in the
same process so the printed ratio means the same on any machine.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass
from typing import Any, Callable


@dataclass
class Row:
    """One measured number with its unit, target and (optional) same-run baseline.

    ``ratio`` is how many times better the number is than the baseline's, in the row's own
    sense: baseline / value where lower is better (a time, a cost), value / baseline where
    higher is (a rate, a score). Above 1 ours is ahead, below 1 behind, whatever the unit: the
    table's column reads "6.7× mido" for a load 6.7 times as fast and "0.8× course alone" for
    a tick that costs 1.25 times as much."""

    name: str
    value: float
    unit: str
    target: float | None = None
    higher_is_better: bool = True
    baseline: str | None = None
    ratio: float | None = None

    @property
    def passed(self) -> bool | None:
        if self.target is None:
            return None
        # bool(): a numpy comparison gives numpy.bool_, which json cannot write.
        return bool(self.value >= self.target if self.higher_is_better else self.value <= self.target)

    def to_dict(self) -> dict[str, Any]:
        """The row for the results file. A number without a value (a skipped row's NaN, an
        unanswered note's infinite wait) is written as the string ``float`` reads back ("nan",
        "inf"): ``json`` would write the bare ``NaN`` and ``Infinity`` that strict readers refuse."""
        row = {key: str(v) if isinstance(v, float) and not math.isfinite(v) else v for key, v in asdict(self).items()}
        return {**row, "passed": self.passed}


HEADER = f"{'benchmark':<58} {'value':>14} {'unit':<12} {'target':>10}  {'× better than':>18}  ok"
"""The heading of the table :func:`format_row` lines up under."""


def format_row(bench: str, row: Row, previous: float | None = None) -> str:
    """One line of the results table; with ``previous`` (the same row's value in an earlier
    run) the ratio now/then is appended, so a regression shows beside the number."""
    mark = {True: "PASS", False: "FAIL", None: "-"}[row.passed]
    target = "" if row.target is None else f"{'≥' if row.higher_is_better else '≤'}{row.target:g}"
    ratio = "" if row.ratio is None else f"{row.ratio:.3g}× {row.baseline or ''}"
    line = f"{bench + ': ' + row.name:<58} {row.value:>14.4g} {row.unit:<12} {target:>10}  {ratio:>18}  {mark}"
    if previous is None:
        return line
    if not (math.isfinite(row.value) and math.isfinite(previous)):  # a skipped row has no number (NaN)
        return line + f"  (prev {previous:.4g})"
    return line + (f"  {row.value / previous:.3g}× prev" if previous else "  (prev 0)")


def best_of(fn: Callable[[], object], *, repeat: int = 3,
            clock: Callable[[], float] = time.perf_counter) -> float:
    """Smallest time of ``repeat`` calls of ``fn`` (seconds): the least disturbed run. Wall
    time unless ``clock`` says otherwise (``time.process_time``: this process's CPU time)."""
    best = float("inf")
    for _ in range(repeat):
        t0 = clock()
        fn()
        best = min(best, clock() - t0)
    return best
