"""A minimal exchange peer the OSC tests run as a process of its own: ``python tests/osc_peer.py
--name A --port 9001 --peer 127.0.0.1:9002`` (tests/test_midi_osc.py).

It plays the exchange game over OSC (thesis, "exchange"): every note it hears is remembered;
at its own pace it plays back the oldest remembered note, transformed (transposed), or its
own seed note when it remembers nothing. It learns peers from their ``hello`` messages (a
bounded table, :mod:`midi.peer_table`), so a peer that restarts is heard again without
configuration. With each hello it sends its state: ``remembered`` (notes waiting to be played
back).

It reports on stdout, one JSON object per line: ``listening``, ``hello``, ``heard`` (each note
heard), ``state`` (each state value heard) and ``stats`` (whenever a dropped-packet counter
changes) — what the two-process tests read. The framework's own creatures speak the same
protocol (``creatures run`` with ``[osc]``, :mod:`creatures.runtime.network`); this peer lives
with the tests because nothing in the product runs it.
"""

from __future__ import annotations

import argparse
import json
import signal
import socket
import sys
from collections import deque

from creatures.clock import WallClock
from midi.notes import NoteEvent
from midi.osc import OscListener, OscSender, answer_hello
from midi.peer_table import PeerTable


def _address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` with the host resolved, as asks from that peer will come from it."""
    host, _, port = text.rpartition(":")
    return socket.gethostbyname(host or "127.0.0.1"), int(port)


def _say(**event: object) -> None:
    print(json.dumps(event), flush=True)


def transform(note: NoteEvent, transpose: int, *, low: int = 36, high: int = 96) -> NoteEvent:
    """The heard note moved by ``transpose`` semitones, folded back into ``low..high``."""
    span = high - low + 1
    pitch = low + (note.pitch + transpose - low) % span
    return NoteEvent(note.time, pitch, note.velocity, note.channel, note.duration)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python tests/osc_peer.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--name", required=True)
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on")
    parser.add_argument("--port", type=int, default=0, help="UDP port to listen on (0: any free)")
    parser.add_argument("--peer", action="append", default=[], type=_address, help="HOST:PORT")
    parser.add_argument("--interval", type=float, default=0.05, help="seconds between notes played")
    parser.add_argument("--transpose", type=int, default=7)
    parser.add_argument("--seed-pitch", type=int, default=60)
    parser.add_argument("--hello-every", type=float, default=0.5, help="seconds between hellos")
    args = parser.parse_args(argv)

    clock = WallClock()
    listener = OscListener(clock, host=args.host, port=args.port)
    table = PeerTable(args.peer)
    sender = OscSender(args.name, peers=table.targets)
    memory: deque[NoteEvent] = deque(maxlen=64)
    running = True

    def stop(*_: object) -> None:
        nonlocal running
        running = False

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    _say(event="listening", name=args.name, port=listener.port)
    next_play = next_hello = 0.0
    counters = (0, 0)
    try:
        while running:
            now = clock.now()
            if now >= next_hello:
                table.expire(now)
                sender.hello(listener.port, table.echo)
                sender.state({"remembered": len(memory)})
                next_hello = now + args.hello_every
            for heard in listener.poll():
                if heard.creature == args.name:
                    continue
                if heard.kind == "hello":
                    if answer_hello(table, listener, args.name, heard, now) in ("new", "moved"):
                        _say(event="hello", name=heard.creature, port=heard.args[0])
                elif heard.kind == "ask":
                    table.was_asked(heard.sender, heard.args[0])
                elif heard.kind == "note":
                    memory.append(heard.note)
                    _say(event="heard", name=heard.creature, pitch=heard.note.pitch,
                         velocity=heard.note.velocity, duration=heard.note.duration)
                elif heard.kind == "state":
                    _say(event="state", name=heard.creature, key=heard.args[0], value=heard.args[1])
                elif heard.kind == "bye":
                    table.part(heard.creature)
            if now >= next_play:
                played = memory.popleft() if memory else NoteEvent(now, args.seed_pitch, 90, 0, 0.2)
                sender.note(transform(played, args.transpose))
                next_play = now + args.interval
            if (listener.malformed, listener.oversize) != counters:
                counters = (listener.malformed, listener.oversize)
                _say(event="stats", received=listener.received, malformed=counters[0], oversize=counters[1])
            listener.wait(max(0.0, min(next_play, next_hello) - clock.now()))
    finally:
        sender.bye()
        sender.close()
        listener.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
