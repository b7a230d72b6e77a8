"""Input-map benchmarks: what routing outside messages costs the creature's thread.

Every ``[[input]]`` message is applied on the creature's thread between ticks (the loop looks
at its inputs every millisecond, :mod:`creatures.runtime.ticking`), so a burst must be taken
in well inside one look: the target, 20,000 messages/s, is a 20-message burst (a controller
surface moved at once) in 1 ms. The baseline is the shipped ``/creature/<name>/note`` decode,
the cheapest thing the listener does with a message.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import mido

from bench import Row, best_of
from creatures.clock import SimulatedClock
from creatures.events import EventLog
from creatures.runtime.schema import load_installation
from creatures.runtime.session import Session
from midi.osc import decode
from midi.sinks import MemorySink

CONFIG = """
title = "input map bench"
[[creature]]
name = "bo"
kind = "exchange"
[[input]]
osc = "/fader/{a,b,c}/[0-9]*"
to = "sensor"
name = "fader"
range = [0.0, 10.0]
[[input]]
osc = "/reward"
to = "reward"
[[input]]
midi = "cc"
control = 7
to = "sensor"
name = "knob"
range = [-1.0, 1.0]
"""

TARGET = 20_000.0
"""Messages per second: a 20-message burst taken in within the loop's 1 ms look at its inputs."""


def run(quick: bool) -> list[Row]:
    n = 2_000 if quick else 20_000
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.toml"
        path.write_text(CONFIG)
        inst = load_installation(path)
    clock = SimulatedClock()
    session = Session(inst, clock, EventLog(keep_in_memory=0), MemorySink())
    router = session.inputs
    clock.advance_to(1.0)
    cc = [mido.Message("control_change", control=7, value=i % 128) for i in range(n)]

    def osc_sensor() -> None:
        for i in range(n):
            router.osc("/fader/b/12", [i / n], 1.0)

    def midi_sensor() -> None:
        for msg in cc:
            router.midi(msg, 1.0)

    def unmapped() -> None:
        for i in range(n):
            router.osc("/nobody/listens", [i], 1.0)

    def shipped() -> None:
        for i in range(n):
            decode("/creature/bo/note", [60, 100, 0.25], 1.0, ("127.0.0.1", 9000))

    t_base = best_of(shipped)
    rows = []
    for name, fn in (("OSC wildcard -> sensor", osc_sensor), ("MIDI cc -> sensor", midi_sensor),
                     ("OSC unmapped (counted, rate-limited log)", unmapped)):
        t = best_of(fn)
        rows.append(Row(f"route {name}", n / t, "msgs/s", target=TARGET, baseline="creature note decode",
                        ratio=t_base / t))
    return rows
