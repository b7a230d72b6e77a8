"""A room's speaker layout on the live path (issue 21, "for out.wav and live output"): a live run
(``creatures run``) of a ring of four opens four output ports on JACK, and a JACK client of the
test's own, recording them, hears the creature east of the listener on speaker 0 alone.

Needs a JACK server with at least four playback ports (CI starts the dummy one with 16:
``jackd --no-realtime -d dummy -r 44100 -p 512 -P 16``); skips with the reason otherwise."""

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

SECONDS = 3.0
"""Recorded once the run is up."""


def ring_config(tmp_path) -> str:
    path = tmp_path / "ring.toml"
    path.write_text(textwrap.dedent(HEADER.format(room='speakers = "ring"\nchannels = 4')
                                    + caller("east", 9.0, 5.0, "max_speed = 0.01")))
    return str(path)


@pytest.mark.jack
def test_a_live_ring_of_four_sounds_on_four_jack_ports_panned_by_place(tmp_path):
    why = jack_available()
    if why:
        pytest.skip(why)
    import jack

    probe = jack.Client(f"speakers-probe-{os.getpid()}", no_start_server=True)
    if len(probe.get_ports("system:playback", is_audio=True)) < 4:
        probe.close()
        pytest.skip("the JACK server has fewer than four playback ports (start it with -P 16)")
    inputs = [probe.inports.register(f"in_{k}") for k in range(4)]
    frames = int(SECONDS * probe.samplerate)
    recorded = np.zeros((4, frames), np.float32)
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
    colony = subprocess.Popen([sys.executable, "-m", "creatures.cli", "run", ring_config(tmp_path), "--duration", "30",
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
            assert len(ours) == 4, ("".join(lines), [p.name for p in ours])
            for port, mine in zip(ours, inputs):
                probe.connect(port, mine)
            state["on"] = True
            assert full.wait(SECONDS + 20), "the recording did not fill"
    finally:
        colony.terminate()
        output = colony.communicate(timeout=60)[0]
    assert colony.returncode == 0, "".join(lines) + output
    rms = np.sqrt((recorded.astype(float) ** 2).mean(axis=1))
    assert rms[0] > 0.001, rms  # speaker 0 at azimuth 0 (+x, east of the listener) carries it
    assert rms[0] > 20 * rms[1:].max(), rms
