"""docs/config.md documents every key the loader accepts (regenerate: creatures config-docs)."""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel

from creatures.kinds import load_all
from creatures.runtime.docs import config_reference
from creatures.runtime.schema import Installation

DOCS = Path(__file__).resolve().parents[1] / "docs" / "config.md"


def test_config_reference_is_up_to_date():
    assert DOCS.read_text() == config_reference(), "run: creatures config-docs > docs/config.md"


def test_every_key_is_documented_with_a_meaning():
    text = config_reference()
    models = [Installation, *(cls.Spec for cls in load_all().values())]
    while models:
        model = models.pop()
        for name, field in model.model_fields.items():
            if isinstance(field.annotation, type) and issubclass(field.annotation, BaseModel):
                assert field.annotation.__doc__, f"{field.annotation.__name__} (section [{name}]) has no docstring"
                models.append(field.annotation)
                continue
            if name in ("kind", "creature"):
                continue
            assert field.description, f"{model.__name__}.{name} has no description"
            assert f"`{name}`" in text
