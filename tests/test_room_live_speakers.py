"""A room's speaker layout on the live path (issue 21, "for out.wav and live output"): a live run
(``creatures run``) of a ring of four opens four output ports on JACK, and a JACK client of the
test's own, recording them, hears the creature east of the listener on speaker 0 alone; a run
with the default dome opens its thirteen, and what each carries is the dome's 3-D VBAP gain
for where the creature stands (east, and high, since nearer the listener sounds higher).

Needs a JACK server with at least as many playback ports as speakers (CI starts the dummy one
with 16: ``jackd --no-realtime -d dummy -r 44100 -p 512 -P 16``); skips with the reason otherwise."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import textwrap

import numpy as np
import pytest
from test_room_stage import HEADER, caller

from bench.live_hearing import jack_available
from creatures.room.speakers import DOME, Dome

SECONDS = 3.0
"""Recorded once the run is up."""


LAYOUTS = {"ring": ('speakers = "ring"\nchannels = 4', 4), "dome": ('speakers = "dome"', len(DOME))}
"""Each layout's [room] lines and its speakers."""


def layout_config(tmp_path, layout: str) -> str:
    path = tmp_path / f"{layout}.toml"
    path.write_text(textwrap.dedent(HEADER.format(room=LAYOUTS[layout][0])
                                    + caller("east", 9.0, 5.0, "max_speed = 0.01")))
    return str(path)


def expected(layout: str) -> np.ndarray:
    """What each speaker should carry of the creature 4 m east of the listener (5, 5): speaker 0
    of the ring alone; over the dome, its VBAP gains at azimuth 0 and the elevation the floor
    maps to (90° × (1 − 4 m / the farthest corner's 7.07 m))."""
    if layout == "ring":
        return np.eye(4)[0]
    return Dome(DOME).gains(0.0, 90.0 * (1.0 - 4.0 / np.hypot(5.0, 5.0)))[0]


@pytest.mark.jack
@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_a_live_speaker_layout_sounds_on_its_jack_ports_panned_by_place(tmp_path, layout):
    why = jack_available()
    if why:
        pytest.skip(why)
    import jack

    count = LAYOUTS[layout][1]
    probe = jack.Client(f"speakers-probe-{os.getpid()}", no_start_server=True)
    if len(probe.get_ports("system:playback", is_audio=True)) < count:
        probe.close()
        pytest.skip(f"the JACK server has fewer than {count} playback ports (start it with -P 16)")
    inputs = [probe.inports.register(f"in_{k}") for k in range(count)]
    frames = int(SECONDS * probe.samplerate)
    recorded = np.zeros((count, frames), np.float32)
    state = {"at": 0, "on": False}
    full = threading.Event()

    @probe.set_process_callback
    def process(block: int) -> None:
        if not state["on"] or full.is_set():
            return
        n = min(block, frames - state["at"])
        for k, port in enumerate(inputs):
            recorded[k, state["at"]:state["at"] + n] = port.get_array()[:n]
        state["at"] += n
        if state["at"] >= frames:
            full.set()

    before = {p.name for p in probe.get_ports(is_audio=True, is_output=True)}
    colony = subprocess.Popen([sys.executable, "-m", "creatures.cli", "run", layout_config(tmp_path, layout),
                               "--duration", "30",
                               "--out", str(tmp_path / "out")], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        with probe:
            lines = []
            for line in colony.stdout:
                lines.append(line)
                if "running; Ctrl-C" in line:
                    break
            ours = sorted((p for p in probe.get_ports(is_audio=True, is_output=True) if p.name not in before),
                          key=lambda p: (len(p.name), p.name))
            assert len(ours) == count, ("".join(lines), [p.name for p in ours])
            for port, mine in zip(ours, inputs):
                probe.connect(port, mine)
            state["on"] = True
            assert full.wait(SECONDS + 20), "the recording did not fill"
    finally:
        colony.terminate()
        output = colony.communicate(timeout=60)[0]
    assert colony.returncode == 0, "".join(lines) + output
    rms = np.sqrt((recorded.astype(float) ** 2).mean(axis=1))
    want = expected(layout)
    assert rms.max() > 0.001, rms
    silent = want < 1e-6
    assert silent.any() and rms[silent].max() < rms.max() / 20, (rms, want)  # the others carry nothing of it
    np.testing.assert_allclose(rms[~silent] / rms.max(), want[~silent] / want.max(), atol=0.1)  # in the VBAP ratio
