"""Live (issue 18): an onset played into the run's microphone through JACK → the creature's
answering note on its MIDI output, measured on JACK's frame clock (bench/live_hearing.py does
the measuring: one probe client plays the tones and receives the notes, so both ends are JACK
frame times).

Every onset must be answered, and the p99 must stay under :data:`P99_BOUND_MS`, a bound for a
loaded 2-core CI, not the issue's benchmark target (≤ 30 ms, `python -m bench live_hearing`). The
transcriber gives a note 3 hops (35 ms) after the hop an attack lands in (``audio/transcribe.py``,
the live look: the model judges 3 hops back; before 2026-12-05 its notes waited a hop more for
the onset ear's), and the block comes on top, so 30 ms is below what this configuration can
give: a model trained for a smaller hop and a shorter look would be the way there (a JACK period
of 128 frames, with the microphone read between ticks, shortens it to p99 39.2 ms; models judging
1 and 2 hops back reached 28–29 ms without hearing the generated phrases exactly, and 33.5 ms
hearing them: docs/hearing.md).

Measured 2026-12-04 on the 2-core machine, JACK dummy at 44.1 kHz / 512 frames, 20 onsets, two
runs: p50 54.1 and 54.2 ms, p99 63.6 and 67.0 ms (2026-12-05: p50 51.8 and 54.4, p99 59.4 and 59.5 ms;
with the 3-hop look, 60 onsets: p50 41.3 and 41.0, p99 47.6 and 47.9 ms) (the model alone, its notes not waiting: p50
42.6, p99 51.4 ms; the onset ear alone, 2026-12-01: p50 71–81 ms, p99 93–225 ms, the tail a
loaded machine: in the 225 ms run the run's ticks began up to 100 ms late, with 128 input
overruns). Hence 300 ms: it still fails a run that loses onsets or stalls for the gap between
two of them.

An answer is the creature's first note-on or polyphonic pressure after the onset: the exchange
strikes a note that still sounds by perturbing it (its rule two), so a tone whose pitch the
wandering hand has just played is answered with pressure. Counting only note-ons, a run here
lost one onset of 20 so (2026-12-03, from the run's log: the hand struck 60 at 12.18 s, the
probe played 60 at 12.37 s, heard at once, answered with pressure on the sounding 60), as did a
CI run (19/20 answered, 22 notes played for 20 onsets: the hand's strikes among them).
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from bench.live_hearing import jack_available, measure

ONSETS, GAP = 20, 0.5
P99_BOUND_MS = 300.0
"""The worst p99 measured under load (225 ms, before) plus room (see the module's docstring)."""


@pytest.mark.jack
@pytest.mark.slow
@pytest.mark.parametrize("look", ["live", "quick"])
def test_every_onset_is_answered_through_jack_within_the_bound(look: str) -> None:
    """Either look a config chooses (``[audio] look``): the quick one answers sooner (p99 22.6 ms
    at a 128-frame period, docs/hearing.md), and must lose no onset either."""
    if not os.environ.get("CREATURES_JACK"):
        pytest.skip("set CREATURES_JACK=1 with a JACK server running (.ci/run starts one)")
    why = jack_available()
    if why is not None:
        pytest.skip(why)
    heard = measure(onsets=ONSETS, gap=GAP, look=look)
    summary = f"{heard.summary()} (p99 bound {P99_BOUND_MS:.0f} ms)"
    print(summary)
    assert heard.played == ONSETS, heard.output
    # Each answer is the first note-on or pressure after its onset and before the next one (GAP later): a
    # deaf or silent run answers none, one that loses onsets (a stalled loop) fewer than all.
    assert len(heard.latencies) == heard.played, f"{summary}\n{heard.output}"
    ms = 1e3 * np.array(heard.latencies)
    assert ms.min() > 0, summary
    assert np.percentile(ms, 99) <= P99_BOUND_MS, f"{summary}\n{heard.output}"
