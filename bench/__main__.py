"""Run the project's benchmarks and print a table of numbers, targets and ratios.

Usage: ``python -m bench`` (all), ``python -m bench behaviour temporal``, ``--quick`` for a
smoke run. Every run writes its numbers as JSON (``bench-results-<UTC time>.json`` in the
current directory, or ``--json FILE``) so later runs can be compared: ``--compare FILE``
prints each number's ratio to the same row of that earlier run.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import pkgutil
import platform
import sys
import time
import traceback
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable

import bench


def available() -> list[str]:
    return sorted(
        m.name for m in pkgutil.iter_modules(bench.__path__) if not m.name.startswith("_")
    )


def previous_values(path: Path) -> dict[tuple[str, str], float]:
    """``(bench, row name) → value`` of an earlier run's JSON (rows whose name carries a
    measured number, e.g. a size, only match runs of the same size)."""
    try:
        results = json.loads(path.read_text())["results"]
        return {(r["bench"], r["name"]): float(r["value"]) for r in results}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SystemExit(f"python -m bench: cannot compare with {path}: {exc}") from None


def spare_core() -> int | None:
    """A CPU for the benchmarks that run beside the others (modules with ``start(quick, cpu)``),
    taken off this process's own set; None on a one-CPU machine, where they run in turn.

    A 2-core machine runs the suite in its 10 minutes only by using both: the day-long soak
    takes one core for most of the run while every other benchmark measures on the other.
    Pinning keeps the two from taking turns on the same core, so neither's numbers are
    disturbed by the other beyond what shared caches and memory do."""
    if not hasattr(os, "sched_setaffinity"):
        return None
    cpus = os.sched_getaffinity(0)
    if len(cpus) < 2:
        return None
    spare = max(cpus)
    os.sched_setaffinity(0, cpus - {spare})
    return spare


def crashed(exc: Exception) -> bench.Row:
    """A failing row for a benchmark that raised ``exc`` (its traceback goes to stderr): the run
    keeps the rows of every other benchmark, in the table and the JSON, and still fails."""
    traceback.print_exception(exc)
    return bench.Row(f"crashed: {type(exc).__name__}: {exc}", float("nan"), "", target=0.0)


def rows_of(measure: Callable[..., list[bench.Row]], **kwargs: Any) -> list[bench.Row]:
    """``measure(**kwargs)``'s rows, or one :func:`crashed` row where it raises."""
    try:
        return list(measure(**kwargs))
    except Exception as exc:
        return [crashed(exc)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench", description=__doc__)
    parser.add_argument("names", nargs="*", help=f"benchmarks to run (default all: {available()})")
    parser.add_argument("--quick", action="store_true", help="smaller sizes, for smoke tests")
    parser.add_argument("--json", type=Path, help="write the results here (default bench-results-<UTC time>.json)")
    parser.add_argument("--compare", type=Path, metavar="PREV.json", help="print ratios to an earlier run's results")
    args = parser.parse_args(argv)
    names = args.names or available()
    unknown = sorted(set(names) - set(available()))
    if unknown:
        parser.error(f"unknown benchmark(s) {unknown}; choose from {available()}")
    previous = previous_values(args.compare) if args.compare else {}
    started = datetime.now(timezone.utc)
    out = args.json or Path(f"bench-results-{started:%Y%m%dT%H%M%SZ}.json")

    results: list[dict[str, Any]] = []
    print(bench.HEADER + ("  vs prev" if args.compare else ""))

    def show(name: str, row: bench.Row) -> None:
        print(bench.format_row(name, row, previous.get((name, row.name))))
        results.append({"bench": name, **row.to_dict()})

    start = time.perf_counter()
    modules = {}
    for name in names:
        try:
            modules[name] = importlib.import_module(f"bench.{name}")
        except Exception as exc:  # a peer's package broken on import, say: the other benchmarks still run
            show(name, crashed(exc))
    cpu = spare_core() if any(hasattr(m, "start") for m in modules.values()) else None
    beside = {name: module.start(quick=args.quick, cpu=cpu) for name, module in modules.items()
              if hasattr(module, "start") and cpu is not None}
    for name, module in modules.items():
        if name in beside:
            continue
        t0 = time.perf_counter()
        for row in rows_of(module.run, quick=args.quick):
            show(name, row)
        print(f"  ({name} took {time.perf_counter() - t0:.1f} s)", file=sys.stderr)
    for name, finish in beside.items():
        for row in rows_of(finish):
            show(name, row)
        print(f"  ({name}, beside the others, took {time.perf_counter() - start:.1f} s)", file=sys.stderr)
    if not args.names and not args.quick:  # the whole suite must fit in 10 minutes on 2 cores
        show("all", bench.Row("every benchmark, wall time", time.perf_counter() - start, "s",
                              target=600.0, higher_is_better=False))
    record = {"started": started.isoformat(timespec="seconds"), "argv": sys.argv[1:] if argv is None else argv,
              "python": platform.python_version(), "machine": platform.machine(), "results": results}
    try:
        out.write_text(json.dumps(record, indent=1))
    except OSError as exc:  # the table above is still the run's record
        print(f"python -m bench: cannot write {out}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    print(f"results written to {out}")
    return 1 if any(r["passed"] is False for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
