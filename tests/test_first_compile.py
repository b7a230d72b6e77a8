"""A first run's long start is said: numba compiling the kernels (creatures/runtime/first_compile.py)."""

from __future__ import annotations

import io

import numba

from creatures.runtime import first_compile


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _compile_something(k: int) -> None:
    """A kernel numba has never seen (no cache): a real compile, with its event."""
    numba.njit(lambda x: x + k)(1.0)


def test_the_first_compile_of_a_command_is_said_once_on_a_terminal(monkeypatch):
    terminal = _Terminal()
    monkeypatch.setattr("sys.stderr", terminal)
    unsay = first_compile.say_first_compile()
    try:
        _compile_something(1)
        _compile_something(2)
    finally:
        unsay()
    assert terminal.getvalue() == f"creatures: {first_compile.NOTE}\n"
    _compile_something(3)  # the command is over: said no more
    assert terminal.getvalue().count("compiling") == 1


def test_captured_stderr_gets_no_line(monkeypatch):
    captured = io.StringIO()  # a test's, a service's journal
    monkeypatch.setattr("sys.stderr", captured)
    unsay = first_compile.say_first_compile()
    _compile_something(4)
    unsay()
    assert captured.getvalue() == ""
