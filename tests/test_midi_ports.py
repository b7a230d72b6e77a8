"""Ports: in-memory pairs, lookup by name or pattern, devices that vanish and come back, and
virtual ports on a real backend (JACK here; ALSA where the kernel has it)."""

from __future__ import annotations

import os
import threading
import time

import mido
import numpy as np
import pytest
from mido.ports import BaseInput, BaseOutput

from midi.ports import MidoInputs, MidoOutputs, ResilientPort, match_port, memory_pair
from midi.sinks import PortSink


class FakePort(BaseInput, BaseOutput):
    """A device port that raises once its cable is pulled, as backends do."""

    def __init__(self, name: str, backend: FakeBackend) -> None:
        self.backend = backend
        super().__init__(name)

    def _receive(self, block: bool = True) -> None:
        if not self.backend.present:
            raise OSError("device disconnected")
        self._messages.extend(self.backend.queued)
        self.backend.queued.clear()

    def _send(self, msg: mido.Message) -> None:
        if not self.backend.present:
            raise OSError("device disconnected")
        self.backend.sent.append(msg)


class FakeBackend:
    """A port factory whose one device can be unplugged and plugged back in."""

    def __init__(self, name: str = "Fake Synth MIDI 1 20:0") -> None:
        self.name = name
        self.present = True
        self.raises = True  # whether an unplugged port raises, or only drops off the list
        self.listed = 0
        self.opened = 0
        self.queued: list[mido.Message] = []
        self.sent: list[mido.Message] = []

    def names(self) -> list[str]:
        self.listed += 1
        return ["Midi Through Port-0", self.name] if self.present else ["Midi Through Port-0"]

    def open(self, name: str, *, virtual: bool = False) -> FakePort:
        if not self.present:
            raise OSError(f"no such port {name!r}")
        self.opened += 1
        return FakePort(name, self.backend_view())

    def backend_view(self) -> FakeBackend:
        return self if self.raises else _Quiet(self)


class _Quiet:
    """The same device, but its port stays silent when unplugged instead of raising."""

    def __init__(self, backend: FakeBackend) -> None:
        self._backend = backend

    present = property(lambda self: True)
    queued = property(lambda self: self._backend.queued if self._backend.present else [])
    sent = property(lambda self: self._backend.sent)


def test_match_port_by_exact_name_regex_or_substring():
    names = ["Midi Through Port-0", "Fake Synth MIDI 1 20:0", "Fake Synth MIDI 2 20:1", "USB [Keys 24:0"]
    assert match_port(names, "Fake Synth MIDI 2 20:1") == names[2]
    assert match_port(names, r"synth midi \d 20:1") == names[2]
    assert match_port(names, "MIDI 1 20:0") == names[1]
    assert match_port(names, "[keys") == names[3]  # not a valid regex: a substring
    assert match_port(names, "Nope") is None


def test_memory_pair_needs_no_backend(clock):
    inport, outport = memory_pair("creature")
    for pitch in (60, 64, 67):
        PortSink(outport).send(0.0, mido.Message("note_on", note=pitch))
    assert [m.note for m in inport.iter_pending()] == [60, 64, 67]
    assert list(inport.iter_pending()) == []  # non-blocking when empty


@pytest.mark.parametrize("raises", [True, False], ids=["port-raises", "port-goes-quiet"])
def test_vanishing_port_is_reported_once_and_reopened(clock, raises):
    backend = FakeBackend()
    backend.raises = raises
    reports: list[str] = []
    port = ResilientPort(r"fake synth midi 1", backend, clock, retry_interval=0.5, report=reports.append)
    assert port.connected and reports == []
    backend.queued.append(mido.Message("note_on", note=60))
    assert [m.note for m in port.pending()] == [60]

    backend.present = False
    listed = backend.listed
    for _ in range(1000):  # 10 s of simulated time at 100 polls/s
        clock.advance(0.01)
        assert port.pending() == []
        port.send(mido.Message("note_on", note=61))  # dropped, counted, never raises
    assert len(reports) == 1 and "lost" in reports[0] and port.faults == 1
    assert backend.listed - listed <= 10 / 0.5 + 1  # device listing at a bounded rate
    # A port that goes quiet is noticed at the next listing, within one retry interval.
    assert port.dropped >= 1000 - (0 if raises else 0.5 / 0.01 + 1)

    backend.present = True
    clock.advance(0.5)
    port.pending()
    assert port.connected and port.reopened == 1
    assert len(reports) == 2 and "is back" in reports[1]
    backend.queued.append(mido.Message("note_on", note=62))
    assert [m.note for m in port.pending()] == [62]
    assert port.send(mido.Message("note_on", note=63)) and backend.sent[-1].note == 63


def test_port_absent_at_start_is_reported_once_and_opened_when_it_appears(clock):
    backend = FakeBackend()
    backend.present = False
    reports: list[str] = []
    port = ResilientPort("Fake Synth", backend, clock, retry_interval=1.0, report=reports.append)
    for _ in range(50):
        clock.advance(0.1)
        port.pending()
    assert not port.connected and len(reports) == 1 and "not found" in reports[0]
    backend.present = True
    clock.advance(1.0)
    port.pending()
    assert port.connected and backend.opened == 1 and "is back" in reports[-1]


def _jack_backend() -> mido.Backend:
    os.environ.setdefault("JACK_NO_START_SERVER", "1")  # never spawn a server from a test
    backend = mido.Backend("mido.backends.rtmidi/UNIX_JACK", load=True)
    try:
        backend.get_input_names()
    except Exception as exc:  # rtmidi raises its own SystemError when no server runs
        pytest.skip(f"no JACK server running ({exc}); start one with "
                    "`jackd --no-realtime -d dummy -r 44100 -p 512 &`")
    return backend


def _receive_all(port: BaseInput | ResilientPort, n: int, timeout: float = 5.0) -> list[mido.Message]:
    """Up to ``n`` messages from ``port``, read without blocking as the live run reads its
    input (``ResilientPort.pending``), or from a plain port's ``iter_pending``."""
    got: list[mido.Message] = []
    deadline = time.monotonic() + timeout
    while len(got) < n and time.monotonic() < deadline:
        got += port.pending() if isinstance(port, ResilientPort) else list(port.iter_pending())
        time.sleep(0.001)  # yield to the backend thread; the deadline bounds the wait
    return got


@pytest.mark.jack
def test_jack_virtual_ports_loop_100_messages(clock):
    backend = _jack_backend()
    inputs, outputs = MidoInputs(backend), MidoOutputs(backend)
    ear = inputs.open("creature-ear", virtual=True)  # others play into it
    voice = outputs.open("creature-voice", virtual=True)  # others listen to it
    player = outputs.open(match_port(outputs.names(), r"creature-ear$"))
    listener = ResilientPort(match_port(inputs.names(), r"creature-voice$"), inputs, clock)
    try:
        sent = [mido.Message("note_on", note=i % 128, velocity=1 + i % 127) for i in range(100)]
        for msg in sent:
            player.send(msg)
        heard = _receive_all(ear, 100)
        for msg in heard:  # the creature answers each note, transposed up a fifth
            voice.send(msg.copy(note=(msg.note + 7) % 128))
        echoed = _receive_all(listener, 100)
    finally:
        for port in (ear, voice, player, listener):
            port.close()
    assert heard == sent
    assert echoed == [m.copy(note=(m.note + 7) % 128) for m in sent]



@pytest.mark.jack
def test_jack_input_keeps_every_note_while_python_is_busy(clock):
    """The creature's thread may hold the GIL for a second (a GC pass, a numba compile). No
    Python runs on JACK's thread, so the graph does not stall and no stale buffer is re-read:
    a 100-note burst arrives whole, in order (mido's callback input got 50 distinct of 100)."""
    backend = _jack_backend()
    inputs, outputs = MidoInputs(backend), MidoOutputs(backend)
    voice = outputs.open("creature-busy", virtual=True)
    listener = ResilientPort(match_port(inputs.names(), r"creature-busy$"), inputs, clock)
    floats = np.random.default_rng(0).random(4_000_000).tolist()
    busy = threading.Thread(target=sorted, args=(floats,))  # list sorting never releases the GIL
    sent = [mido.Message("note_on", note=i % 128, velocity=1 + i % 127) for i in range(100)]
    try:
        # The connection is made in JACK's graph at a cycle's edge: on a loaded machine notes sent
        # at once could go before it (CI, 2026-12-06: the first 50 lost, the last 50 whole). One
        # note heard first shows the connection live; the burst is what is tested.
        voice.send(mido.Message("control_change", control=123, value=0))
        assert _receive_all(listener, 1) == [mido.Message("control_change", control=123, value=0)]
        for i, msg in enumerate(sent):
            voice.send(msg)
            if i == 49:
                busy.start()
        busy.join()
        heard = _receive_all(listener, 100)
    finally:
        voice.close()
        listener.close()
    assert heard == sent

def test_alsa_sequencer_virtual_port(clock):
    if not os.path.exists("/dev/snd/seq"):
        reason = "no ALSA sequencer (/dev/snd/seq absent): ALSA virtual MIDI ports cannot exist here"
        print(reason)
        pytest.skip(reason)
    backend = mido.Backend("mido.backends.rtmidi/LINUX_ALSA", load=True)
    inputs, outputs = MidoInputs(backend), MidoOutputs(backend)
    ear = inputs.open("creature-alsa", virtual=True)  # a player connects to it
    player = outputs.open(match_port(outputs.names(), "creature-alsa"))
    try:
        player.send(mido.Message("note_on", note=60))
        heard = _receive_all(ear, 1)
    finally:
        player.close()
        ear.close()
    assert heard == [mido.Message("note_on", note=60)]


@pytest.mark.skipif(os.path.exists("/dev/snd/seq"), reason="an ALSA sequencer here: libasound has nothing to complain of")
def test_without_a_sequencer_the_devices_listing_says_why_once_and_libasound_says_nothing(tmp_path):
    """libasound prints its own line for a missing /dev/snd/seq below any Python; the run's
    stderr would repeat it at every port lookup. Only our sentence, with what to do, remains."""
    import ctypes.util
    import subprocess
    import sys

    if ctypes.util.find_library("asound") is None:
        pytest.skip("no libasound here")
    run = subprocess.run([sys.executable, "-m", "creatures.cli", "devices"], capture_output=True, text=True)
    assert run.returncode == 0 and "MIDI devices: unavailable" in run.stdout and "JACK" in run.stdout
    assert "ALSA lib" not in run.stderr, run.stderr
