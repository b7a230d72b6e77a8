"""Compiled kernels warmed before the show (creatures/runtime/kernels.py): what numba's cache
holds is loaded, for the code as it is, before the first call."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

KERNEL = textwrap.dedent("""
    import numba

    @numba.njit(cache=True)
    def twice(x):
        return 2 * x
""")

FIRST_RUN = "import kernel_module as k; print(k.twice(3), k.twice(1.5))"

SECOND_RUN = textwrap.dedent("""
    import sys, kernel_module as k
    from creatures.runtime import kernels
    before = len(k.twice.signatures)
    loaded = kernels.warm([k])
    print(before, loaded, len(k.twice.signatures), kernels.warm([k]))
""")


def _run(code: str, tmp_path) -> str:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join([str(tmp_path), os.getcwd(), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True,
                          timeout=300).stdout.split()


def test_every_cached_overload_is_loaded_before_its_first_call(tmp_path) -> None:
    (tmp_path / "kernel_module.py").write_text(KERNEL)
    assert _run(FIRST_RUN, tmp_path) == ["6", "3.0"]  # two overloads (int, float) now cached
    assert _run(SECOND_RUN, tmp_path) == ["0", "2", "2", "0"]  # none before, both loaded, once


def test_an_overload_cached_for_other_code_is_not_compiled(tmp_path) -> None:
    (tmp_path / "kernel_module.py").write_text(KERNEL)
    _run(FIRST_RUN, tmp_path)
    (tmp_path / "kernel_module.py").write_text(KERNEL.replace("2 * x", "3 * x"))
    assert _run(SECOND_RUN, tmp_path) == ["0", "0", "0", "0"]
