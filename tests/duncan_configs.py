"""The shipped duncan config as tests vary it: with its simulated trainer taken out or replaced."""

from __future__ import annotations

from pathlib import Path

SHIPPED = Path(__file__).resolve().parents[1] / "installations" / "duncan.toml"


def with_trainer(table: str, text: str | None = None) -> str:
    """``text`` (the shipped config) with its ``[input.trainer]`` table, up to the next table,
    replaced by ``table`` ("" takes it out: a test whose cues and clicks are its own)."""
    text = SHIPPED.read_text(encoding="utf-8") if text is None else text
    start = text.index("\n[input.trainer]")
    return text[:start] + ("\n" + table if table else "") + text[text.index("\n[", start + 1):]
