"""Truncated OSC packets at the listener: python-osc zero-pads an argument cut short, so a
``/creature/x/note ,iif 60 100 1.5`` cut to 38 of its 40 bytes was heard with a made-up
duration, and a ``,f`` message whose float kept 2 bytes was heard too. Every cut of a valid
packet must be dropped and counted (``not osc``), and the whole packet still taken."""

from __future__ import annotations

import socket

from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message_builder import OscMessageBuilder

from midi.osc import OscListener



def message(address: str, *args: tuple[object, str]):
    builder = OscMessageBuilder(address)
    for value, tag in args:
        builder.add_arg(value, tag)
    return builder.build()


NOTE = message("/creature/x/note", (60, "i"), (100, "i"), (1.5, "f"))
LIGHT = message("/light", (0.5, "f"))
MIXED = message("/mixed", (b"abcde", "b"), ("hi", "s"), (True, "T"), (2.0, "d"), (7, "h"))


def bundle(*messages) -> bytes:
    builder = OscBundleBuilder(IMMEDIATELY)
    for m in messages:
        builder.add_content(m)
    return builder.build().dgram


def listener(clock, outside: list) -> OscListener:
    """A listener on a port the kernel chose whose input map records what it is given."""
    return OscListener(clock, port=0, elsewhere=lambda address, args, t: outside.append((address, args)))


def test_every_truncation_of_a_valid_packet_is_dropped_and_counted_and_the_whole_one_taken(clock):
    packets = [NOTE.dgram, LIGHT.dgram, MIXED.dgram, bundle(NOTE), bundle(LIGHT, MIXED)]
    assert len(NOTE.dgram) == 40
    # A bundle cut exactly between two elements is a valid smaller bundle (no length in OSC says
    # otherwise): every other cut must be refused.
    cuts = [p[:n] for p in packets for n in range(len(p)) if p is not packets[-1] or n != 16 + 4 + len(LIGHT.dgram)]
    outside: list = []
    ear = listener(clock, outside)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    heard: list = []
    try:
        for cut in cuts:
            sender.sendto(cut, ("127.0.0.1", ear.port))
        for packet in packets:  # after the cuts, so all of them were read once these are
            sender.sendto(packet, ("127.0.0.1", ear.port))
        while len(heard) < 2 or len(outside) < 4:
            assert ear.wait(5.0), (ear.counts(), heard, outside)
            heard.extend(ear.poll())
    finally:
        sender.close()
        ear.close()
    assert [(h.kind, h.note.pitch, h.note.velocity, h.note.duration) for h in heard] == [("note", 60, 100, 1.5)] * 2
    assert [address for address, _ in outside] == ["/light", "/mixed", "/light", "/mixed"]
    assert outside[0][1] == [0.5] and outside[1][1] == [b"abcde", "hi", True, 2.0, 7]
    assert ear.dropped == {"not osc": len(cuts)}, ear.counts()
    assert ear.malformed == len(cuts)
