"""Config text for tests of a running colony."""

from __future__ import annotations


def creature_tables(*names: str, kind: str = "exchange") -> str:
    """``[[creature]]`` tables for ``names``, all of ``kind``."""
    return "".join(f'[[creature]]\nname = "{name}"\nkind = "{kind}"\n' for name in names)
