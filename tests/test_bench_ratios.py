"""The ratio column says how many times better a row is than its same-run baseline (bench.Row):
above 1 ours is ahead, below 1 behind, for costs as for rates. Rows that printed a cost ratio
(dearer read as "1.2×", like a speed-up) read the same way as every other row now."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

import bench.behaviour as behaviour
import bench.rehearse as rehearse
from bench import Row
from bench.blend import colony_table


def better(row: Row, baseline: float) -> float:
    """How many times better ``row`` is than ``baseline`` (same unit), as bench.Row defines it."""
    return baseline / row.value if not row.higher_is_better else row.value / baseline


def test_a_dearer_shipped_colony_reads_below_one_against_the_course_alone() -> None:
    alone, blended = {"ada": 2.0e-3, "bo": 3.0e-3}, {"ada": 2.4e-3, "bo": 4.5e-3}
    rows = colony_table(10e-3, 12e-3, alone, blended)
    colony, creatures, dearest = (r for r in rows if r.ratio is not None)
    assert colony.ratio == pytest.approx(better(colony, 10.0)) == pytest.approx(10 / 12)
    assert colony.passed  # 1.2× the cost, within the 1.5× the issue allows
    assert creatures.ratio == pytest.approx(better(creatures, 2.5)) and creatures.ratio < 1
    assert "bo" in dearest.name and dearest.ratio == pytest.approx(3.0 / 4.5)


def test_expectations_that_slow_the_tick_read_below_one_and_their_cost_carries_no_ratio() -> None:
    rows = behaviour.expectation_rows(off=[1000.0, 1100.0], on=[950.0, 1000.0])
    keeping, cost = rows
    assert keeping.ratio == pytest.approx(1000.0 / 1100.0)
    assert "CPU" in keeping.name  # beside rows in wall time, which read half as many ticks on a loaded machine
    assert cost.value == pytest.approx(10.0) and cost.passed
    assert cost.ratio is None  # a share of a tick already; a ratio to "expectations off" said 1.1× (worse)


def test_the_rehearsed_week_is_held_to_its_target_in_cpu_time_with_no_baseline_ratio(monkeypatch) -> None:
    monkeypatch.setattr(rehearse, "setup_cost", lambda inst: 2.0)
    monkeypatch.setattr(rehearse, "rehearse", lambda inst, days: SimpleNamespace(open_seconds=360.0, tick=0.04))
    monkeypatch.delenv("REHEARSE_DAYS", raising=False)
    monkeypatch.delenv("REHEARSE_WEEK", raising=False)
    week = rehearse.run(quick=True)[-1]
    assert "week" in week.name and "CPU" in week.name
    assert week.ratio is None and week.baseline is None  # the target is in its own column
    assert week.target == rehearse.TARGET and not week.higher_is_better
