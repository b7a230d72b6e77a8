"""A live colony under a loopback OSC flood (issue 13, "must show"): the shipped sand:stone
colony, a real ``creatures run`` process with ``[osc] port`` set, is sent 10 s of random OSC
from another process as fast as one core can (hellos with random names, huge and non-finite
numbers, packets of bad type tags, junk; bench/flood.py). It must keep ≥ 95 % of its ticks,
hold a bounded peer table, send no more bytes than it read, and write under 100 lines to
stderr.

Measured here (2 cores shared by eight busy processes, load 6–8): 99.1 % of ticks in 9 runs
of 10 (the other 91 %: one stall of over a second), 0 peers, bytes out/in 0.012, no stderr
line, at 25,000–140,000 packets a second. The same run with no flood at all also stalled once
in 3 runs (a loaded machine freezing the process, not the flood), so a short run is tried a
second time before it fails: a real regression (a loop spinning on the flooded socket made
55 % here) fails both."""

from __future__ import annotations

import pytest

from bench.flood import SECONDS, flood_colony


@pytest.mark.slow
def test_a_colony_flooded_for_ten_seconds_keeps_its_time_its_table_and_its_bounds(tmp_path):
    result = flood_colony(tmp_path / "first", seconds=SECONDS)
    if result.kept < 0.95:
        result = flood_colony(tmp_path / "second", seconds=SECONDS)
    assert result.sent_packets > 10_000 * SECONDS / 10, "the flooder hardly sent: not a flood"
    assert result.kept >= 0.95, result.summary
    assert result.peers <= result.max_peers
    assert result.bytes_out <= result.bytes_in, result.summary
    assert result.stderr_lines < 100
    # the drops were counted by cause, and shown at the end of the run
    assert {"type tags", "arguments", "not osc", "oversize"} <= set(result.dropped)
    assert "dropped (" in result.summary and "bytes in" in result.summary
