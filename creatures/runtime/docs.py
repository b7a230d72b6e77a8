"""The config reference (``docs/config.md``), generated from the schema itself.

Every key's type, default and description come from the pydantic models of
:mod:`creatures.runtime.schema` and of each creature kind, so the page cannot drift from
what the loader accepts (a test regenerates it and compares).
"""

from __future__ import annotations

import sys
import types
import typing

import annotated_types
from pydantic import BaseModel
from pydantic.fields import FieldInfo

import installations
from creatures.kinds import load_all
from creatures.room.crowd import LARGEST_CROWD
from creatures.runtime.schema import Installation, InputMap


def _type_name(annotation: object) -> str:
    """``list[float]``, ``str or None``: bounds of list items (``Annotated``) are left out."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is typing.Annotated:
        return _type_name(args[0])
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_name(a) for a in args)
    if annotation is type(None):
        return "None"
    if origin is not None:
        return f"{getattr(origin, '__name__', origin)}[{', '.join(_type_name(a) for a in args)}]"
    return getattr(annotation, "__name__", str(annotation))


def _range(field: FieldInfo) -> str:
    """The bounds of a number as ``0 < x ≤ 30`` (every number has them, creatures.bounds)."""
    low = next((f"{m.ge:g} ≤ " for m in field.metadata if isinstance(m, annotated_types.Ge)), "")
    low = low or next((f"{m.gt:g} < " for m in field.metadata if isinstance(m, annotated_types.Gt)), "")
    high = next((f" ≤ {m.le:g}" for m in field.metadata if isinstance(m, annotated_types.Le)), "")
    high = high or next((f" < {m.lt:g}" for m in field.metadata if isinstance(m, annotated_types.Lt)), "")
    return f", {low}x{high}" if low or high else ""


def _optional_model(annotation: object) -> object:
    """``Model | None`` (an optional table, off unless written) as ``Model``; else unchanged."""
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) in (typing.Union, types.UnionType) and len(args) == 2 and type(None) in args:
        inner = next(a for a in args if a is not type(None))
        if isinstance(inner, type) and issubclass(inner, BaseModel):
            return inner
    return annotation


def _list_model(annotation: object) -> type[BaseModel] | None:
    """The model of a list of tables (``list[SteerSpec]``: ``[[creature.vehicle.steer]]``), else None."""
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) is typing.Annotated:
        return _list_model(args[0])
    if typing.get_origin(annotation) is list and isinstance(args[0], type) and issubclass(args[0], BaseModel):
        return args[0]
    return None


OWN_SECTION = (InputMap,)
"""Lists of tables documented in a section of their own (the loader moves ``[[input]]`` tables
into ``input.map``: the reference names them as they are written)."""


def _rows(model: type[BaseModel], prefix: str, section: str = "") -> list[str]:
    """The key table of ``model``, then one table per nested model and per list of tables
    (``section``: the dotted path of ``model`` itself, so a table two levels down of a
    creature is titled ``[creature.body.breathe]``, a list of them ``[[room.zones]]``).
    Lists of tables were once left at their row ("list[SteerSpec]"), so no steer table's keys
    were documented anywhere."""
    rows, nested = [], []
    for name, field in model.model_fields.items():
        annotation = _optional_model(field.annotation)
        path = f"{section}.{name}" if section else f"{prefix}{name}"
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            nested.append((f"[{path}]", annotation))
            if annotation is not field.annotation:  # optional: a row says it is off unless written
                rows.append(f"| `{prefix}{name}` | table or None | `None` | {field.description or ''} "
                            f"(its keys: `[{path}]` below) |")
            continue
        if (item := _list_model(annotation)) is not None and item not in OWN_SECTION:
            nested.append((f"[[{path}]]", item))
            rows.append(f"| `{prefix}{name}` | list of tables | `[]` | {field.description or ''} "
                        f"(its keys: `[[{path}]]` below) |")
            continue
        if name == "kind" and typing.get_origin(annotation) is typing.Literal:
            continue  # the discriminating ``kind`` key, documented by its section title
        default = "required" if field.is_required() else f"`{field.get_default(call_default_factory=True)!r}`"
        rows.append(f"| `{prefix}{name}` | {_type_name(annotation)}{_range(field)} | {default} | {field.description or ''} |")
    out = ["| key | type | default | meaning |", "|---|---|---|---|", *rows] if rows else []
    for title, sub in nested:
        summary = " ".join((sub.__doc__ or "").split("\n\n")[0].split())  # its first paragraph
        out += [*([""] if out else []), f"`{title}` — {summary}", "", *_rows(sub, "", title.strip("[]"))]
    return out


def _crowd_rows() -> list[str]:
    """The keys any ``[[creature]]`` table takes before its kind's are read (they make or
    start the tables the kind then validates: :mod:`creatures.room.crowd`, ``like``)."""
    return [
        "| key | type | default | meaning |", "|---|---|---|---|",
        "| `like` | str | none | start from the table of the earlier creature of that name (tables merge key by "
        "key, this one's keys win) |",
        f"| `count` | int, 1 ≤ x ≤ {LARGEST_CROWD:,} | none | make this many creatures of the table, named NAME-0 … "
        "NAME-(count−1) |",
        "| `vary` | table of [low, high] | `{}` | with count: each clone draws the dotted key's value uniformly from "
        "its range, seeded by the installation's seed (integers when both ends are): "
        "`vary = { \"vehicle.max_speed\" = [0.8, 1.2] }` |",
        "| `cycle` | table of lists | `{}` | with count: clone k takes item k mod the list's length for the dotted "
        "key: `cycle = { channel = [0, 1, 2] }` |",
    ]


def config_reference() -> str:
    """Markdown reference of every key an installation config accepts."""
    lines = [
        "# Installation config reference",
        "",
        "Generated by `creatures config-docs` from the schema (do not edit by hand).",
        "A config is TOML; `extends = \"base.toml\"` merges a base config (this file wins): tables merge key "
        "by key, other values and lists are replaced, and a `[[creature]]` named as one of the base's is merged "
        "over it while one of a new name is added after the base's creatures.",
        "Errors name the file, the key path and the line, and suggest the nearest valid key.",
        "A number or a truth value is written bare: `tick = \"0.04\"` and `midi = 1` are errors "
        "(write `tick = 0.04`, `midi = true`).",
        "Every number must be finite (`nan` and `inf` are refused) and lie in the range its type shows.",
        "",
        "## Top level",
        "",
        *[row for row in _rows(Installation, "") if not row.startswith("| `creature` | list")],  # its own section
        "",
        "## `[[input]]` — the input map: one table per source",
        "",
        " ".join((InputMap.__doc__ or "").split()),
        "",
        *_rows(InputMap, ""),
        "",
        "## `[[creature]]` — one table per creature; `kind` picks the keys below",
        "",
        "Any kind's table also takes these, read before its kind's keys:",
        "",
        *_crowd_rows(),
    ]
    for kind, cls in sorted(load_all().items()):
        doc = (sys.modules[cls.__module__].__doc__ or "").strip()
        lines += ["", f"### kind = \"{kind}\"", "", doc.split("\n\n")[0].replace("\n", " "), "",
                  *_rows(cls.Spec, "", "creature")]
        if kind == "authored":
            shipped = ", ".join(f"`{name}`" for name in installations.creature_names())
            lines += ["", f"Shipped authored creatures, named as a kind ({shipped}): the table starts from "
                          "`installations/creatures/NAME.toml` and its own keys (those above) merge over it."]
    return "\n".join(lines) + "\n"
