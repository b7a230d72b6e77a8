"""Live: an onset played into the run's microphone through JACK → the creature's answering note
on its MIDI output, measured on JACK's frame clock (bench/live_hearing.py does the measuring)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from bench.live_hearing import jack_available, measure


@pytest.mark.jack
@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="measured 2026-12-01: the first onset is answered (147-307 ms after it), then "
                   "the run's loop stalls for seconds at a time: every send re-lists the JACK MIDI ports on the "
                   "creature's thread (midi/ports.py ResilientPort._check -> factory.names()), the microphone's "
                   "ring overflows and later onsets are lost; without a MIDI output all 8 of 8 onsets were heard "
                   "and answered")
def test_onset_to_answer_latency_through_jack() -> None:
    if not os.environ.get("CREATURES_JACK"):
        pytest.skip("set CREATURES_JACK=1 with a JACK server running (.ci/run starts one)")
    why = jack_available()
    if why is not None:
        pytest.skip(why)
    latencies, played, output = measure(onsets=20, gap=0.5)
    ms = 1e3 * np.array(latencies)
    print(f"answered {len(ms)}/{played}; onset → answer p50 {np.median(ms):.1f} ms, "
          f"p99 {np.percentile(ms, 99):.1f} ms" if len(ms) else f"answered 0/{played}\n{output}")
    assert played == 20
    # Each answer is the first note-on after its onset and before the next one (0.5 s later);
    # a silent run answers none, so at least a third must be heard and answered.
    assert len(ms) >= played // 3, output
    assert ms.min() > 0
