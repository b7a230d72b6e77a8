"""bench voice's peers failing: a Csound that will not render, or a pyrender that cannot be
loaded, leaves our rows standing (without a ratio) and a row that says skipped and why, instead
of ending the benchmark with a traceback."""

from __future__ import annotations

import math
import re
import shutil

import numpy as np
import pytest

import bench._peers
import bench.voice as voice
import creatures.body.render


def test_a_failing_csound_is_a_skipped_row_with_its_error(monkeypatch) -> None:
    def broken(**kwargs):
        raise RuntimeError("csound failed on strings.csd: ['INIT ERROR in instr 1: scantable: ...']")

    monkeypatch.setattr(voice, "csound_string_seconds", broken)
    monkeypatch.setattr(voice, "_pool_seconds", lambda masses, voices, seconds, repeat, interpolation: 0.5)
    rows = voice._peer_rows(quick=True)
    skipped = [r for r in rows if "skipped" in r.name]
    assert len(skipped) == 5 and all("INIT ERROR" in r.name and math.isnan(r.value) for r in skipped)
    ours = [r for r in rows if "VoicePool" in r.name]
    assert len(ours) == 6 and all(r.ratio is None and r.target is None and r.value > 0 for r in ours)


class FakeRenderer:
    """A body renderer without GL."""

    camera_pose = np.eye(4)

    def __init__(self, width: int, height: int) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        pass

    def render(self, positions, parents, notes, out=None) -> None:
        pass


def test_a_pyrender_that_cannot_load_leaves_our_frames_and_says_why(monkeypatch) -> None:
    def missing(*args, **kwargs):
        raise ImportError("No module named 'pyrender'")

    monkeypatch.setattr(creatures.body.render, "BodyRenderer", FakeRenderer)
    monkeypatch.setattr(bench._peers, "PyrenderBodies", missing)
    rows = voice._render_rows(quick=True)
    assert [("skipped" in r.name) for r in rows] == [False, True, False, True]
    assert all("No module named 'pyrender'" in r.name for r in rows[1::2])
    three = rows[2]
    assert three.target == 120.0 and three.passed and three.ratio is None


def test_the_csound_row_names_the_version_that_ran(monkeypatch) -> None:
    monkeypatch.setattr(voice, "csound_string_seconds", lambda **kwargs: 1.0)
    monkeypatch.setattr(voice, "csound_version", lambda: "7.0")
    monkeypatch.setattr(voice, "_pool_seconds", lambda masses, voices, seconds, repeat, interpolation: 0.5)
    peers = [r for r in voice._peer_rows(quick=True) if "scantable, same run" in r.name]
    assert len(peers) == 5 and all("Csound 7.0 scantable" in r.name for r in peers)


def test_the_installed_csound_gives_its_version() -> None:
    if shutil.which("csound") is None:
        pytest.skip("csound is not installed")
    assert re.fullmatch(r"\d+(\.\d+)+", bench._peers.csound_version())
