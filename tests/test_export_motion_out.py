"""``creatures export-motion RUN OUT``: OUT is written whole or not at all, and never in place of
something that is not a take (the run's log, a creature's learned state, a folder)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from creatures.cli import main
from creatures.motor.bvh import save_bvh
from creatures.motor.animations import creature_skeleton, strike


@pytest.mark.parametrize("name, text", [("events.jsonl", '{"kind": "run", "t": 0.0}\n'),
                                        ("heron.json", '{"format": "creature-music creature state"}\n')])
def test_an_out_that_is_not_a_bvh_is_refused_and_kept(tmp_path: Path, capsys, name: str, text: str):
    """The two paths swapped, or a state file given as OUT: refused before anything is read
    (the run folder here holds nothing to export), the file kept byte for byte."""
    kept = tmp_path / name
    kept.write_text(text)
    assert main(["export-motion", str(tmp_path), str(kept), "--creature", "heron"]) == 2
    err = capsys.readouterr().err
    assert f"{kept}: exists and is not a BVH file" in err and "Traceback" not in err
    assert kept.read_text() == text


def test_a_folder_as_out_is_refused_with_a_file_to_give(tmp_path: Path, capsys):
    assert main(["export-motion", str(tmp_path), str(tmp_path), "--creature", "heron"]) == 2
    assert f"{tmp_path}: is a folder; give the BVH file to write (e.g. {tmp_path / 'motion.bvh'})" in \
        capsys.readouterr().err


def test_a_take_that_fails_to_write_leaves_the_previous_one(tmp_path: Path, monkeypatch):
    """A full disk (or Ctrl-C) while the take is written: the earlier take stays whole."""
    animation = strike(creature_skeleton())
    out = tmp_path / "take.bvh"
    save_bvh(out, animation)
    before = out.read_bytes()

    def full(fd: int) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OSError, match="No space left"):
        save_bvh(out, animation.subset(list(range(len(animation) // 2))))
    assert out.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["take.bvh"]  # no temporary file left
