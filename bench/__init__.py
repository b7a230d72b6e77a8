"""Benchmarks (not timed tests): ``python -m bench [NAME ...]``.

Each module ``bench/<name>.py`` defines ``run(quick: bool) -> list[Row]``. A row carries the
measured number, its target, and, where one applies, a baseline measured side by side in the
same process so the printed ratio means the same on any machine.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Callable


@dataclass
class Row:
    """One measured number with its unit, target and (optional) same-run baseline."""

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

    def to_dict(self) -> dict:
        return {**asdict(self), "passed": self.passed}


def best_of(fn: Callable[[], object], *, repeat: int = 3) -> float:
    """Smallest wall time of ``repeat`` calls of ``fn`` (seconds): the least disturbed run."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best
