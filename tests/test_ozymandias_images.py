"""ozymandias's image half (thesis, "off-line image processing – image creatures"): a graph of
frames by sum of squared differences with in-betweens as spokes, walked by a trivial behaviour
system the audio EDL commands, with motion blur that grows with traversals; video out."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from creatures.body.frames import FrameWriter
from creatures.image.footage import Footage, FootageError, cube_footage, load_footage
from creatures.image.image_graph import ImageGraph
from creatures.image.spec import IMAGES_KIND
from creatures.image.video import Blur
from creatures.image.walker import Command, ImageCreature, Shot
from creatures.kinds.ozymandias import read_edl
from creatures.persist import load_json
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "installations" / "ozymandias.toml"
FPS = 25.0


def bar_footage(period: int = 40, count: int = 400) -> Footage:
    """A bright bar sweeping across the frame once every ``period`` frames: a pure loop."""
    frames = np.zeros((count, 24, 80, 3), np.uint8)
    for f in range(count):
        x = int(80 * (f % period) / period)
        frames[f, :, x : x + 4] = 255
    return Footage(frames, FPS)


def test_jumps_join_frames_that_look_alike():
    """The SSD metric finds the loop: every jump from a key lands on a key that looks like the
    one after it (the same phase of the sweep), never elsewhere."""
    graph = ImageGraph.build(bar_footage(), subsample=10, jumps=3)
    assert graph.jumps > 0
    rows, cols = graph.matrix.nonzero()
    jumps = [(a, b) for a, b in zip(rows, cols) if b != a + 1]
    assert jumps and all(b % 10 == 0 for a, b in jumps)  # onto keys only; the rest are spokes
    assert any(a == 399 for a, b in jumps)  # the last frame has a way on
    inner = [(a, b) for a, b in jumps if a != 399]
    assert all(a % 10 == 0 for a, b in inner) and all((b - (a + 10)) % 40 == 0 for a, b in inner)


def test_a_path_goes_back_in_time_through_the_graph():
    """A target behind the walker is reached through jumps (not a cut), every step an edge."""
    graph = ImageGraph.build(bar_footage(), subsample=10, jumps=3)
    path = graph.path(350, 12)
    assert path is not None and path[-1] == 12
    node = 350
    for nxt in path:
        assert graph.matrix[node, nxt] > 0
        node = nxt
    assert len(path) < 30  # a handful of jumps, not 338 frames of playing on


def test_footage_with_no_way_back_is_cut_to_and_counted():
    frames = np.stack([np.full((16, 16, 3), i, np.uint8) for i in range(0, 250, 5)])  # a fade: nothing repeats
    footage = Footage(frames, FPS)
    graph = ImageGraph.build(footage, subsample=10, jumps=0)
    walker = ImageCreature(footage, graph, [Command(0.4, 0.8, 0.1, 0.5)], fps=FPS)
    shots = walker.run(1.0)
    commanded = [s for s in shots if s.command is not None]
    assert walker.walk.cuts == 1 and sum(s.cut for s in shots) == 1
    assert all(int(s.command.source * FPS) <= s.nodes[-1] <= int(s.command.source_end * FPS) + 1 for s in commanded)


def test_between_commands_the_footage_plays_on():
    footage = bar_footage()
    walker = ImageCreature(footage, ImageGraph.build(footage), [], fps=FPS)
    shots = walker.run(2.0)
    assert [s.nodes[-1] for s in shots] == list(range(1, 51))  # drift: one natural step a frame


def test_blur_grows_with_how_often_nodes_were_traversed():
    footage = bar_footage()
    blur = Blur(footage, blur=1.5, max_blur=12)
    first = [blur.compose(Shot(k / FPS, [k], None))[2] for k in range(40)]
    for _ in range(15):  # the same stretch read again and again
        again = [blur.compose(Shot(k / FPS, [k], None))[2] for k in range(40)]
    assert max(first) <= 1 and min(again[12:]) >= 4 and max(again) <= 12
    image, summed, tail = blur.compose(Shot(0.0, [1, 2, 3], None))
    assert summed == 3 + tail and image.dtype == np.uint8  # travel is blurred along the path


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[Path, dict]:
    """The shipped installation, its traveller writing video from its EDL (generated speech)."""
    out = tmp_path_factory.mktemp("ozy-images")
    inst = load_installation(CONFIG)
    inst.settings.output.report = False
    summary = run_offline(inst, out, duration=20.0)
    assert {"images traveller", "video traveller"} <= set(summary.files)
    return out, load_json(out / "traveller.images.json", kind=IMAGES_KIND)


def test_frame_selection_follows_the_edl_source_times(run):
    """≥ 90 % of the frames shown while a part sounds come from that part's time in the
    recording (the footage's frame f is the recording's time f / fps)."""
    out, images = run
    fps = images["fps"]
    edl = read_edl(out / "traveller.edl.json")
    commanded = [f for f in images["frames"] if f["source"] is not None]
    assert len(edl["entries"]) >= 10 and len(commanded) >= 40
    inside = [int(f["source"] * fps) <= f["node"] <= int(np.ceil(f["source_end"] * fps)) for f in commanded]
    assert np.mean(inside) >= 0.9
    # and not by playing the footage as it ran: most parts are read out of time
    assert np.mean([abs(f["node"] / fps - f["time"]) > 1.0 for f in commanded]) > 0.5
    assert images["graph"]["jumps"] > 0 and not any(f["cut"] for f in images["frames"])


def test_the_video_holds_one_frame_per_output_frame(run):
    out, images = run
    video = iio.imread(out / "traveller.mp4")
    assert len(video) == len(images["frames"]) == int(np.ceil(20.0 * images["fps"]))
    assert video.shape[1:] == (120, 160, 3) and video[len(video) // 2].std() > 10  # a picture, not blank
    # material wears with reading: frames of often-traversed footage are blurred longer
    tail = np.array([f["tail"] for f in images["frames"]])
    visits = np.array([f["visits"] for f in images["frames"]])
    assert visits.max() >= 8 and (visits <= 2).sum() >= 10
    assert tail[visits >= 8].mean() >= tail[visits <= 2].mean() + 2


def _cube_files(tmp_path: Path) -> tuple[Footage, Path]:
    """A second of the cube, and the folder of its PNG frames (its video is ``cube.mp4`` beside)."""
    cube = cube_footage(duration=1.0, fps=FPS, size=(64, 48))
    pngs = tmp_path / "frames"
    writer = FrameWriter(directory=pngs, video=tmp_path / "cube.mp4", fps=FPS)
    for frame in cube.frames:
        writer.write(frame)
    writer.close()
    return cube, pngs


def test_footage_from_png_frames_and_from_a_video(tmp_path):
    cube, pngs = _cube_files(tmp_path)
    read = load_footage(pngs, fps=FPS, duration=1.0, size=(64, 48))
    assert np.array_equal(read.frames, cube.frames)
    video = load_footage(tmp_path / "cube.mp4", fps=FPS, duration=1.0, size=(64, 48))
    assert video.frames.shape == cube.frames.shape
    assert np.abs(video.frames.astype(int) - cube.frames).mean() < 8  # lossy, but the same pictures


def test_footage_past_the_memory_budget_waits_on_disk_and_reads_the_same(tmp_path, monkeypatch):
    """Footage is read at random, so it was held whole in memory: an hour-long run's cube was
    5.2 GB at its default 160×120. Past the budget its frames wait in an unlinked file in the
    run's folder, every path reading the same pictures."""
    from creatures.image import frame_store

    cube, pngs = _cube_files(tmp_path)
    in_memory = load_footage(tmp_path / "cube.mp4", fps=FPS, duration=1.0, size=(64, 48))
    scratch = tmp_path / "run"
    scratch.mkdir()
    monkeypatch.setattr(frame_store, "IN_MEMORY", 5 * 64 * 48 * 3)  # five frames
    for source in ("cube", pngs, tmp_path / "cube.mp4"):
        read = load_footage(source, fps=FPS, duration=1.0, size=(64, 48), scratch=scratch)
        assert isinstance(read.frames.base, np.memmap) or isinstance(read.frames, np.memmap)
        assert np.array_equal(read.frames, in_memory.frames if source == tmp_path / "cube.mp4" else cube.frames)
    assert list(scratch.iterdir()) == []  # nothing left in the run's folder
    graph = ImageGraph.build(load_footage("cube", fps=FPS, duration=1.0, size=(64, 48), scratch=scratch))
    assert graph.matrix.nnz == ImageGraph.build(cube).matrix.nnz


def test_no_room_for_footage_on_disk_is_a_clear_error(tmp_path, monkeypatch):
    import errno
    import os

    from creatures.image import frame_store

    def full(fd, offset, length):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(frame_store, "IN_MEMORY", 1)
    monkeypatch.setattr(os, "posix_fallocate", full)
    with pytest.raises(FootageError, match=f"cube: no room for .* GB of footage frames in {tmp_path}"):
        load_footage("cube", fps=FPS, duration=1.0, size=(64, 48), scratch=tmp_path)


def test_the_graph_of_long_footage_needs_little_more_memory_than_its_frames():
    """The graph's grey thumbnails were made from the whole footage as float32 at once: a
    5-minute cube's graph peaked at 2.7 GB of a 0.43 GB footage. Measured in a fresh process."""
    code = """
import resource
from creatures.image.footage import cube_footage
from creatures.image.image_graph import ImageGraph
footage = cube_footage(duration=60.0, fps=25.0, size=(160, 120))
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
ImageGraph.build(footage)
print(before, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""
    before, after = map(int, subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                                            cwd=ROOT).stdout.split())
    frames = 1500 * 160 * 120 * 3 / 1024  # kB, as ru_maxrss counts
    assert after - before < 0.25 * frames


def test_bad_footage_is_a_clear_error(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(FootageError, match="holds no PNG frames"):
        load_footage(tmp_path / "empty", fps=FPS, duration=1, size=(64, 48))
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    iio.imwrite(mixed / "a.png", np.zeros((10, 10, 3), np.uint8))
    iio.imwrite(mixed / "b.png", np.zeros((12, 10, 3), np.uint8))
    with pytest.raises(FootageError, match="b.png: frame is 10×12, the first was 10×10"):
        load_footage(mixed, fps=FPS, duration=1, size=(64, 48))
    (tmp_path / "broken.mp4").write_bytes(b"not a video")
    with pytest.raises(FootageError, match="broken.mp4: not a readable video"):
        load_footage(tmp_path / "broken.mp4", fps=FPS, duration=1, size=(64, 48))


def test_missing_footage_in_a_config_names_the_key_and_line(tmp_path):
    text = CONFIG.read_text().replace('footage = "cube"', 'footage = "nowhere/frames"')
    config = tmp_path / "ozy.toml"
    config.write_text(text)
    line = next(i for i, s in enumerate(text.splitlines(), 1) if s.startswith("footage"))
    done = subprocess.run([sys.executable, "-m", "creatures.cli", "offline", str(config), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 2
    assert f"{config}:{line}" in done.stderr and "creature.0.images.footage" in done.stderr
    assert "no footage at" in done.stderr and not (tmp_path / "o").exists()


def test_the_colonys_own_renders_as_footage_through_the_cli(run, tmp_path):
    """The thesis took its frames from sand:stone's renders: a bodied installation's frames/
    become the footage of `creatures images`, and the video is drawn from those pictures."""
    from creatures.body.render import BodyRenderer, RenderUnavailable

    try:
        BodyRenderer(64, 48).close()
    except RenderUnavailable as exc:
        pytest.skip(f"no GL platform: {exc}")
    out, _ = run
    renders = tmp_path / "wren"
    inst = load_installation(ROOT / "installations" / "wren.toml")
    inst.settings.output.frames, inst.settings.output.report = True, False
    inst.settings.output.width, inst.settings.output.height, inst.settings.output.fps = 96, 72, FPS
    run_offline(inst, renders, duration=8.0)  # the footage is shorter than the reading: clipped
    done = subprocess.run([sys.executable, "-m", "creatures.cli", "images", str(out), "--creature", "traveller",
                           "--footage", str(renders / "frames"), "--out", str(tmp_path / "v")],
                          capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    images = load_json(tmp_path / "v" / "traveller.images.json", kind=IMAGES_KIND)
    assert images["footage_frames"] == len(list((renders / "frames").glob("*.png")))
    video = iio.imread(tmp_path / "v" / "traveller.mp4")
    assert video.shape[1:] == (72, 96, 3) and len(video) == len(images["frames"])
    plain = [i for i, f in enumerate(images["frames"]) if f["blur"] == 1]  # unblurred: the render itself
    assert plain
    shown = iio.imread(renders / "frames" / f"frame_{images['frames'][plain[-1]]['node']:06d}.png")
    assert np.abs(video[plain[-1]].astype(int) - shown).mean() < 6  # up to the codec
    bad = subprocess.run([sys.executable, "-m", "creatures.cli", "images", str(out), "--creature", "nobody"],
                         capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode == 2 and "nobody.edl.json" in bad.stderr


def test_frames_made_again_shorter_leave_none_of_the_longer_behind(tmp_path):
    """``creatures images --png`` at a lower ``--fps`` into the same folder: the frames of the
    earlier, longer video stayed after the new ones, and a sequence made of the folder showed both."""
    from creatures.image.spec import ImagesSpec, make_video

    entries = [{"output_frame": 0, "source_start_frame": 8000, "source_end_frame": 16000}]
    for fps, count in ((10.0, 20), (5.0, 10)):
        spec = ImagesSpec(fps=fps, png=True, video=False, size=(32, 24))
        make_video(spec, "oz", entries, 8000, 2.0, tmp_path)
        assert len(list((tmp_path / "oz.frames").glob("frame_*.png"))) == count


def test_a_video_made_again_and_stopped_leaves_the_earlier_one_whole(tmp_path, monkeypatch):
    """``creatures images`` writes into a finished run: stopped part way (Ctrl-C, a full disk),
    it had already cut the run's video short; now the new one replaces it only once whole."""
    from creatures.image.spec import ImagesSpec, make_video

    entries = [{"output_frame": 0, "source_start_frame": 8000, "source_end_frame": 16000}]
    spec = ImagesSpec(fps=10.0, size=(32, 24))
    make_video(spec, "oz", entries, 8000, 2.0, tmp_path)
    before = (tmp_path / "oz.mp4").read_bytes()
    _stop_composing_after(1.0, monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        make_video(spec, "oz", entries, 8000, 2.0, tmp_path)
    assert (tmp_path / "oz.mp4").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["oz.images.json", "oz.mp4"]


def test_images_made_again_and_stopped_leave_the_last_ones_as_they_were(tmp_path, monkeypatch, capsys):
    """``creatures images --png`` stopped part way (Ctrl-C) had drawn its frames over the start
    of the last ones, beside the last video and record: now the folder is as it was."""
    from creatures.cli import main
    from creatures.kinds.ozymandias import EDL_KIND
    from creatures.persist import save_json
    from test_faults import _tree

    save_json(tmp_path / "oz.edl.json", {"sample_rate": 8000, "creature": "oz", "entries": [
        {"output_frame": 0, "source_start_frame": 8000, "source_end_frame": 16000, "gain": 1.0}]}, kind=EDL_KIND)
    images = ["images", str(tmp_path), "--creature", "oz", "--png", "--fps"]
    assert main([*images, "5"]) == 0
    before = _tree(tmp_path / "images")
    _stop_composing_after(0.5, monkeypatch)
    assert main([*images, "10"]) == 130
    assert _tree(tmp_path / "images") == before and len(list((tmp_path / "images" / "oz.frames").iterdir())) == 5
    assert "nothing was replaced" in capsys.readouterr().err


def _stop_composing_after(seconds: float, monkeypatch) -> None:
    """A Ctrl-C as the frame after ``seconds`` of output is composed."""
    from creatures.image import video as video_module

    composed = video_module.Blur.compose

    def stopped(self, shot):
        if shot.time > seconds:
            raise KeyboardInterrupt
        return composed(self, shot)

    monkeypatch.setattr(video_module.Blur, "compose", stopped)


def test_without_a_video_encoder_a_run_keeps_its_outputs_and_images_says_why(tmp_path, no_video_encoder, capsys,
                                                                               caplog):
    """The traveller's video is made when the run is over: without ffmpeg the run died there
    with a traceback and published nothing. Now it publishes all but the video and warns why;
    ``creatures images``, asked for a video, says why in a line (exit 2) before reading footage."""
    from creatures.cli import main

    inst = load_installation(CONFIG)
    inst.settings.output.report = False
    summary = run_offline(inst, tmp_path / "run", duration=2.0)
    assert {"edl traveller", "images traveller"} <= set(summary.files) and "video traveller" not in summary.files
    assert not list((tmp_path / "run").glob("*.mp4"))
    said = [r.getMessage() for r in caplog.records if "no video encoder" in r.getMessage()]
    assert len(said) == 1 and said[0].startswith("traveller: cannot write") and "without the video" in said[0]
    assert main(["images", str(tmp_path / "run"), "--creature", "traveller", "--out", str(tmp_path / "v")]) == 2
    err = capsys.readouterr().err
    assert "traveller.mp4" in err and "no video encoder" in err and "Traceback" not in err
    assert not (tmp_path / "v").exists() or not any((tmp_path / "v").iterdir())
