"""The loudspeaker's lead (audio/lead.py) on a fake sound card and a simulated clock.

The live loop's conditions, measured on JACK (issue 14), played on :class:`FakeCard` (tests/
test_audio_faults.py): the device calls back before the first mix exists, the first tick is
an instant with no frames, the stream is resampled (soxr HQ hands its output on in chunks),
writes come up to 3 ms late, and the device's clock runs fast, slow, or stalls and never
catches up (the dummy server skipping cycles). The old fixed lead written at the first block
underran in every one of these; with :class:`audio.lead.Lead` nothing underruns after the
first second, the only gaps are the start's, and the latency stays bounded.
"""

from __future__ import annotations

import numpy as np
import pytest

from audio.lead import GAIN, MOST_STRETCH, UNSEEN, Lead
from audio import resilient
from audio.resilient import ResilientOutput
from creatures.clock import SimulatedClock
from creatures.runtime.live import AUDIO_BUFFER
from tests.test_audio_faults import BLOCK, RATE, TICK, FakeCard

LEAD = 0.03
STEP = 0.001  # the simulation's resolution: the device runs, and writes fall, on this grid


def show(seconds: float, *, ppm: float = 0.0, stalls: tuple[float, ...] = (), first_write: float = 0.1,
         seed: int = 0, late_once: tuple[float, float] = (np.inf, 0.0)) -> tuple[ResilientOutput, dict[str, float]]:
    """A live run's writes (one tick's mix a tick, up to 3 ms late; the first due after
    ``late_once[0]`` s, ``late_once[1]`` s late) into a card twice the mix's rate whose clock
    is ``ppm`` fast (negative: slow) and that loses 40 ms at each time in ``stalls``. Returns
    the output and what was counted after the first second."""
    rng = np.random.default_rng(seed)
    clock = SimulatedClock()
    card = FakeCard(clock, rate=2 * RATE, gone=(np.inf, np.inf))
    out = ResilientOutput(RATE, 2, clock=clock, backend=card, blocksize=BLOCK, lead=LEAD, buffer_seconds=AUDIO_BUFFER)
    stream = card.streams[0]
    tone = (0.5 * np.sin(np.arange(int(seconds * RATE) + RATE) * 0.05)).astype(np.float32)
    written, next_write, late = 0, first_write, rng.uniform(0, 0.003)
    after_first: dict[str, float] = {}
    lowest_spare, highest_spare = np.inf, 0.0
    for step in range(1, int(round(seconds / STEP)) + 1):
        t = clock.advance_to(round(step * STEP, 6))
        if any(abs(t - at) < STEP / 2 for at in stalls):
            stream._due -= 0.04 * card.rate  # 40 ms of the device's time lost, never made up
        card.run(STEP * (1 + ppm * 1e-6))
        if t >= next_write + late:
            frames = int(round((next_write - first_write) * RATE)) - written  # the first tick: none
            out.write(np.repeat(tone[written:written + frames, None], 2, axis=1))
            written += frames
            next_write += TICK
            late = rng.uniform(0, 0.003)
            if next_write >= late_once[0]:
                late, late_once = late_once[1], (np.inf, 0.0)
            if t > 1.0:
                lowest_spare = min(lowest_spare, stream_spare(out))
                highest_spare = max(highest_spare, stream_spare(out))
        if t >= 1.0 and not after_first:
            after_first = {"underruns": out.underruns, "gaps": out.gaps}
    return out, {"underruns": out.underruns - after_first["underruns"], "gaps": out.gaps - after_first["gaps"],
                 "lowest spare": lowest_spare / card.rate, "highest spare": highest_spare / card.rate,
                 "overruns": out.overruns}


def stream_spare(out: ResilientOutput) -> float:
    """Frames queued for the device just after a write."""
    live = out.watch.stream
    return live.ring.available() / live.channels


@pytest.mark.parametrize("ppm", [0.0, 500.0, -500.0])
def test_nothing_underruns_after_the_first_second_whichever_way_the_device_clock_drifts(ppm):
    out, after = show(60.0, ppm=ppm)
    assert after["underruns"] == 0 and after["gaps"] == 0 and after["overruns"] == 0, after
    assert out.gaps >= 1  # the start: the device played before the first mix came, and the lead was put in then
    # 500 ppm is 30 ms in the minute, the whole lead: the resampler runs that much faster or slower
    assert out.keeper.stretch == pytest.approx(1 + ppm * 1e-6, abs=2e-4)
    assert LEAD / 3 < after["lowest spare"] and after["highest spare"] < 2 * LEAD + TICK + BLOCK / RATE, after


def test_a_write_late_but_within_the_lead_plays_whole_with_no_gap_put_in(monkeypatch):
    # 24 ms late in a 30 ms lead: the device still had sound
    out, after = show(20.0, late_once=(10.0, 0.024))
    assert after["underruns"] == 0 and after["gaps"] == 0 and after["overruns"] == 0, after
    # a floor at a third of the lead (as shipped before stop 28) put a gap in where nothing was missing
    with monkeypatch.context() as old:
        old.setattr(resilient, "GAP_FLOOR", int(LEAD * 2 * RATE) // 3)
        assert show(20.0, late_once=(10.0, 0.024))[1]["gaps"] == 1
    out, after = show(20.0, late_once=(10.0, 0.06))  # later than the lead: the device ran dry
    assert after["underruns"] >= 1 and after["gaps"] == 1, after


def test_a_device_that_loses_time_gives_it_back_by_resampling_not_as_latency():
    out, after = show(40.0, stalls=(5.0, 6.0, 7.0))  # 120 ms lost: it would stay as latency
    assert after["underruns"] == 0 and after["gaps"] == 0 and after["overruns"] == 0, after
    assert after["highest spare"] > 0.1  # just after the stalls
    assert stream_spare(out) / out.device_rate < 2 * LEAD + TICK + BLOCK / RATE  # given back by the end


def test_a_device_that_stalls_at_its_start_has_the_surplus_left_out_at_once():
    # JACK's dummy server on a loaded machine: one callback, then none for 423 ms while ticks came
    out, after = show(10.0, stalls=tuple(0.02 + STEP * k for k in range(0, 400, 40)))
    assert after["underruns"] == 0 and after["gaps"] == 0 and after["overruns"] == 0, after
    assert out.skips == 1 and out.keeper.skipped > 0.2 * out.device_rate  # the rest is eased away
    assert stream_spare(out) / out.device_rate < 2 * LEAD + TICK + BLOCK / RATE


def test_a_write_later_than_the_lead_is_a_counted_gap_and_the_lead_is_put_back():
    keeper = Lead(target=300, floor=100, window=1000)
    assert keeper.correct(UNSEEN, 160) == 0  # no callback yet: nothing to correct
    assert keeper.correct(-64, 160) == 364  # the device played silence: the lead goes ahead of this block
    assert (keeper.gaps, keeper.silence) == (1, 364)
    assert keeper.correct(250, 160) == 0 and keeper.stretch == 1.0  # near the target: left alone


def test_the_resampling_ratio_moves_once_a_window_by_part_of_the_mean_error_and_never_far():
    keeper = Lead(target=300, floor=100, window=100_000)
    keeper.correct(400, 50_000)
    assert keeper.stretch == 1.0  # the window is not over
    keeper.correct(500, 50_000)  # a mean 150 frames too many in 100 000: 1500 ppm, half of it corrected at once
    assert keeper.stretch == pytest.approx(1 - GAIN * 0.0015)
    keeper.correct(150, 100_000)  # too few: faster, by this window's error alone
    assert keeper.stretch == pytest.approx(1 + GAIN * 0.0015)
    keeper.correct(-1_000, 100_000)  # an underrun is a gap, not a jump of the ratio
    assert keeper.stretch == pytest.approx(1 + GAIN * 0.0015) and keeper.gaps == 1
    keeper.correct(100_000, 100_000)
    assert keeper.stretch == 1 - MOST_STRETCH
    keeper = Lead(target=300, floor=100, window=1000)
    assert [keeper.correct(1300, 500) for _ in range(4)] == [0, -500, -500, 0]  # 1000 too many: left out
    assert (keeper.skips, keeper.skipped) == (1, 1000)
    with pytest.raises(ValueError):
        Lead(target=100, floor=100, window=10)
