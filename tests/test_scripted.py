"""Scripted levels (creatures/authored/scripted.py): a drive's arc and a ``script`` percept
read their points by bisection, and must give np.interp's number exactly (a run's course
hangs on a drive's last bits)."""

from __future__ import annotations

import numpy as np
import pytest

from creatures.authored.scripted import Scripted


def test_a_script_reads_as_np_interp_does_between_at_and_beyond_its_points():
    rng = np.random.default_rng(7)
    for _ in range(300):
        times = np.unique(rng.uniform(0.0, 100.0, rng.integers(1, 7)))
        levels = rng.normal(size=len(times))
        script = Scripted(list(zip(times.tolist(), levels.tolist())))
        for t in np.concatenate([rng.uniform(-10.0, 110.0, 25), times]):
            assert script(float(t)) == float(np.interp(t, times, levels))


def test_a_script_of_no_points_is_refused():
    with pytest.raises(ValueError, match="at least one"):
        Scripted([])
