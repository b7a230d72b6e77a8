"""``include = ["creatures/heron.toml"]``: creature files an installation includes (paths
relative to the file that writes the ``include``: an ``extends`` base in another folder
includes from its own folder). Each included file holds ``[[creature]]`` tables (and may
include further files); they are appended to the installation's creatures in order, and
their key lines keep pointing into their own file, so an error in a creature says where it
was written. A missing or circular include is a :class:`ConfigError` at the ``include`` line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import installations
from creatures.config import (MAX_CONFIG_CHAIN, ConfigError, _merge, config_error, nearest, not_a_file, read_toml,
                              written_in)

Where = dict[tuple, tuple[Path, int]]


def expand_includes(data: dict[str, Any], where: Where, path: Path, *, _chain: tuple[Path, ...] = ()) -> None:
    """Append the creatures of every included file to ``data["creature"]`` (in place)."""
    includes = data.pop("include", None)
    if includes is None:
        return
    if not isinstance(includes, list) or not all(isinstance(i, str) for i in includes):
        raise config_error(path, where, ("include",), "must be a list of file names (strings)")
    including = written_in(where, ("include",), path)  # the config, or the extends base that wrote it
    chain = (*_chain, including.resolve())
    creatures = data.setdefault("creature", [])
    if not isinstance(creatures, list):
        return  # the schema reports the malformed [[creature]] itself
    for k, name in enumerate(includes):
        file = (including.parent / name).resolve()
        if file in chain:
            loop = " -> ".join(p.name for p in (*chain, file))
            raise config_error(path, where, ("include", k), f"circular include ({loop})")
        if len(chain) >= MAX_CONFIG_CHAIN:
            raise config_error(path, where, ("include", k), f"more than {MAX_CONFIG_CHAIN} files include one "
                                                            "another; refused")
        if not file.is_file():
            raise config_error(path, where, ("include", k), f"included file {name!r} "
                                                            f"{not_a_file(name, including.parent)}")
        sub, sub_where = read_toml(file)
        expand_includes(sub, sub_where, file, _chain=chain)
        extra = set(sub) - {"creature"}
        if extra:
            key = sorted(extra)[0]
            raise config_error(file, sub_where, (key,), "an included file holds only [[creature]] tables "
                                                         "(and include)")
        tables = sub.get("creature", [])
        if not isinstance(tables, list):
            raise ConfigError(file, "'creature' must be [[creature]] tables", key="creature")
        offset = len(creatures)
        creatures.extend(tables)
        for loc, at in sub_where.items():
            if len(loc) >= 2 and loc[0] == "creature" and isinstance(loc[1], int):
                where[("creature", loc[1] + offset, *loc[2:])] = at


def expand_kinds(data: dict[str, Any], where: Where, path: Path) -> None:
    """``kind = "exchange"``: a ``[[creature]]`` table whose kind names a shipped creature
    document (``installations/creatures/exchange.toml``, one authored ``[[creature]]`` table)
    starts from that table, its own keys merged over it key by key as with ``like``. The
    shipped pieces are authored creatures; this is how an installation names one. Inherited
    keys keep pointing at the lines of the document they were written in."""
    tables = data.get("creature")
    if not isinstance(tables, list):
        return
    shipped = set(installations.creature_names())
    for i, table in enumerate(tables):
        if not isinstance(table, dict) or not isinstance(table.get("kind"), str) or table["kind"] not in shipped:
            continue
        file = installations.CREATURES / f"{table['kind']}.toml"
        doc, doc_where = read_toml(file)
        base = doc["creature"][0]
        own = {k: v for k, v in table.items() if k != "kind"}
        tables[i] = _merge(base, own)
        for loc, at in doc_where.items():
            if loc[:2] == ("creature", 0) and ("creature", i, *loc[2:]) not in where:
                where[("creature", i, *loc[2:])] = at


def expand_likes(data: dict[str, Any], where: Where, path: Path) -> None:
    """``like = "ada"`` in a ``[[creature]]`` table: start from the table of the earlier
    creature named ada (keys merge table by table; this one's win, and ``name`` is its own), so
    a colony of near-identical creatures is written once. Inherited keys keep the lines they
    were written at."""
    tables = data.get("creature")
    if not isinstance(tables, list):
        return
    seen: dict[str, int] = {}
    for i, table in enumerate(tables):
        if not isinstance(table, dict):
            continue
        like = table.pop("like", None)
        if like is not None:
            if not isinstance(like, str) or like not in seen:
                raise config_error(path, where, ("creature", i, "like"),
                                   f"no earlier creature named {like!r} to be like"
                                   + nearest(like, sorted(seen), "earlier creatures"))
            j = seen[like]
            tables[i] = _merge(tables[j], table)
            for loc, at in list(where.items()):
                if loc[:2] == ("creature", j) and ("creature", i, *loc[2:]) not in where:
                    where[("creature", i, *loc[2:])] = at
        name = tables[i].get("name")
        if isinstance(name, str):
            seen[name] = i
