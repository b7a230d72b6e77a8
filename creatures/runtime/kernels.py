"""Every compiled kernel loaded before the show, not at its first call mid-run.

numba compiles (or loads from its on-disk cache) a ``@njit(cache=True)`` kernel for each
argument types it is called with, the first time: 10–100 ms on the loop thread. The
rehearsal (:func:`creatures.runtime.live.rehearse`) calls what one second of the colony
calls, but not a path taken later (a body's first seek after a minute, a blend first used
when a creature rests); an audit of a live run found a cache load mid-run. So after the
rehearsal every kernel of the project's loaded modules takes every overload its cache
holds for the code as it is now: loading, never compiling (an entry for other code, or
another machine, is skipped).
"""

from __future__ import annotations

import sys
from types import ModuleType
from typing import Iterable

from numba.core.registry import CPUDispatcher

PACKAGES = ("creatures", "midi", "audio")
"""The project's packages, whose loaded modules' kernels are warmed."""


def project_modules() -> list[ModuleType]:
    """The project's modules loaded so far."""
    return [module for name, module in list(sys.modules.items())
            if module is not None and name.split(".")[0] in PACKAGES]


def warm(modules: Iterable[ModuleType]) -> int:
    """Load every cached overload of every kernel in ``modules``; how many were loaded.

    Reads numba's cache index through its dispatcher (``_cache``: numba has no public call
    for "load what is cached"); an index numba cannot read is skipped, as numba itself does.
    """
    loaded = 0
    seen: set[int] = set()
    for module in modules:
        for kernel in list(vars(module).values()):
            if not isinstance(kernel, CPUDispatcher) or id(kernel) in seen:
                continue
            seen.add(id(kernel))
            loaded += _load_cached(kernel)
    return loaded


def _load_cached(kernel: CPUDispatcher) -> int:
    cache = getattr(kernel, "_cache", None)
    index = getattr(getattr(cache, "_cache_file", None), "_load_index", None)
    if index is None:
        return 0
    try:
        keys = list(index())
    except Exception:  # a stale or foreign index: numba ignores it too
        return 0
    codegen = kernel.targetctx.codegen()
    loaded = 0
    for key in keys:
        signature = key[0]
        if signature in kernel.overloads or key != cache._index_key(signature, codegen):
            continue  # loaded already, or compiled for other code or another machine
        kernel.compile(signature)
        loaded += 1
    return loaded
