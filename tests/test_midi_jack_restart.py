"""A JACK server that dies under a run's MIDI output and comes back: the loss is said once, the
port is opened again on the new server, and a note sent afterwards arrives.

Before, the kept rtmidi client of the dead server still listed the old ports and took every
message, so the run said nothing, /health said connected, and nothing was ever sent again.

The run's side is a child process of its own: once a JACK server has died, libjack frees every
client of the process the next time one opens, so the scenario must share its libjack with no
other test's clients. Its server is named (``JACK_DEFAULT_SERVER``), started, killed and started
again by the child; the default server the other JACK tests use is never touched. The receiver
is ``jack_midi_dump`` (a real JACK client in its own process, as fluidsynth would be)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from creatures.clock import SimulatedClock
from midi.jack import JackPulse
from midi.ports import ResilientPort

ROOT = Path(__file__).resolve().parents[1]
RECEIVER = "midi-monitor:input"  # jack_midi_dump's port


class _Backend:
    """A pair of rtmidi clients looping through a server that can die, without JACK: what is
    sent comes back while ``up``, and never once the server ``died``."""

    def __init__(self) -> None:
        self.up = True
        self.stalled = False  # alive, but running no cycles (a loaded machine): nothing delivered yet
        self.opened = 0

    def pair(self):
        if not self.up:
            raise SystemError("MidiOutJack::initialize: JACK server not running?")
        self.opened += 1
        backend, generation, queue = self, self.opened, []

        class Out:
            def send_message(self, msg):
                if backend.up and backend.opened == generation:
                    queue.append(msg)

        class Ear:
            def get_message(self):
                return (queue.pop(0), 0.0) if queue and not backend.stalled else None

        return Out(), Ear()


def test_pulse_says_a_server_lost_after_two_pulses_missed_and_back_when_a_pair_opens():
    clock, server = SimulatedClock(), _Backend()
    pulse = JackPulse(patience=0.5, clock=clock.now)
    pulse._open_pair = server.pair
    assert pulse.alive() and pulse.alive()  # two ports looking at once: the pulse is on its way
    for _ in range(3):
        clock.advance(1.0)
        assert pulse.alive() and pulse.generation == 0  # each came back
    server.stalled = True  # a live server held up past a look: one pulse late is not a death
    clock.advance(1.0)
    assert pulse.alive() and pulse.generation == 0  # one missed, a second on its way
    server.stalled = False
    clock.advance(1.0)
    assert pulse.alive() and pulse.generation == 0  # both came back: the count starts again
    server.up = False
    clock.advance(1.0)
    assert pulse.alive()  # the last pulse came back before the server died; a new one goes out
    clock.advance(0.4)
    assert pulse.alive()  # not yet past patience
    clock.advance(0.6)
    assert pulse.alive() and pulse.generation == 0  # one missed: a second goes out
    clock.advance(1.0)
    assert not pulse.alive() and pulse.generation == 1  # two in a row: the server is gone
    clock.advance(1.0)
    assert not pulse.alive() and pulse.generation == 1  # no new pair while the server is away
    server.up = True
    clock.advance(1.0)
    assert pulse.alive() and pulse.generation == 1 and server.opened == 2


class _StalePorts:
    """A factory whose port goes stale with its server, as :class:`MidoOutputs` under JACK."""

    def __init__(self) -> None:
        self.generation = 0
        self.up = True
        self.closed = []

    def names(self) -> list[str]:
        if not self.up:
            raise OSError("the JACK server is not running")
        return ["synth:midi_in"]

    def open(self, name, *, virtual=False):
        from midi.ports import MemoryOutput

        port = MemoryOutput(name)
        port.jack_generation = self.generation
        port.close = lambda p=port: self.closed.append(p)  # closing a stale one would crash
        return port

    def stale(self, port) -> bool:
        return port.jack_generation != self.generation


def test_a_port_lost_with_its_server_is_said_once_abandoned_not_closed_and_reopened(clock):
    import mido

    factory, reports = _StalePorts(), []
    port = ResilientPort("synth", factory, clock, retry_interval=1.0, report=reports.append)
    first = port.port
    factory.up, factory.generation = False, 1  # the server died; the pulse said so
    for _ in range(3):
        clock.advance(1.0)
        assert not port.send(mido.Message("note_on"))
    assert reports == ["MIDI port 'synth:midi_in' lost (the JACK server is not running); "
                       "will reopen it when it returns"]
    assert (port.faults, port.dropped, factory.closed) == (1, 3, [])
    factory.up = True
    clock.advance(1.0)
    assert port.send(mido.Message("note_on"))
    second = port.port
    assert second is not first
    assert reports[-1] == "MIDI port 'synth:midi_in' is back" and port.reopened == 1
    port.close()
    assert factory.closed == [second]  # the live one closes as usual; the stale one never


class _Took:
    """An rtmidi client told no API, which took ``api``'s: RtMidi takes the first API that has
    ports, so JACK's where ALSA's sequencer offers none."""

    api = 0

    def __init__(self, rtapi: int, name: str) -> None:
        import rtmidi

        assert rtapi == rtmidi.API_UNSPECIFIED

    ports = ["synth:midi_in"]

    def get_current_api(self) -> int:
        return self.api

    def get_ports(self) -> list[str]:
        return list(self.ports)

    def get_port_count(self) -> int:
        return len(self.ports)


@pytest.mark.parametrize("took, ports", [("UNIX_JACK", ["synth:midi_in"]), ("LINUX_ALSA", ["synth:midi_in"]),
                                         ("UNIX_JACK", [])])
def test_rtmidi_told_no_api_is_watched_by_the_pulse_where_it_took_jack(monkeypatch, took, ports):
    """Where RtMidi took JACK's API for its ports, they are watched and opened as JACK's; ALSA's
    are not, nor is JACK's API kept only because no API had ports (no server, perhaps)."""
    import mido
    import rtmidi

    from midi.ports import MemoryOutput, MidoOutputs

    clock, server = SimulatedClock(), _Backend()
    pulse = JackPulse(patience=0.5, clock=clock.now)
    pulse._open_pair = server.pair
    monkeypatch.setattr(_Took, "api", getattr(rtmidi, f"API_{took}"))
    monkeypatch.setattr(_Took, "ports", ports)
    monkeypatch.setattr(rtmidi, "MidiOut", _Took)
    backend = mido.Backend("mido.backends.rtmidi", load=False)  # MIDO_BACKEND without an API
    opened_on = []
    monkeypatch.setattr(backend, "open_output",
                        lambda name, virtual=False, **api: opened_on.append(api) or MemoryOutput(name))
    outputs = MidoOutputs(backend, pulse=pulse)
    assert outputs.names() == ports
    port = outputs.open("synth:midi_in")
    server.up = False  # the server dies
    said = []
    for _ in range(4):
        clock.advance(1.0)
        try:
            said.append(outputs.names())
        except OSError as exc:
            said.append(str(exc))
    if took == "UNIX_JACK" and ports:
        assert said[-1] == "the JACK server is not running" and outputs.stale(port)
        assert opened_on == [{"api": "UNIX_JACK"}]  # its own client takes JACK's too, whatever ALSA has by then
    else:  # ALSA's ports are not JACK's, and no port at all says nothing: no pulse, nothing goes stale
        assert said == [ports] * 4 and not outputs.stale(port) and server.opened == 0 and opened_on == [{}]


class _Chooses:
    """An rtmidi client told no API, made as RtMidi makes one: on the first compiled API (ALSA's,
    then JACK's) that lists ports now, else on the last it tried. ``offered`` is what each API
    lists; a JACK client lists what its server had when it was made (one of a dead server
    still lists the old ports)."""

    offered: dict[str, list[str]] = {}

    def __init__(self, rtapi: int, name: str) -> None:
        import rtmidi

        assert rtapi == rtmidi.API_UNSPECIFIED
        self.api = next((api for api in ("LINUX_ALSA", "UNIX_JACK") if self.offered.get(api)), "UNIX_JACK")
        self.made_with = list(self.offered.get(self.api, []))

    def get_current_api(self) -> int:
        import rtmidi

        return getattr(rtmidi, f"API_{self.api}")

    def get_ports(self) -> list[str]:
        return list(self.offered.get("LINUX_ALSA", [])) if self.api == "LINUX_ALSA" else list(self.made_with)

    def get_port_count(self) -> int:
        return len(self.get_ports())


def test_rtmidi_told_no_api_chooses_again_when_the_jack_it_took_is_gone(monkeypatch, clock):
    """Told no API, RtMidi took JACK's (ALSA's sequencer had no port then); a USB synth is
    plugged into ALSA's and the JACK server goes. The port was looked for on JACK for ever
    ("the JACK server is not running"), the synth beside it unplayed; now RtMidi is asked
    again, takes ALSA's, and the port opens there. The lost JACK port is abandoned, not closed."""
    import mido
    import rtmidi

    from midi.ports import MemoryOutput, MidoOutputs

    server = _Backend()
    pulse = JackPulse(patience=0.5, clock=clock.now)
    pulse._open_pair = server.pair
    monkeypatch.setattr(_Chooses, "offered", {"LINUX_ALSA": [], "UNIX_JACK": ["fluidsynth:midi_in"]})
    monkeypatch.setattr(rtmidi, "MidiOut", _Chooses)
    backend = mido.Backend("mido.backends.rtmidi", load=False)  # MIDO_BACKEND without an API
    opened, closed = [], []

    def open_output(name, virtual=False, **api):
        port = MemoryOutput(name)
        port.close = lambda: closed.append(name)
        opened.append((name, api))
        return port

    monkeypatch.setattr(backend, "open_output", open_output)
    reports: list[str] = []
    port = ResilientPort("synth", MidoOutputs(backend, pulse=pulse), clock, retry_interval=1.0, report=reports.append)
    assert opened == [("fluidsynth:midi_in", {"api": "UNIX_JACK"})] and port.connected
    _Chooses.offered["LINUX_ALSA"] = ["USB synth:USB synth MIDI 1 20:0"]  # plugged in
    _Chooses.offered["UNIX_JACK"] = []
    server.up = False  # the JACK server goes
    for _ in range(5):
        clock.advance(1.0)
        port.send(mido.Message("note_on"))
    assert opened[1:] == [("USB synth:USB synth MIDI 1 20:0", {})]  # on ALSA's API, as RtMidi chose it
    assert port.connected and port.port.name == "USB synth:USB synth MIDI 1 20:0"
    assert reports == ["MIDI port 'fluidsynth:midi_in' lost (it is no longer listed); will reopen it when it returns",
                       "MIDI port 'USB synth:USB synth MIDI 1 20:0' is back"]
    assert closed == []  # the JACK port went with its server: abandoned, never closed


# --- the same with a real JACK server, in a child process ---------------------------------


def _wait(predicate, what: str, timeout: float = 10.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if result := predicate():
            return result
        time.sleep(0.02)  # polling a real process; the deadline bounds the wait
    raise AssertionError(f"timed out waiting for {what}")


class _Child:
    """The child's JACK server and its peer (a receiver, or a source): each a real process,
    started and stopped here. The peer's standard output goes to ``CREATURES_TEST_DUMP``."""

    def __init__(self, server: str, peer: list[str], port: str) -> None:
        self.server, self.peer, self.port = server, peer, port
        self.jackd: subprocess.Popen | None = None
        self.dump: subprocess.Popen | None = None
        self.heard = Path(os.environ["CREATURES_TEST_DUMP"])

    def start(self) -> None:
        self.jackd = subprocess.Popen(["jackd", "-n", self.server, "--no-realtime", "-d", "dummy", "-r", "44100",
                                       "-p", "512"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        subprocess.run(["jack_wait", "-w", "-t", "10"], check=True, capture_output=True)  # a process of its own
        self.heard.write_text("")
        self.dump = subprocess.Popen(self.peer, stdout=self.heard.open("a"), stderr=subprocess.DEVNULL)
        _wait(lambda: self.port in subprocess.run(["jack_lsp"], capture_output=True, text=True).stdout,
              f"the port {self.port}")

    def kill_server(self) -> None:
        self.jackd.send_signal(signal.SIGKILL)  # as a crash: no goodbye to the clients
        self.jackd.wait(timeout=10)
        self.dump.send_signal(signal.SIGTERM)  # the peer goes with its server
        self.dump.wait(timeout=10)

    def stop(self) -> None:
        for proc in (self.dump, self.jackd):  # SIGTERM: jackd then frees its name in JACK's registry
            if proc is not None and proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()

    def heard_notes(self) -> list[int]:
        """Pitches of the note-ons jack_midi_dump printed (``   0: 90 3c 64 note on ...``)."""
        return [int(line.split()[2], 16) for line in self.heard.read_text().splitlines() if "note on" in line]


def _looks(port: ResilientPort, clock: SimulatedClock, act, *, while_connected: bool) -> int:
    """The port's own checks, one simulated second apart, ``act`` at each, while it is (or is
    not) connected, five at most: how many it took."""
    looks = 0
    while port.connected == while_connected and looks < 5:
        clock.advance(1.0)
        act()
        looks += 1
    return looks


def _on(server: str) -> None:
    """This process's rtmidi clients on ``server``, never starting one of their own."""
    os.environ["JACK_DEFAULT_SERVER"] = server
    os.environ["JACK_NO_START_SERVER"] = "1"


def _watched(factory: type, pattern: str, clock: SimulatedClock, reports: list[str]) -> ResilientPort:
    """A :class:`ResilientPort` of ``factory`` (MidoInputs or MidoOutputs) on JACK, with a pulse
    of its own on the simulated clock."""
    import mido

    backend = mido.Backend("mido.backends.rtmidi/UNIX_JACK", load=True)
    return ResilientPort(pattern, factory(backend, pulse=JackPulse(clock=clock.now)), clock, retry_interval=1.0,
                         report=reports.append)


def _scenario(server: str) -> dict:
    """Run in the child: a ResilientPort to jack_midi_dump, the server killed and restarted."""
    import mido

    from midi.ports import MidoOutputs

    _on(server)
    child = _Child(server, ["stdbuf", "-oL", "jack_midi_dump"], RECEIVER)
    clock, reports, seen = SimulatedClock(), [], {}
    try:
        child.start()
        port = _watched(MidoOutputs, RECEIVER, clock, reports)
        seen["connected_at_start"] = port.connected
        port.send(mido.Message("note_on", note=60, velocity=100))
        seen["heard_before"] = _wait(child.heard_notes, "the first note")

        child.kill_server()
        seen["looks_to_loss"] = _looks(port, clock, lambda: port.send(mido.Message("note_on", note=61, velocity=100)),
                                       while_connected=True)
        seen["dropped"] = port.dropped
        seen["reports_while_down"] = list(reports)

        child.start()
        seen["looks_to_reconnect"] = _looks(port, clock, lambda: port.send(mido.Message("note_on", note=62, velocity=100)),
                                            while_connected=False)
        sent = port.send(mido.Message("note_on", note=63, velocity=100))
        seen["sent_after"] = sent
        try:
            _wait(lambda: 63 in child.heard_notes(), "the note sent after the restart", 5.0)
            seen["heard_after"] = True
        except AssertionError:
            seen["heard_after"] = False
        seen["reports"] = reports
        seen["faults"], seen["reopened"] = port.faults, port.reopened
        port.close()
    finally:
        child.stop()
    return seen


SOURCE = "creatures-seq:out"  # jack_midiseq's port


def _input_scenario(server: str) -> dict:
    """Run in the child: a ResilientPort listening to jack_midiseq (a real JACK client playing a
    note every quarter second), the server killed and restarted with it."""

    from midi.ports import MidoInputs

    _on(server)
    child = _Child(server, ["jack_midiseq", "creatures-seq", "11025", "0", "64", "2000"], SOURCE)
    clock, reports, seen = SimulatedClock(), [], {}

    def notes(port: ResilientPort) -> list[int]:
        return [m.note for m in port.pending() if m.type == "note_on" and m.velocity]

    try:
        child.start()
        port = _watched(MidoInputs, SOURCE, clock, reports)
        seen["connected_at_start"] = port.connected
        seen["heard_before"] = _wait(lambda: notes(port), "the sequencer's first note")

        child.kill_server()  # a poll of a client whose server died: nothing, and no exception
        seen["looks_to_loss"] = _looks(port, clock, port.pending, while_connected=True)
        seen["reports_while_down"] = list(reports)

        child.start()
        seen["looks_to_reconnect"] = _looks(port, clock, port.pending, while_connected=False)
        try:
            seen["heard_after"] = _wait(lambda: notes(port), "a note from the restarted sequencer", 5.0)
        except AssertionError:
            seen["heard_after"] = []
        seen["reports"] = reports
        seen["faults"], seen["reopened"] = port.faults, port.reopened
        port.close()
    finally:
        child.stop()
    return seen


def _in_a_child(scenario: str, tools: tuple[str, ...], tmp_path: Path) -> dict:
    """Run ``scenario`` of this file in a child process on a JACK server of its own; what it saw."""
    missing = [tool for tool in ("jackd", "jack_wait", "jack_lsp", *tools) if not shutil.which(tool)]
    if missing:
        pytest.skip(f"needs JACK's tools ({', '.join(missing)} not found; apt-get install jackd2)")
    server = f"creatures-test-{uuid.uuid4().hex[:8]}"
    env = dict(os.environ, CREATURES_TEST_DUMP=str(tmp_path / "heard.txt"),
               PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "tests")]))
    code = f"import json, test_midi_jack_restart as t; print('RESULT', json.dumps(t.{scenario}({server!r})))"
    run = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = run.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        os.killpg(run.pid, signal.SIGKILL)  # the child's session: its jackd and peer too
        out, err = run.communicate()
    print(out, err[-3000:], sep="\n")
    assert run.returncode == 0, f"the child failed (exit {run.returncode})"
    return json.loads(next(line for line in out.splitlines() if line.startswith("RESULT "))[7:])


def _lost_once_and_back(seen: dict, name: str) -> None:
    """The loss is said once, within three looks (the pulse out when the server died is missed at
    the next look, a second at the one after: two in a row); with the server and the peer back,
    the next look reopens the port and says so."""
    assert seen["looks_to_loss"] <= 3, seen
    lost = [r for r in seen["reports"] if " lost " in r]
    assert lost == [f"MIDI port {name!r} lost (the JACK server is not running); will reopen it when it returns"]
    assert seen["reports_while_down"] == lost and seen["faults"] == 1
    assert seen["looks_to_reconnect"] <= 2, seen
    assert seen["reports"][-1] == f"MIDI port {name!r} is back" and seen["reopened"] == 1


@pytest.mark.jack
@pytest.mark.realtime
def test_jack_server_restart_is_reported_and_the_port_reconnects_and_delivers(tmp_path):
    seen = _in_a_child("_scenario", ("jack_midi_dump", "stdbuf"), tmp_path)

    assert seen["connected_at_start"] and seen["heard_before"] == [60]
    _lost_once_and_back(seen, RECEIVER)
    assert seen["dropped"] >= 1  # the notes sent meanwhile are dropped and counted
    assert seen["sent_after"] and seen["heard_after"], seen  # a note sent once it is back arrives


@pytest.mark.jack
@pytest.mark.realtime
def test_jack_server_restart_under_a_midi_input_is_reported_and_it_listens_again(tmp_path):
    """A performer's keyboard on JACK: after the server dies and returns (with the keyboard's
    client), the input is said lost once, reopened, and hears the keyboard again."""
    seen = _in_a_child("_input_scenario", ("jack_midiseq",), tmp_path)

    assert seen["connected_at_start"] and set(seen["heard_before"]) == {64}
    _lost_once_and_back(seen, SOURCE)
    assert set(seen["heard_after"]) == {64}, seen
