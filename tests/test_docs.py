"""docs/config.md documents every key the loader accepts (regenerate: creatures config-docs)."""

from __future__ import annotations

import typing
from pathlib import Path

from pydantic import BaseModel

from creatures.kinds import load_all
from creatures.runtime.docs import config_reference
from creatures.runtime.schema import Installation

DOCS = Path(__file__).resolve().parents[1] / "docs" / "config.md"


def test_config_reference_is_up_to_date():
    assert DOCS.read_text() == config_reference(), "run: creatures config-docs > docs/config.md"


def _table_list(annotation: object) -> type[BaseModel] | None:
    """The model of ``list[Model]`` (a list of tables, ``[[...]]``), else None."""
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) is list and isinstance(args[0], type) and issubclass(args[0], BaseModel):
        return args[0]
    return None


def test_every_key_is_documented_with_a_meaning():
    """Every key of every table, lists of tables too (``[[creature.vehicle.steer]]``'s keys
    were once documented nowhere)."""
    text = config_reference()
    models = [Installation, *(cls.Spec for cls in load_all().values())]
    while models:
        model = models.pop()
        for name, field in model.model_fields.items():
            table = field.annotation if isinstance(field.annotation, type) else _table_list(field.annotation)
            if table is not None and issubclass(table, BaseModel):
                assert table.__doc__, f"{table.__name__} (section [{name}]) has no docstring"
                models.append(table)
                continue
            if name in ("kind", "creature"):
                continue
            assert field.description, f"{model.__name__}.{name} has no description"
            assert f"`{name}`" in text


def test_lists_of_tables_and_crowd_keys_have_sections():
    text = config_reference()
    for title in ("[[creature.vehicle.steer]]", "[[room.zones]]", "[[room.paths]]", "[[room.flows]]",
                  "[[room.notes]]", "[[room.visitors]]", "[[room.obstacles]]", "[[output.cc]]", "[creature.vehicle]"):
        assert f"`{title}` — " in text, title
    assert "`[[input.map]]` — " not in text  # [[input]] has its own section, as it is written
    for key in ("count", "vary", "cycle", "like", "panic", "slowing", "probability"):
        assert f"| `{key}` |" in text, key
