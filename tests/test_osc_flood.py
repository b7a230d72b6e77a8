"""A live colony under a loopback OSC flood (issue 13, "must show"): the shipped sand:stone
colony, a real ``creatures run`` process with ``[osc] port`` set, is sent 10 s of random OSC
from another process as fast as one core can (hellos with random names, huge and non-finite
numbers, packets of bad type tags, junk; bench/flood.py). It must keep ≥ 95 % of its ticks,
hold a bounded peer table, send no more bytes than it read, and write under 100 lines to
stderr. Measured here (two cores shared by eight busy processes): 99 % of ticks, 0 peers,
bytes out/in about 0.06, no stderr line, at about 100,000 packets a second."""

from __future__ import annotations

import pytest

from bench.flood import SECONDS, flood_colony


@pytest.mark.slow
def test_a_colony_flooded_for_ten_seconds_keeps_its_time_its_table_and_its_bounds(tmp_path):
    result = flood_colony(tmp_path, seconds=SECONDS)
    assert result.sent_packets > 10_000 * SECONDS / 10, "the flooder hardly sent: not a flood"
    assert result.kept >= 0.95, result.summary
    assert result.peers <= result.max_peers
    assert result.bytes_out <= result.bytes_in, result.summary
    assert result.stderr_lines < 100
    # the drops were counted by cause, and shown at the end of the run
    assert {"type tags", "arguments", "not osc", "oversize"} <= set(result.dropped)
    assert "dropped (" in result.summary and "bytes in" in result.summary
