"""Hypothesis-generated authored configs never crash the loader (issue 15): whatever an
author writes, it either loads (and then builds) or is a ConfigError naming the file and a line."""

from __future__ import annotations

import json
import math
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from creatures.authored.describe import describe
from creatures.authored.registry import ACTIONS, MODELS, PERCEPTS, load_parts
from creatures.config import ConfigError
from creatures.runtime.schema import load_installation

load_parts()
NAMES = ["a", "b", "bored", "boredom", "main", "inner", "whatever", "rest", "sing", "x y"]
KEYS = sorted({"type", "parent", "drive", "of", "window", "after", "near", "low", "high", "pitches", "pitch",
               "durations", "count", "phrase", "labels", "text", "seconds", "gaussian", "pulse", "percept", "done",
               "follow", "model", "value", "plastic", "kind", "source", "serves", "growth", "decay", "coupling",
               "inputs", "on_heard", "arc", "tuples", "alpha", "discount", "trigger", "action", "until",
               "constraints", "relation", "max_active", "temperature", "times", "sensor", "since", "amount",
               "group", "min_notes", "level", "bogus"})
TYPES = [*ACTIONS.names(), *PERCEPTS.names(), *MODELS.names(), "nope"]

scalars = st.one_of(
    st.sampled_from(NAMES + TYPES), st.integers(-3, 200), st.booleans(),
    st.floats(-10, 10, allow_nan=False).filter(math.isfinite),
    st.just('sway: getTo "reach"; wait; cycle 0'), st.just("m: cycle 7"),
)
values = st.recursive(
    scalars,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.sampled_from(KEYS), inner, max_size=4),
    max_leaves=12,
)
tables = st.dictionaries(st.sampled_from(KEYS), values, max_size=6)
sections = st.dictionaries(st.sampled_from(NAMES), tables, max_size=3)
creatures = st.fixed_dictionaries(
    {"name": st.sampled_from(["c", "d"]), "kind": st.sampled_from(["authored", "authord"])},
    optional={"drives": sections, "percepts": sections, "tuples": sections, "groups": sections,
              "learning": tables, "body": st.booleans()},
)


# A second generator stays close to valid creatures, so the checks past the first error run too.
DRIVES = ["boredom", "hunger"]
PERCEPT_NAMES = ["bored", "hearing", "p"]
TUPLE_NAMES = ["sing", "rest", "t"]
GROUP_NAMES = ["main", "inner"]
pos = st.floats(0.05, 5.0)
names = st.sampled_from(PERCEPT_NAMES + ["whatever", "nope"])
drive = st.fixed_dictionaries({}, optional={
    "growth": st.floats(-1, 1), "decay": pos, "on_heard": st.floats(-1, 1), "on_played": st.floats(-1, 1),
    "coupling": st.dictionaries(st.sampled_from(DRIVES + ["thirst"]), st.floats(-1, 1), max_size=2),
    "inputs": st.dictionaries(names, st.floats(-1, 1), max_size=2),
    "arc": st.lists(st.tuples(st.floats(0, 100), st.floats(-1, 1)).map(list), max_size=3).map(sorted)})
percept = st.fixed_dictionaries({"type": st.sampled_from(PERCEPTS.names() + ["pich"])}, optional={
    "parent": names, "drive": st.sampled_from(DRIVES + ["thirst"]), "of": names | st.lists(names, max_size=3),
    "window": pos, "after": pos, "near": st.floats(0, 127), "low": st.floats(0, 127), "high": st.floats(0, 127),
    "times": st.lists(st.floats(0, 60), max_size=3), "pitches": st.lists(st.integers(0, 130), max_size=3),
    "since": st.sampled_from(TUPLE_NAMES + ["nobody"]), "scale": st.sampled_from(["free", "level", "log"])})
action = st.sampled_from(ACTIONS.names() + ["sign"]) | st.fixed_dictionaries(
    {"type": st.sampled_from(ACTIONS.names())}, optional={
        "pitches": st.lists(st.integers(0, 130), max_size=4), "pitch": st.integers(0, 130),
        "count": st.integers(1, 5), "phrase": st.integers(0, 3) | st.just("latest"),
        "labels": st.lists(st.sampled_from(["reach", "sway left", "rech"]), max_size=2),
        "text": st.sampled_from(['s: getTo "reach"; wait; end', "s: cycle 4", "getTo x"]),
        "drive": st.sampled_from(DRIVES), "amount": st.floats(-1, 1)})
until = st.fixed_dictionaries({"seconds": pos}, optional={
    "gaussian": st.lists(st.floats(-1, 5), min_size=2, max_size=2), "pulse": st.integers(1, 4),
    "percept": names, "done": st.booleans(), "follow": st.booleans(),
    "model": st.fixed_dictionaries({"type": st.sampled_from(MODELS.names() + ["gauss"])})})
value = st.floats(-2, 5) | st.fixed_dictionaries({}, optional={
    "value": st.floats(-2, 5), "plastic": st.booleans(), "plasticity": st.floats(-0.5, 1.5),
    "kind": st.sampled_from(["scalar", "chain", "gaussian", "stance"]), "stance": st.floats(-1.5, 1.5),
    "serves": st.dictionaries(st.sampled_from(["eat"]), st.sampled_from(DRIVES + ["thirst"]), max_size=1)})
tuple_ = st.fixed_dictionaries({"action": action, "until": until}, optional={"trigger": names, "value": value})
members = st.lists(st.sampled_from(TUPLE_NAMES + GROUP_NAMES), min_size=1, max_size=4)
group = st.fixed_dictionaries({"tuples": members}, optional={
    "alpha": st.sampled_from([0.0, 0.1]), "discount": st.sampled_from([0.8, 1.0]), "max_active": st.integers(1, 3),
    "constraints": st.lists(st.fixed_dictionaries({
        "relation": st.sampled_from(["before", "meets", "during", "after"]), "a": st.sampled_from(TUPLE_NAMES),
        "b": st.sampled_from(TUPLE_NAMES)}), max_size=2)})
near_valid = st.fixed_dictionaries(
    {"name": st.just("c"), "kind": st.just("authored"),
     "tuples": st.dictionaries(st.sampled_from(TUPLE_NAMES), tuple_, min_size=1, max_size=3),
     "groups": st.dictionaries(st.sampled_from(GROUP_NAMES), group, min_size=1, max_size=2)},
    optional={"drives": st.dictionaries(st.sampled_from(DRIVES), drive, max_size=2),
              "percepts": st.dictionaries(st.sampled_from(PERCEPT_NAMES), percept, max_size=3),
              "body": st.booleans(),
              "mood": st.fixed_dictionaries({"drive": st.sampled_from(DRIVES + ["thirst"])},
                                            optional={"strength": st.floats(-0.5, 1.5)}),
              "learning": st.fixed_dictionaries({}, optional={"phrases": st.fixed_dictionaries(
                  {"group": st.sampled_from(GROUP_NAMES)}, optional={"trigger": names})})})


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float, str)):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return "{ " + ", ".join(f"{json.dumps(k)} = {_value(x)}" for k, x in v.items()) + " }"


def _toml(creature: dict) -> str:
    lines = ['title = "fuzz"', "", "[[creature]]"]
    lines += [f"{k} = {_value(v)}" for k, v in creature.items() if not isinstance(v, dict)]
    for section, entries in creature.items():
        if not isinstance(entries, dict):
            continue
        if section in ("learning", "mood") or section not in ("drives", "percepts", "tuples", "groups"):
            lines += ["", f"[creature.{section}]", *(f"{json.dumps(k)} = {_value(v)}" for k, v in entries.items())]
            continue
        for name, table in entries.items():
            lines += ["", f"[creature.{section}.{json.dumps(name)}]",
                      *(f"{json.dumps(k)} = {_value(v)}" for k, v in table.items())]
    return "\n".join(lines) + "\n"


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(creature=creatures | near_valid)
def test_generated_authored_configs_load_or_fail_with_file_and_line(tmp_path: Path, creature: dict):
    _loads_and_builds_or_fails_at_a_line(tmp_path, _toml(creature))


def _loads_and_builds_or_fails_at_a_line(tmp_path: Path, text: str) -> None:
    path = tmp_path / "fuzz.toml"
    path.write_text(text)
    try:
        inst = load_installation(path)
    except ConfigError as exc:
        assert exc.file == path and exc.line is not None, str(exc)
        return
    assert describe(inst).startswith("fuzz")  # what loads also builds


HERON = (Path(__file__).resolve().parents[1] / "installations" / "tutorial" / "creatures" / "heron.toml").read_text()
NUMBERS = ["0.05", "-0.3", "-0.08", "1.5", "1.0", "2.0", "0.3", "0.5", "4.0", "0.2", "0.8"]


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(numbers=st.lists(st.floats(-3, 5) | st.integers(-2, 70), min_size=len(NUMBERS), max_size=len(NUMBERS)),
       drop=st.sampled_from(["", "window", "pitches", "trigger", "value", "until", "group", "plastic"]))
def test_the_heron_with_any_numbers_or_a_line_missing_loads_and_builds_or_fails_at_a_line(tmp_path: Path, numbers,
                                                                                            drop):
    text = "title = \"fuzz\"\n" + HERON
    for old, new in zip(NUMBERS, numbers):
        text = text.replace(f"= {old}", f"= {json.dumps(new)}", 1)
    if drop:
        text = "\n".join(line for line in text.splitlines() if not line.startswith(drop)) + "\n"
    _loads_and_builds_or_fails_at_a_line(tmp_path, text)


MOOD = """
drive_floor = -1.0

[creature.drives.mood]
decay = 0.05

[creature.mood]
drive = {drive}
strength = {strength}
"""


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(drive=st.sampled_from(["mood", "boredom", "moood"]), strength=st.floats(-0.5, 1.5) | st.integers(-1, 2),
       stance=st.floats(-1.5, 1.5) | st.integers(-2, 2), plasticity=st.floats(-0.5, 1.5) | st.booleans(),
       plastic=st.booleans())
def test_a_heron_with_a_mood_and_any_stance_loads_and_builds_or_fails_at_a_line(tmp_path: Path, drive, strength,
                                                                                 stance, plasticity, plastic):
    """Emotional tags (thesis "emotional tags"): the stance keys an author types, in every
    combination, including those that contradict each other (a plasticity with plastic = false)."""
    value = (f'{{ kind = "stance", value = 2.0, stance = {_value(stance)}, plasticity = {_value(plasticity)}, '
             f"plastic = {_value(plastic)} }}")
    heron = HERON.replace("value = 2.0", f"value = {value}", 1)
    head, tail = heron.split("\n# -- drives", 1)
    text = 'title = "fuzz"\n' + head + MOOD.format(drive=json.dumps(drive), strength=_value(strength)) + "\n# -- drives" + tail
    _loads_and_builds_or_fails_at_a_line(tmp_path, text)
