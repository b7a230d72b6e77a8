"""``python -m bench`` writes its table as JSON, compares with an earlier run, and gives a
benchmark that runs beside the others (the soak) a core of its own."""

from __future__ import annotations

import json
import os
import sys
import types

import pytest

import bench
from bench import Row
from bench import __main__ as runner


@pytest.fixture
def affinity():
    """Restore this process's CPU set after a test that pins it."""
    if not hasattr(os, "sched_getaffinity"):
        pytest.skip("this OS cannot pin a process to CPUs")
    cpus = os.sched_getaffinity(0)
    yield cpus
    os.sched_setaffinity(0, cpus)


def fake_bench(monkeypatch, name: str, **functions) -> None:
    """Install ``bench.<name>`` with ``functions`` (``run``, ``start``) as a benchmark module."""
    module = types.ModuleType(f"bench.{name}")
    for key, fn in functions.items():
        setattr(module, key, fn)
    monkeypatch.setitem(sys.modules, f"bench.{name}", module)
    known = [n for n in runner.available() if n != name]
    monkeypatch.setattr(runner, "available", lambda: sorted([*known, name]))


def test_results_are_written_and_compared(tmp_path, monkeypatch, capsys, affinity):
    fake_bench(monkeypatch, "steady", run=lambda quick: [Row("ticks/s", 400.0, "1/s", target=200.0)])
    first, second = tmp_path / "first.json", tmp_path / "second.json"
    assert runner.main(["steady", "--json", str(first)]) == 0
    saved = json.loads(first.read_text())["results"]
    assert saved == [{"bench": "steady", **Row("ticks/s", 400.0, "1/s", target=200.0).to_dict()}]
    assert saved[0]["passed"] is True
    first.write_text(first.read_text().replace("400.0", "800.0"))  # an earlier, faster run
    assert runner.main(["steady", "--json", str(second), "--compare", str(first)]) == 0
    assert "0.5× prev" in capsys.readouterr().out


def test_a_failed_target_makes_the_run_fail(tmp_path, monkeypatch, affinity):
    fake_bench(monkeypatch, "steady", run=lambda quick: [Row("ticks/s", 100.0, "1/s", target=200.0)])
    assert runner.main(["steady", "--json", str(tmp_path / "r.json")]) == 1


def test_a_benchmark_beside_the_others_gets_a_core_they_do_not_use(tmp_path, monkeypatch, affinity):
    if len(affinity) < 2:
        pytest.skip("one CPU: benchmarks run in turn")
    seen: dict[str, object] = {}

    def start(quick: bool, cpu: int | None) -> object:
        seen["cpu"] = cpu
        return lambda: [Row("beside", 1.0, "runs")]

    def run(quick: bool) -> list[Row]:
        seen["others ran on"] = os.sched_getaffinity(0)
        return [Row("in turn", 1.0, "runs")]

    fake_bench(monkeypatch, "beside", start=start, run=lambda quick: pytest.fail("a beside bench ran in turn"))
    fake_bench(monkeypatch, "steady", run=run)
    out = tmp_path / "r.json"
    assert runner.main(["beside", "steady", "--json", str(out)]) == 0
    assert seen["cpu"] in affinity and seen["cpu"] not in seen["others ran on"]
    assert [r["bench"] for r in json.loads(out.read_text())["results"]] == ["steady", "beside"]


def test_format_row_marks_pass_and_fail():
    assert bench.format_row("x", Row("a", 1.0, "s", target=2.0, higher_is_better=False)).endswith("PASS")
    assert bench.format_row("x", Row("a", 3.0, "s", target=2.0, higher_is_better=False)).endswith("FAIL")


def test_a_row_without_a_number_is_not_given_a_ratio_to_the_previous_run():
    from bench._peers import skipped

    skip = skipped("peer", "not installed")
    assert bench.format_row("x", skip, float("nan")).endswith("(prev nan)")
    unanswered = Row("latency p99", float("inf"), "ms", target=5.0, higher_is_better=False)
    line = bench.format_row("x", unanswered, 2.5)
    assert line.endswith("FAIL  (prev 2.5)") and "× prev" not in line
    assert bench.format_row("x", Row("latency p99", 5.0, "ms"), 2.5).endswith("2× prev")


def test_a_benchmark_that_raises_fails_the_run_but_keeps_the_others_rows(tmp_path, monkeypatch, capsys, affinity):
    def broken(quick: bool) -> list[Row]:
        raise IndexError("index -1 is out of bounds for axis 0 with size 0")

    fake_bench(monkeypatch, "broken", run=broken)
    fake_bench(monkeypatch, "steady", run=lambda quick: [Row("ticks/s", 400.0, "1/s", target=200.0)])
    out = tmp_path / "r.json"
    assert runner.main(["broken", "steady", "--json", str(out)]) == 1
    saved = json.loads(out.read_text())["results"]
    assert [(r["bench"], r["passed"]) for r in saved] == [("broken", False), ("steady", True)]
    assert saved[0]["name"] == "crashed: IndexError: index -1 is out of bounds for axis 0 with size 0"
    assert "Traceback" in capsys.readouterr().err


def test_a_benchmark_that_cannot_be_imported_is_a_failing_row(tmp_path, monkeypatch, affinity):
    fake_bench(monkeypatch, "unloadable", run=lambda quick: [])
    monkeypatch.setitem(sys.modules, "bench.unloadable", None)  # importing it raises ImportError
    fake_bench(monkeypatch, "steady", run=lambda quick: [Row("ticks/s", 400.0, "1/s", target=200.0)])
    out = tmp_path / "r.json"
    assert runner.main(["unloadable", "steady", "--json", str(out)]) == 1
    saved = json.loads(out.read_text())["results"]
    assert [(r["bench"], r["passed"]) for r in saved] == [("unloadable", False), ("steady", True)]
    assert saved[0]["name"].startswith("crashed: ModuleNotFoundError")


def test_the_results_file_is_strict_json_and_a_skipped_row_reads_back(tmp_path, monkeypatch, capsys, affinity):
    from bench._peers import skipped

    def strict(constant: str) -> None:
        pytest.fail(f"{constant} is not JSON")

    fake_bench(monkeypatch, "peers", run=lambda quick: [skipped("peer", "not installed"),
                                                        Row("wait p99", float("inf"), "ms", target=5.0, higher_is_better=False)])
    first = tmp_path / "first.json"
    assert runner.main(["peers", "--json", str(first)]) == 1  # the infinite wait fails its target
    saved = json.loads(first.read_text(), parse_constant=strict)["results"]
    assert [r["value"] for r in saved] == ["nan", "inf"]
    assert runner.main(["peers", "--json", str(tmp_path / "second.json"), "--compare", str(first)]) == 1
    assert "(prev nan)" in capsys.readouterr().out
