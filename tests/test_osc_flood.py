"""A live colony under a loopback OSC flood (issue 13, "must show"): the shipped sand:stone
colony, a real ``creatures run`` process with ``[osc] port`` set, is sent 10 s of random OSC
from another process as fast as one core can (hellos with random names, huge and non-finite
numbers, packets of bad type tags, junk; bench/flood.py). It must keep ≥ 95 % of its ticks,
hold a bounded peer table, send no more bytes than it read, and write under 100 lines to
stderr.

Measured here (2 cores shared by eight busy processes, load 8–9), with the default
``max_rate`` of 1,000: 99.9 % of ticks in 7 runs of 7, 16–34 proved peers (the flooder hears
the asks and proves hellos from new names), bytes out/in 0.02–0.035, no stderr line, at
50,000–190,000 packets a second. At ``max_rate`` 2,000, 2 runs of 4 at load 12 lost a
second (92 %); the same run with no flood once stalled so too at load 7. So a run that falls
short is tried a second time before the test fails: a real regression (a loop spinning on the
flooded socket made 55 % here) fails both. A CI run whose flooder sent only ~16,000 packets
once held no peer: its proved hellos went in a burst at each round's end, into a full socket
buffer; they are now spread through the round, and the asker proves its own hello at once. It
ran beside the other test worker, which took the niced flooder's core: the test now runs with
the real-time ones, alone (the issue's flood is "as fast as one core can")."""

from __future__ import annotations

import pytest

from bench.flood import SECONDS, flood_colony


@pytest.mark.realtime  # alone: beside the other test worker the flooder once sent a tenth as much or less
@pytest.mark.slow
def test_a_colony_flooded_for_ten_seconds_keeps_its_time_its_table_and_its_bounds(tmp_path):
    result = flood_colony(tmp_path / "first", seconds=SECONDS)
    if result.kept < 0.95:
        result = flood_colony(tmp_path / "second", seconds=SECONDS)
    assert result.sent_packets > 10_000 * SECONDS / 10, "the flooder hardly sent: not a flood"
    assert result.kept >= 0.95, result.summary
    assert result.proved_sent > 0, "the colony never asked the flooder for its token"
    assert 0 < result.peers <= result.max_peers, result.summary  # the flooder proved some hellos
    assert result.bytes_out <= result.bytes_in, result.summary
    assert result.stderr_lines < 100
    # the drops were counted by cause, and shown at the end of the run
    assert {"type tags", "arguments", "not osc", "oversize"} <= set(result.dropped)
    assert "dropped (" in result.summary and "bytes in" in result.summary
