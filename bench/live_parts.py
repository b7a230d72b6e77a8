"""The real parts of a live show, for the live benchmark (bench/live.py) and the live test: fluidsynth on JACK
as the colony's synth, a JACK client that listens to fluidsynth's audio, and a foreign OSC
sender (python-osc's client in its own process, not this project's code).

Everything started here is stopped here; JACK itself must already run (CI starts the dummy
server). Client names carry the process id so parallel runs never collide.
"""

from __future__ import annotations

import json
import os
import random
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

SOUNDFONT = Path("/usr/share/sounds/sf2/FluidR3_GM.sf2")


def missing_parts() -> str | None:
    """Why the real parts cannot run here, or None."""
    if shutil.which("fluidsynth") is None:
        return "fluidsynth is not installed (apt-get install fluidsynth fluid-soundfont-gm)"
    if not SOUNDFONT.exists():
        return f"{SOUNDFONT} is missing (apt-get install fluid-soundfont-gm)"
    try:
        import jack
    except (ImportError, OSError) as exc:
        return f"JACK-Client is unusable ({exc}); pip install JACK-Client"
    try:
        jack.Client(f"creatures-probe-{os.getpid()}", no_start_server=True).close()
    except jack.JackError as exc:
        return f"no JACK server running ({exc}); start: jackd --no-realtime -d dummy -r 44100 -p 512 &"
    return None


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def free_listening_port(first: int = 20000, last: int = 32000) -> int:
    """A free TCP port for a server that a client polls before it listens.

    Below the kernel's ephemeral range on purpose: a client retrying ``connect`` to a port in
    that range can be given that same port as its own source and connect to itself (TCP's
    simultaneous open), and then the server finds its port taken. A CI run lost a test to it."""
    for candidate in random.Random().sample(range(first, last), 200):
        with socket.socket() as probe:
            try:
                probe.bind(("127.0.0.1", candidate))
            except OSError:
                continue
            return candidate
    raise OSError(f"no free TCP port in {first}-{last}")


class Synth:
    """``fluidsynth -a jack -m jack`` under a unique JACK name, and a JACK client that keeps the
    peak of each block of its audio (a Python process callback is fine here: this client is
    not the creatures' process)."""

    def __init__(self, tag: str) -> None:
        import jack

        self.name = f"{tag}{os.getpid()}"
        self.process = subprocess.Popen(
            ["fluidsynth", "-a", "jack", "-m", "jack", "-i", "-s", "-g", "0.8",
             "-o", f"midi.jack.id={self.name}", "-o", f"audio.jack.id={self.name}", str(SOUNDFONT)],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.client = jack.Client(f"{self.name}-ear", no_start_server=True)
        self.ears = [self.client.inports.register(f"in_{side}") for side in ("l", "r")]
        self.peaks = np.zeros(1 << 20, dtype=np.float32)
        self.blocks = 0
        self.client.set_process_callback(self._process)
        self.client.activate()
        deadline = time.monotonic() + 30.0
        while not self.client.get_ports(f"{self.name}:left"):
            if time.monotonic() > deadline or self.process.poll() is not None:
                self.close()
                raise RuntimeError(f"fluidsynth did not come up on JACK as {self.name}")
            time.sleep(0.1)
        for side, ear in zip(("left", "right"), self.ears):
            self.client.connect(f"{self.name}:{side}", ear)
        while not self.client.get_ports(f"{self.name}:midi", is_midi=True):
            time.sleep(0.1)

    @property
    def midi_port(self) -> str:
        """A pattern for the synth's MIDI input port (``<name>:midi_00``)."""
        return f"{self.name}:midi"

    def _process(self, frames: int) -> None:
        if self.blocks < len(self.peaks):
            self.peaks[self.blocks] = max(float(np.abs(ear.get_array()).max()) for ear in self.ears)
            self.blocks += 1

    def loud_blocks(self, since: int = 0, threshold: float = 1e-3) -> int:
        """Blocks since block ``since`` whose peak passed ``threshold`` (about -60 dBFS)."""
        return int((self.peaks[since:self.blocks] > threshold).sum())

    def close(self) -> None:
        try:
            self.client.deactivate()
            self.client.close()
        finally:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()


SENDER = r"""
import json, sys, time
from pythonosc.udp_client import SimpleUDPClient
port, count, rate, name = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
rewarded, reward_after = sys.argv[5], int(sys.argv[6])
client = SimpleUDPClient("127.0.0.1", port)
start = time.monotonic()
for i in range(count):
    while time.monotonic() < start + i / rate:
        time.sleep(0.0005)
    pitch, velocity = 48 + (i * 7) % 36, 60 + i % 60
    # Max's and TouchDesigner's defaults send floats; others send ints: both where the protocol allows.
    args = [pitch, velocity, 0.2] if i % 2 == 0 else [pitch, velocity, 1, i % 16]
    sent = time.time()  # before the send: an answer can reach the MIDI port before send_message returns
    client.send_message(f"/creature/{name}/note", args)
    print(json.dumps({"i": i, "pitch": pitch, "args": args, "sent": sent}), flush=True)
    if i == reward_after:  # the clicker: "/reward <creature> <amount>"
        client.send_message("/reward", [rewarded, 1.0])
        print(json.dumps({"reward": rewarded, "amount": 1.0, "sent": time.time()}), flush=True)
"""


def send_notes(port: int, count: int, rate: float, record: Path, name: str = "visitor",
               reward: tuple[str, int] | None = None) -> subprocess.Popen:
    """A foreign OSC sender (python-osc's client, its own process) sending ``count`` notes at
    ``rate`` a second to ``/creature/<name>/note``, and with ``reward = (creature, i)`` a
    clicker's ``/reward <creature> 1.0`` right after note ``i``; it writes one JSON line per
    message sent (with its Unix send time) to ``record`` (a file, not a pipe: a pipe nobody
    reads until the end fills and stops it)."""
    rewarded, after = reward or ("", -1)
    with open(record, "w") as out:
        return subprocess.Popen([sys.executable, "-c", SENDER, str(port), str(count), str(rate), name, rewarded,
                                 str(after)], stdout=out)


def sent_notes(sender: subprocess.Popen, record: Path, timeout: float) -> list[dict]:
    """What the sender sent, once it has finished (notes and rewards, in order)."""
    sender.wait(timeout)
    return [json.loads(line) for line in record.read_text().splitlines() if line.strip()]


def after_first_second(events: list[dict], tick: float) -> dict[str, int]:
    """The audio output's underruns, gaps and skips (audio/lead.py) after a live run's first
    second, from its events log: the counters are logged at the first tick and then once a
    second when they changed, so what the record just after the first second holds happened
    within it (the device's start)."""
    xruns = [e for e in events if e["kind"] == "xruns"]
    early = [e for e in xruns if e["t"] <= xruns[0]["t"] + 1.0 + 2 * tick][-1]
    return {key: xruns[-1][key] - early[key] for key in ("underruns", "gaps", "skips")}
