"""``creatures new NAME``: a commented starting installation with one authored creature,
ready to run offline and to grow step by step as in docs/authoring.md."""

from __future__ import annotations

import re
from pathlib import Path

TEMPLATE = '''# {name} — a new installation (docs/authoring.md explains every line).
# Run it:   creatures offline {file} --out {name}-out
# Inspect:  creatures describe {file}
title = "{name}"
seed = 0
tick = 0.05
duration = 60.0   # simulated seconds of an offline run

[output]
report = true

[[creature]]
name = "{name}"
kind = "authored"

# Drives: the creature's synthetic chemistry. Boredom grows in silence; notes relieve it.
[creature.drives.boredom]
growth = 0.05
on_heard = -0.3
on_played = -0.1

# Percepts: what it notices. 'drive' is scale-free: how bored, among the boredoms it has known.
[creature.percepts.bored]
type = "drive"
drive = "boredom"

[creature.percepts.hearing]
type = "heard"
window = 1.5

# Action-tuples: in context Tr (trigger), doing Ac (action) until Du (until) is worth V (value).
[creature.tuples.sing]
trigger = "bored"
action = {{ type = "play_phrase", pitches = [60, 64, 67, 72], durations = 0.3 }}
until = {{ done = true }}
value = 1.0

[creature.tuples.echo]
trigger = "hearing"
action = {{ type = "echo", count = 4, mutation = 0.2 }}
until = {{ done = true }}
value = 0.8

[creature.tuples.rest]
action = "rest"
until = {{ pulse = 2 }}   # two durations of the rhythm it hears
value = 0.3

# The action-group they compete in. alpha = 0 keeps the values as written; to learn, add a
# reward tuple with 'value = {{ value = 4.0, plastic = false }}' and raise alpha.
[creature.groups.main]
tuples = ["sing", "echo", "rest"]
alpha = 0.0
'''


def new_installation(name: str, directory: Path) -> Path:
    """Write ``directory/NAME.toml``; refuses a bad name or an existing file."""
    if not re.fullmatch(r"[A-Za-z0-9_\-]+", name):
        raise ValueError(f"{name!r}: a name is ASCII letters, digits, _ and - (it names the file and the creature, and goes into OSC addresses)")
    path = directory / f"{name}.toml"
    if path.exists():
        raise FileExistsError(f"{path} exists; not overwritten")
    directory.mkdir(parents=True, exist_ok=True)
    path.write_text(TEMPLATE.format(name=name, file=path.name), encoding="utf-8")
    return path
