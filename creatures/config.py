"""Installation configs: TOML read with the stdlib, validated with pydantic.

A bad config must say *where* it is wrong: every :class:`ConfigError` names the file, the
dotted key path and the line, and for an unknown key suggests the nearest valid one. A config
may name a base config with ``extends = "base.toml"`` (relative to itself); tables merge
key by key, the extending file wins.
"""

from __future__ import annotations

import difflib
import re
import stat
import tomllib
import typing
from pathlib import Path, PurePath
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from creatures.paths import kind_of

Model = TypeVar("Model", bound=BaseModel)

MAX_CONFIG_BYTES = 1024 * 1024
"""Largest config file read (a hand-written installation is a few kilobytes)."""

MAX_CONFIG_DEPTH = 16
"""Deepest nesting of tables and arrays a config may have (the schema needs five)."""

MAX_CONFIG_CHAIN = 32
"""Longest chain of files one ``extends`` (or ``include``) pulls in after another. Each link
is read recursively: a generated chain of a thousand ran out of stack (a traceback, or an
error about nesting in a file that nests nothing)."""

_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_ASSIGN = re.compile(r"""^\s*((?:[A-Za-z0-9_\-]+|"[^"]*"|'[^']*')(?:\s*\.\s*(?:[A-Za-z0-9_\-]+|"[^"]*"|'[^']*'))*)\s*=""")


class ConfigError(Exception):
    """A config problem located by file, key path and line."""

    def __init__(self, file: Path, message: str, *, key: str = "", line: int | None = None) -> None:
        self.file, self.key, self.line, self.message = file, key, line, message
        where = f"{file}:{line}" if line else str(file)
        super().__init__(f"{where}: {key + ': ' if key else ''}{message}")


def _split_key(text: str) -> list[str]:
    parts = re.findall(r'"[^"]*"|\'[^\']*\'|[^.\s]+', text)
    return [p.strip("\"'") for p in parts]


def key_lines(text: str) -> dict[tuple[str | int, ...], int]:
    """Map each key path defined in TOML ``text`` to its 1-based line.

    Arrays of tables get integer indices (``creature.0.name``) in the order they appear, so a
    validation error at ``("creature", 1, "kind")`` finds the second ``[[creature]]`` block.
    A table a header or a dotted key defines implicitly (``group`` in ``[creature.group.mood]``,
    ``edits`` in ``edits.favour = …``) is at the first line that writes it: an unknown key
    there is a typo on that line, not on the line of the table around it.
    """
    lines: dict[tuple[str | int, ...], int] = {}
    prefix: tuple[str | int, ...] = ()
    counters: dict[tuple[str | int, ...], int] = {}
    for lineno, raw in enumerate(text.splitlines(), 1):
        header = _HEADER.match(raw)
        if header:
            names = _split_key(header.group(2))
            # A sub-table of an array of tables belongs to that array's latest element.
            path: tuple[str | int, ...] = ()
            for name in names[:-1]:
                path = (*path, name)
                if path in counters:
                    path = (*path, counters[path])
                lines.setdefault(path, lineno)
            path = (*path, names[-1])
            if header.group(1) == "[[":
                index = counters.get(path, -1) + 1
                counters[path] = index
                prefix = (*path, index)
            else:
                prefix = path
            lines.setdefault(prefix, lineno)
            continue
        assign = _ASSIGN.match(raw)
        if assign:
            keys = _split_key(assign.group(1))
            for n in range(1, len(keys) + 1):
                lines.setdefault((*prefix, *keys[:n]), lineno)
    return lines


def _merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    merged = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = _merge(merged[key], value)
        else:
            merged[key] = value
    return merged


def read_toml(path: str | Path, *, _seen: tuple[Path, ...] = ()) -> tuple[dict[str, Any], dict[tuple, tuple[Path, int]]]:
    """Read a TOML file and its ``extends`` chain; return data and key → (file, line)."""
    path = Path(path).resolve()
    if path in _seen:
        raise ConfigError(path, f"'extends' loops back to {path.name}", key="extends")
    try:
        mode = path.stat().st_mode
        if not stat.S_ISREG(mode):  # /dev/zero would be read until memory runs out; a FIFO blocks
            raise ConfigError(path, f"is {kind_of(mode)}, not a regular file; a config is a TOML file")
        # Read at most one byte past the cap, whatever stat said (a file may grow meanwhile).
        with path.open("rb") as handle:
            raw = handle.read(MAX_CONFIG_BYTES + 1)
        if len(raw) > MAX_CONFIG_BYTES:
            raise ConfigError(path, f"config file larger than {MAX_CONFIG_BYTES} bytes; refused")
        text = raw.decode("utf-8-sig")  # a byte-order mark (Windows editors write one) is no TOML
    except FileNotFoundError:
        raise ConfigError(path, "config file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(path, f"cannot read config ({exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        match = re.search(r"line (\d+)", str(exc))
        raise ConfigError(path, f"invalid TOML ({exc}){_both_forms(text)}",
                          line=int(match.group(1)) if match else None) from None
    except RecursionError:  # tomllib parses nested arrays and tables recursively
        raise ConfigError(path, f"invalid TOML (nested too deeply; at most {MAX_CONFIG_DEPTH} levels of tables and arrays)") from None
    where = {loc: (path, line) for loc, line in key_lines(text).items()}
    deep = _too_deep(data, ())
    if deep is not None:
        raise config_error(path, where, deep, f"nested too deeply (at most {MAX_CONFIG_DEPTH} levels of tables and arrays)")
    parent = data.pop("extends", None)
    if parent is None:
        return data, where
    line = where.get(("extends",), (path, None))[1]
    if not isinstance(parent, str):
        raise ConfigError(path, "must be a file name (string)", key="extends", line=line)
    base = path.parent / parent
    if not base.is_file():
        # Named here, at the including file's line: the base's own path alone would not say
        # which config asked for it.
        raise ConfigError(path, f"base config {parent!r} {not_a_file(parent, path.parent)}", key="extends", line=line)
    if len(_seen) + 1 >= MAX_CONFIG_CHAIN:
        raise ConfigError(path, f"more than {MAX_CONFIG_CHAIN} configs extend one another; refused", key="extends",
                          line=line)
    base_data, base_where = read_toml(base, _seen=(*_seen, path))
    return _extend(base_data, base_where, data, where)


BY_NAME = ("creature",)
"""The lists of tables an ``extends`` merges by ``name``: a ``[[creature]]`` named as one of the
base's is merged over it (this file wins), any other is added after the base's. Other lists are
replaced, as values are: a base's creatures dropped by a file that meant to add one, silently,
was what an artist met."""


def _extend(base: dict[str, Any], base_where: dict[tuple, tuple[Path, int]], data: dict[str, Any],
            where: dict[tuple, tuple[Path, int]]) -> tuple[dict[str, Any], dict[tuple, tuple[Path, int]]]:
    """``data`` over its ``extends`` base, with each key's file and line (renumbered where a
    table of :data:`BY_NAME` lands at another index)."""
    merged, moved = _merge(base, data), {}
    for key in BY_NAME:
        old, new = base.get(key), data.get(key)
        if not (isinstance(old, list) and isinstance(new, list)):
            continue
        tables = list(old)
        named = {t["name"]: i for i, t in enumerate(old) if isinstance(t, dict) and isinstance(t.get("name"), str)}
        for j, table in enumerate(new):
            i = named.get(table.get("name")) if isinstance(table, dict) else None
            if i is None:
                i = len(tables)
                tables.append(table)
            else:
                tables[i] = _merge(tables[i], table)
            moved[(key, j)] = (key, i)
        merged[key] = tables
    return merged, {**base_where, **{(*moved.get(loc[:2], loc[:2]), *loc[2:]): at for loc, at in where.items()}}


def _too_deep(node: Any, loc: tuple[str | int, ...]) -> tuple[str | int, ...] | None:
    """The key path at which ``node`` nests deeper than :data:`MAX_CONFIG_DEPTH`, if any
    (checked before validation, which would recurse as deep)."""
    if len(loc) > MAX_CONFIG_DEPTH:
        return loc
    children = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, child in children:
        found = _too_deep(child, (*loc, key))
        if found is not None:
            return found
    return None


def _both_forms(text: str) -> str:
    """A hint for TOML that writes one name both as a list of tables and as a table (``[[input]]``
    maps beside an ``[input]`` table: tomllib says only that a value cannot be overwritten)."""
    lists = set(re.findall(r"^\s*\[\[\s*([\w.\-]+)\s*\]\]", text, re.M))
    tables = set(re.findall(r"^\s*\[\s*([\w.\-]+)\s*\](?!\])", text, re.M))
    both = sorted(lists & tables)
    if not both:
        return ""
    name = both[0]
    return (f"; [[{name}]] and [{name}] are both written: a name is a list of tables or a table, not both"
            + (" — write the input maps as [[input.map]]" if name == "input" else ""))


def _fields_at(model: type[BaseModel], loc: tuple[str | int, ...]) -> list[str]:
    """Valid key names at the table that holds ``loc``'s last key (for suggestions). A table
    of named tables (``dict[str, Model]``: ``[creature.drives.boredom]``) has names of the
    author's choosing at its first level, so that step of ``loc`` is passed over."""
    current: Any = model
    branches: dict[str, Any] = {}  # a union's models by the class name pydantic puts in a location
    named = False  # the next key is a name in a table of named tables
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        if named:
            named = False
            continue
        if part in branches:  # pitch = { ar = 0 }: ('pitch', 'Arg', 'ar'), the branch meant
            current, branches = branches[part], {}
            continue
        fields = getattr(current, "model_fields", None)
        if not fields or part not in fields:
            return []
        annotation = fields[part].annotation
        args = typing.get_args(annotation)
        args = (*args, *(a for arg in args for a in typing.get_args(arg)))  # list[Model] | None
        named = any(typing.get_origin(a) is dict for a in (annotation, *args))
        candidates = [annotation, *args]
        branches = {c.__name__: c for c in candidates if isinstance(c, type) and issubclass(c, BaseModel)}
        current = next(iter(branches.values()), None)
        if current is None:
            return []
    return list(getattr(current, "model_fields", {}))


def _data_path(data: Any, loc: tuple[str | int, ...]) -> tuple[str | int, ...]:
    """The part of a pydantic error location that names real keys in ``data``.

    Tagged unions add the tag to the location (``creature.0.exchange.hunger``), and a model's
    own validators their names (``function-after[_one_body(), …]``); walking the data drops such
    steps so the key path is the one the author wrote.
    """
    path: list[str | int] = []
    node = data
    for part in loc:
        if not isinstance(node, (dict, list)):
            continue  # below a value the author wrote: the names of pydantic's own type branches
        if isinstance(part, str) and "[" in part and not (isinstance(node, dict) and part in node):
            continue
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
        elif isinstance(node, (dict, list)) and part != loc[-1]:
            continue
        path.append(part)
    return tuple(path)


def _at(data: Any, path: tuple[str | int, ...]) -> Any:
    """The value at key path ``path`` of ``data`` (as :func:`_data_path` gives it), else ``None``."""
    for part in path:
        if isinstance(data, dict) and part in data or isinstance(data, list) and isinstance(part, int) \
                and 0 <= part < len(data):
            data = data[part]
        else:
            return None
    return data


SCALAR_ERRORS = frozenset({"float_type", "float_parsing", "int_type", "int_parsing", "string_type", "bool_type",
                           "bool_parsing", "literal_error"})
"""Pydantic's errors for a value that is not the number, string or name its field wants."""


def _scalar_of_table(error: Any) -> bool:
    """Whether ``error`` says a table the author wrote is not a scalar: one branch of a union
    of a scalar and a table, the branch the author did not mean."""
    return error["type"] in SCALAR_ERRORS and isinstance(error.get("input"), dict)


def validate(
    model: type[Model],
    data: Any,
    where: dict[tuple, tuple[Path, int]],
    file: Path,
    *,
    prefix: tuple[str | int, ...] = (),
    literal: bool = True,
) -> Model:
    """Validate ``data`` (found at key path ``prefix`` of ``file``) or raise :class:`ConfigError`;
    with ``literal``, numbers and truth values must be written as such, and without it (a
    console's or a controller's value) a number may come as text and a truth value as 0 or 1,
    but never as other text (:func:`_quoted_scalar`)."""
    try:
        valid = model.model_validate(data)
    except ValidationError as exc:
        # An unknown key usually explains a "missing" one (a typo), so report it first. Where a
        # value may be a number or a table (``value = 4.0`` or ``value = { kind = … }``) and the
        # author wrote a table, the table's own error is the one meant, not "should be a number".
        error = min(exc.errors(), key=lambda e: (e["type"] != "extra_forbidden", _scalar_of_table(e)))
        loc = (*prefix, *_data_path(data, tuple(error["loc"])))
        # Valid keys are found along pydantic's own location (where a validator moved a table:
        # ``[[input]]`` read as ``input.map``), else along the keys the author wrote (a tagged
        # union adds its tag to pydantic's).
        choices = _fields_at(model, tuple(error["loc"])) or _fields_at(model, loc[len(prefix):])
        message = error["msg"].removeprefix("Value error, ")  # a validator's own sentence, as it wrote it
        if error["type"] in ("bool_type", "bool_parsing"):  # "unable to interpret input" names no spelling
            message = _truth(literal)
        got = error.get("input") if error["type"] not in ("missing", "extra_forbidden") else None
        if error["type"] == "value_error" and isinstance(got, dict):  # a validator's sentence about a table
            got = None  # names what is wrong in it: the table repeated after it (an action's) buried that
        if error["type"] == "literal_error" and isinstance(got, str):  # kind = "gausian"
            close = difflib.get_close_matches(got, re.findall(r"'([^']*)'", str(error["ctx"]["expected"])), n=1)
            message += f" (got {got!r}" + (f"; did you mean {close[0]!r}?)" if close else ")")
            got = None
        if error["type"] == "model_type" and not isinstance(got, dict):  # body = "stick"
            header = ".".join(str(part) for part in loc if isinstance(part, str))
            truth = any(e["type"] == "bool_parsing" and e["loc"][:-1] == error["loc"][:-1] for e in exc.errors())
            message = (("true, false or " if truth else "") + f"a table is wanted here: {loc[-1]} = {{ … }} or a "
                       f"[{header}] table (docs/config.md)")
        if error["type"] == "list_type" and isinstance(got, dict):  # [creature] for [[creature]]
            header = ".".join(str(part) for part in loc if isinstance(part, str))
            message, got = f"a list of tables: write [[{header}]] (two brackets) before each one", None
        if error["type"] == "too_long" and isinstance(got, list):  # the first entry past the limit, by its line
            limit = error["ctx"]["max_length"]
            loc, message, got = (*loc, limit), f"at most {limit} entries here, not {len(got)}", None
        if error["type"] == "missing" and len(loc) > len(prefix) and isinstance(loc[-1], int):
            short = _at(data, loc[len(prefix):-1])  # a pair written with one value: at = [1.0]
            if isinstance(short, list):
                loc, message, got = loc[:-1], f"too few values: a value is wanted at position {loc[-1] + 1}", short
        raise config_error(file, where, loc, message if error["type"] != "extra_forbidden" else None,
                           choices=choices, got=got) from None
    quoted = _quoted_scalar(valid, data, toggles=not literal)
    if quoted is not None:
        at, written, message = quoted
        raise config_error(file, where, (*prefix, *at), message, got=written)
    return valid


def _truth(literal: bool) -> str:
    """What a truth value may be written as: ``true``/``false`` in a config; a toggle's 0/1 too
    where a controller sends it (:func:`validate` without ``literal``)."""
    return "should be true or false" if literal else "should be true, false, 0 or 1"


def _toggle(data: Any) -> bool:
    """Whether ``data`` is a number, as a Max or Pd toggle sends for a truth value (0 or 1:
    pydantic refuses any other for a truth value)."""
    return isinstance(data, (int, float)) and not isinstance(data, bool)


def _wanted(what: str, data: Any) -> str:
    """The message for ``data`` written where ``what`` is wanted."""
    return f"should be {what}, not text: write it without quotes" if isinstance(data, str) else f"should be {what}"


def _numeral(data: Any) -> bool:
    """Whether ``data`` is a truth value or text that reads as a number (``"0.5"``), which lax
    mode takes for a number; other text that became a number is a name a field's validator
    reads (a note name, ``"F2"``)."""
    if isinstance(data, bool):
        return True
    if not isinstance(data, str):
        return False
    try:
        float(data)
    except ValueError:
        return False
    return True


def _quoted_scalar(valid: Any, data: Any, at: tuple[str | int, ...] = (), *,
                   toggles: bool = False) -> tuple[tuple, Any, str] | None:
    """The first number or truth value the author wrote as something else (``alpha = "0"``,
    ``midi = 1``), as ``(key path, what was written, the error's message)``, else ``None``.
    With ``toggles`` (a value sent, not written: the console's ``set``) a number may be text
    and a truth value 0 or 1, but a truth value is still never text: lax mode would take
    "yes", "on", "t" or "off" for one, which no config takes.

    Pydantic's lax mode, which the schema needs (TOML arrays fill tuple fields), reads text as
    a number and 0/1 as a truth value; a config is a program the artist wrote, and a number in
    quotes is a slip to point at, not a value to guess. Strict mode cannot be used instead: it
    refuses an array for a tuple field. So the validated values are walked beside the data:
    where a number came from text, or a truth value from anything but ``true``/``false``.
    """
    if isinstance(valid, bool):
        if isinstance(data, bool) or toggles and _toggle(data):
            return None
        return at, data, _truth(False) if toggles else _wanted("true or false", data)
    if isinstance(valid, (int, float)):
        return (at, data, _wanted("a number", data)) if not toggles and _numeral(data) else None
    if isinstance(valid, BaseModel):
        if isinstance(data, list):  # a before-validator moved a list into a field (``[[input]]``)
            nested = [getattr(valid, name) for name in type(valid).model_fields]
            return next((found for value in nested if isinstance(value, list) and len(value) == len(data)
                         if (found := _quoted_scalar(value, data, at, toggles=toggles)) is not None), None)
        if not isinstance(data, dict):
            return None
        pairs = [(name, getattr(valid, name)) for name in type(valid).model_fields if name in data]
    elif isinstance(valid, dict) and isinstance(data, dict):
        pairs = [(key, valid[key]) for key in valid if key in data]
    elif isinstance(valid, (list, tuple)) and isinstance(data, list) and len(valid) == len(data):
        pairs = list(zip(range(len(data)), valid))
    else:
        return None
    return next((found for key, value in pairs
                 if (found := _quoted_scalar(value, data[key], (*at, key), toggles=toggles)) is not None), None)


SHOWN_NAMES = 12
"""Most valid names an error lists when none is near the one written: a body's 60 joints, or
every name a table could hold, buried the name that was wrong."""


def nearest(name: object, choices: typing.Iterable[str], what: str, *, n: int = 1) -> str:
    """The end of an error about a name that is not there: `` (did you mean 'neck'?)`` (the
    ``n`` nearest, nearest first: `` (did you mean 'neck.x', 'neck.y' or 'neck.z'?)``), else
    the valid ones, at most :data:`SHOWN_NAMES` (`` (joints: base, neck, head)``), so a typo's
    fix is in the message."""
    choices = list(choices)
    close = difflib.get_close_matches(str(name), choices, n=n)
    if close:
        ranked = sorted(close, key=lambda c: (-difflib.SequenceMatcher(None, str(name), c).ratio(), c))
        quoted = [repr(c) for c in ranked]
        return f" (did you mean {' or '.join([', '.join(quoted[:-1]), quoted[-1]] if len(quoted) > 1 else quoted)}?)"
    more = f" and {len(choices) - SHOWN_NAMES} more" if len(choices) > SHOWN_NAMES else ""
    return f" ({what}: {', '.join(choices[:SHOWN_NAMES]) or 'none'}{more})"


def nearest_file(name: str, base: Path) -> str:
    """The end of an error about a file a config names (relative to ``base``) that is not
    there, as :func:`nearest` ends one about a key: the nearest file in the folder it points
    into, written as the config would write it (`` (did you mean 'creatures/heron.toml'?)``),
    else the files of its suffix there. Names are compared without the folder, which every
    candidate shares (with it, any name was "near"). Nothing when the folder is absent too."""
    written = PurePath(name)
    folder = base / written.parent
    if not written.name or not folder.is_dir():
        return ""
    files = sorted(p.name for p in folder.iterdir() if p.is_file())
    close = difflib.get_close_matches(written.name, files, n=1)
    if close:
        return f" (did you mean {written.with_name(close[0]).as_posix()!r}?)"
    alike = [written.with_name(f).as_posix() for f in files if PurePath(f).suffix == written.suffix]
    return f" ({written.suffix or 'such'} files there: {', '.join(alike)})" if alike else ""


def not_a_file(name: str, base: Path) -> str:
    """Why the file a config names (relative to ``base``) cannot be read, for its error: not
    found, with the nearest file there; or a folder or a FIFO there, said as what it is (a
    folder "not found" sent the artist looking for a file that was never meant)."""
    file = base / name
    if file.exists():
        return f"is {kind_of(file.stat().st_mode)}, not a regular file (looked for {file})"
    return f"not found (looked for {file}){nearest_file(name, base)}"


def written_in(where: dict[tuple, tuple[Path, int]], key: tuple[str | int, ...], config: Path) -> Path:
    """The file that wrote ``key`` (an ``extends`` base, an included file), else ``config``:
    a path in a config is relative to the file that writes it."""
    return where.get(key, (config, 0))[0]


SHOWN_CHARS = 120
"""Longest value an error repeats back: the value is on the line the error names, and a list
of 300 creatures quoted whole was half a megabyte of one message."""


def _shown(value: Any) -> str:
    """``value`` as an error repeats it, cut to :data:`SHOWN_CHARS`."""
    text = repr(value)
    return text if len(text) <= SHOWN_CHARS else text[:SHOWN_CHARS - 1] + "…"


def config_error(
    file: Path,
    where: dict[tuple, tuple[Path, int]],
    loc: tuple[str | int, ...],
    message: str | None,
    *,
    choices: list[str] = (),
    got: Any = None,
) -> ConfigError:
    """A :class:`ConfigError` at key path ``loc``; ``message=None`` means "unknown key"."""
    key = ".".join(str(p) for p in loc)
    line = None
    for n in range(len(loc), 0, -1):
        if loc[:n] in where:
            file, line = where[loc[:n]]
            break
    if message is None:
        close = difflib.get_close_matches(str(loc[-1]), list(choices), n=1)
        message = "unknown key" + (f" (did you mean {close[0]!r}?)" if close else "")
    elif got is not None:
        message += f" (got {_shown(got)})"
    return ConfigError(file, message, key=key, line=line)


def load_config(path: str | Path, model: type[Model]) -> Model:
    """Read, merge and validate a config; raise :class:`ConfigError` on the first problem."""
    data, where = read_toml(path)
    return validate(model, data, where, Path(path).resolve())
