"""Run the project's benchmarks and print a table of numbers, targets and ratios.

Usage: ``python -m bench`` (all), ``python -m bench behaviour temporal``, ``--quick`` for a
smoke run, ``--json FILE`` to keep the numbers for comparison with later runs.
"""

from __future__ import annotations

import argparse
import importlib
import json
import pkgutil
import platform
import sys
import time
from pathlib import Path

import bench


def available() -> list[str]:
    return sorted(
        m.name for m in pkgutil.iter_modules(bench.__path__) if not m.name.startswith("_")
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench", description=__doc__)
    parser.add_argument("names", nargs="*", help=f"benchmarks to run (default all: {available()})")
    parser.add_argument("--quick", action="store_true", help="smaller sizes, for smoke tests")
    parser.add_argument("--json", type=Path, help="also write the results as JSON here")
    args = parser.parse_args(argv)
    names = args.names or available()
    unknown = sorted(set(names) - set(available()))
    if unknown:
        parser.error(f"unknown benchmark(s) {unknown}; choose from {available()}")

    results = []
    print(f"{'benchmark':<58} {'value':>14} {'unit':<12} {'target':>10}  {'ratio':>18}  ok")

    def show(name: str, row: bench.Row) -> None:
        mark = {True: "PASS", False: "FAIL", None: "-"}[row.passed]
        target = "" if row.target is None else f"{'≥' if row.higher_is_better else '≤'}{row.target:g}"
        ratio = "" if row.ratio is None else f"{row.ratio:.3g}× {row.baseline or ''}"
        print(f"{name + ': ' + row.name:<58} {row.value:>14.4g} {row.unit:<12} {target:>10}  {ratio:>18}  {mark}")
        results.append({"bench": name, **row.to_dict()})

    start = time.perf_counter()
    for name in names:
        module = importlib.import_module(f"bench.{name}")
        t0 = time.perf_counter()
        for row in module.run(quick=args.quick):
            show(name, row)
        print(f"  ({name} took {time.perf_counter() - t0:.1f} s)", file=sys.stderr)
    if not args.names and not args.quick:  # the whole suite must fit in 10 minutes on 2 cores
        show("all", bench.Row("every benchmark, wall time", time.perf_counter() - start, "s",
                              target=600.0, higher_is_better=False))
    if args.json:
        args.json.write_text(
            json.dumps({"python": platform.python_version(), "machine": platform.machine(), "results": results}, indent=1)
        )
    return 1 if any(r["passed"] is False for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
