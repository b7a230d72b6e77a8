"""Live hearing latency through JACK: an onset played into the run's microphone → the creature's
answering note leaving its MIDI output, measured on JACK's own frame clock.

A probe JACK client plays tones (one every ``gap`` seconds, pitches cycling through an octave)
from its audio output into the input ports of a ``creatures run`` started as a subprocess, and
receives that run's MIDI output on its MIDI input. The run is one exchange creature that
answers every heard note at once (``answer = 1``, no refractory). Both the onset (the frame the
tone starts in the probe's output buffer) and the note-on (its frame in the probe's input
buffer) are read in the same process callback, so the latency is a difference of JACK frame
times: what the audience would hear between a performer's attack and the creature's note.

``python -m bench live_hearing`` (needs a JACK server and the ``JACK-Client`` package).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from bench import Row
from bench._peers import skipped

CONFIG = """title = "hearing latency"
tick = 0.01
[audio]
sample_rate = 22050
block = 512
input_device = "system"
look = "{look}"
[midi]
output_port = "{port}"
[[creature]]
name = "ada"
kind = "exchange"
space.answer = 1.0
space.refractory = 0.0
space.strike_interval = 0.0
"""


NOTE_ON, POLY_PRESSURE = 0x90, 0xA0
"""The status nibbles that count as an answer."""

RUN_CLIENT = "PortAudio"
"""The JACK client name of the run's microphone (PortAudio's): on a shared JACK server, other
programs' new input ports (a parallel run's listener) must not be taken for the run's."""


def jack_available() -> str | None:
    """None if a JACK server answers and the client package is installed, else why not."""
    try:
        import jack
    except ImportError:
        return "the JACK-Client package is not installed (pip install JACK-Client)"
    try:
        jack.Client(f"hearing-check-{os.getpid()}", no_start_server=True).close()
    except jack.JackError as exc:
        return f"no JACK server ({exc}); start one: jackd --no-realtime -d dummy -r 44100 -p 512"
    return None


def tone(pitch: int, rate: int, seconds: float = 0.3) -> np.ndarray:
    """A plucked harmonic tone: instant attack, exponential decay, faded out at the end."""
    t = np.arange(int(seconds * rate)) / rate
    f0 = 440.0 * 2 ** ((pitch - 69) / 12)
    x = sum(np.sin(2 * np.pi * k * f0 * t) / k for k in range(1, 6) if k * f0 < rate / 2)
    return (0.2 * x * np.exp(-6 * t) * np.minimum(1.0, (seconds - t) / 0.02)).astype(np.float32)


class Heard(NamedTuple):
    """What one :func:`measure` found."""

    latencies: list[float]
    """Seconds from each answered onset to the creature's first answer after it (before the next onset)."""
    unanswered: list[int]
    """The indices of the onsets that went unanswered."""
    output: str
    """What the run printed."""

    @property
    def played(self) -> int:
        """Onsets played: each was answered or not."""
        return len(self.latencies) + len(self.unanswered)

    def summary(self) -> str:
        if not self.latencies:
            return f"answered 0/{self.played}"
        ms = 1e3 * np.array(self.latencies)
        missed = f"; unanswered onsets {self.unanswered}" if self.unanswered else ""
        return (f"answered {len(ms)}/{self.played}; onset → answer p50 {np.median(ms):.1f} ms, "
                f"p99 {np.percentile(ms, 99):.1f} ms{missed}")


def _ready(notify: socket.socket, deadline: float, run: subprocess.Popen) -> bool:
    """Whether the run sent ``READY=1`` on ``notify`` before ``deadline`` (and before it ended)."""
    while time.monotonic() < deadline and run.poll() is None:
        try:
            if b"READY=1" in notify.recv(4096).split(b"\n"):
                return True
        except TimeoutError:
            continue
    return False


def measure(onsets: int = 40, gap: float = 0.5, *, warm_up: float = 2.0, timeout: float = 90.0,
            log: Path | None = None, look: str = "live") -> Heard:
    """Play ``onsets`` tones ``gap`` seconds apart into a run and time its answers (:class:`Heard`).
    The first is played ``warm_up`` seconds after the run says ``READY=1`` (systemd's protocol,
    ``creatures/runtime/sd_notify.py``: its creatures built, devices open, first tick played),
    for its first buffers to fill; a fixed 6 s from its microphone's appearing was not enough on
    a slow machine (a run still starting lost the first two onsets); ``look``: the run's
    ``[audio] look``.

    An answer is a note-on or a polyphonic pressure: the exchange's rule two (thesis "exchange
    (installation)") strikes a note that still sounds by perturbing it, not by playing it again,
    so a tone whose pitch the wandering hand has just struck is answered with pressure."""
    import jack

    name = f"hearing-probe-{os.getpid()}"
    client = jack.Client(name, no_start_server=True)
    out = client.outports.register("out")
    midi_in = client.midi_inports.register("in")
    rate = client.samplerate
    tones = [tone(60 + (k * 5) % 12, rate) for k in range(onsets)]
    start_frames: list[int] = []
    answer_frames: list[int] = []
    state = {"next": None, "k": 0, "playing": None, "pos": 0}

    @client.set_process_callback
    def process(frames: int) -> None:
        buf = out.get_array()
        buf[:] = 0.0
        now = client.last_frame_time
        for offset, data in midi_in.incoming_midi_events():
            data = bytes(data)
            if len(data) == 3 and data[0] & 0xF0 in (NOTE_ON, POLY_PRESSURE) and data[2] > 0:
                answer_frames.append(now + offset)
        if state["next"] is None:
            return
        i = 0
        while i < frames:
            if state["playing"] is None:
                if state["k"] >= onsets:
                    break
                begin = state["next"] - now
                if begin >= frames:
                    break
                i = max(i, begin)
                state["playing"], state["pos"] = tones[state["k"]], 0
                start_frames.append(now + i)
                state["k"] += 1
                state["next"] += int(gap * rate)
            x = state["playing"]
            n = min(frames - i, len(x) - state["pos"])
            buf[i:i + n] = x[state["pos"]:state["pos"] + n]
            state["pos"] += n
            i += n
            if state["pos"] >= len(x):
                state["playing"] = None

    with tempfile.TemporaryDirectory() as tmp, client:
        before = set(p.name for p in client.get_ports(is_audio=True, is_input=True))
        config = Path(tmp) / "latency.toml"
        config.write_text(CONFIG.format(port=name, look=look))
        notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        notify.bind(str(Path(tmp) / "notify"))
        notify.settimeout(0.05)
        env = {**os.environ, "MIDO_BACKEND": "mido.backends.rtmidi/UNIX_JACK", "JACK_NO_START_SERVER": "1",
               "NOTIFY_SOCKET": str(Path(tmp) / "notify")}
        # The probe stops the run once its last onset's answer window has passed on JACK's clock;
        # ``--duration`` is only a net should the probe die. A duration sized to the onsets ended a
        # run before its last onset on a loaded machine, where JACK's dummy driver (one period
        # per cycle, late cycles not caught up) counts frames slower than the run's wall clock.
        run = subprocess.Popen([sys.executable, "-m", "creatures.cli", "run", str(config), "--duration",
                                str(timeout)] + (["--log", str(log)] if log else []), env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        output: list[str] = []
        reader = threading.Thread(target=lambda: output.extend(run.stdout), daemon=True)
        reader.start()
        try:
            deadline = time.monotonic() + timeout
            ears: list[str] = []
            while not ears and time.monotonic() < deadline and run.poll() is None:
                ears = [p.name for p in client.get_ports(is_audio=True, is_input=True)
                        if p.name not in before and p.name.startswith(RUN_CLIENT)]
                time.sleep(0.05)
            if not ears:
                raise RuntimeError("the run's microphone never appeared on JACK:\n" + "".join(output))
            for port in ears:
                client.connect(out, port)
            if not _ready(notify, deadline, run):
                raise RuntimeError("the run never said READY=1:\n" + "".join(output))
            time.sleep(warm_up)  # its first buffers fill
            state["next"] = client.frame_time + rate // 10
            while time.monotonic() < deadline and (state["k"] < onsets
                                                    or client.frame_time < start_frames[-1] + int(gap * rate)):
                time.sleep(0.05)
        finally:
            notify.close()
            run.terminate()
            run.wait(timeout=20)
            reader.join(timeout=5)
    latencies, unanswered = [], []
    for k, start in enumerate(start_frames):
        end = start_frames[k + 1] if k + 1 < len(start_frames) else start + int(gap * rate)
        after = [f for f in answer_frames if start <= f < end]
        if after:
            latencies.append((after[0] - start) / rate)
        else:
            unanswered.append(k)
    return Heard(latencies, unanswered, "".join(output))


def run(quick: bool) -> list[Row]:
    why = jack_available()
    if why is not None:
        return [skipped("live onset → answer", why)]
    rows = []
    for look in ("live", "quick"):  # the quick look is the one made for the 30 ms
        heard = measure(20 if quick else 60, look=look)
        if not heard.latencies:
            # no latency to give: the row fails instead of printing a time nothing took
            rows.append(Row(f"{look} look: onsets answered (none of {heard.played})", 0.0, "onsets", target=1.0))
            continue
        ms = 1e3 * np.array(heard.latencies)
        rows += [
            Row(f"{look} look: onset → answering MIDI note, p50 ({len(ms)}/{heard.played} answered)",
                float(np.median(ms)), "ms", higher_is_better=False),
            Row(f"{look} look: onset → answering MIDI note, p99 (through JACK)", float(np.percentile(ms, 99)), "ms",
                target=30.0 if look == "quick" else None, higher_is_better=False),
        ]
    return rows
