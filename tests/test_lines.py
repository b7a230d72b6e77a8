"""curve's platform, its drawing half (thesis, "curve (technology)"): drawings read in as
animation (SVG paths become a line creature's body, "a piece of paper, a pen and a scanner"),
and the line renderer beside the mesh one (SVG, and PostScript as the thesis did)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import directed_hausdorff

from creatures.body.lines import Page, draw
from creatures.motor.spline import SplinePose, catmull_rom, strokes
from creatures.motor.drawing import DrawingError, drawing_lines, read_drawing, resample
from creatures.runtime.offline import run_offline
from creatures.runtime.schema import load_installation
from test_faults import _tree

ROOT = Path(__file__).resolve().parents[1]
SCRIBBLE = ROOT / "installations" / "scribble.toml"
CHROMIUM = os.environ.get("CREATURES_CHROMIUM", "/usr/bin/chromium")


def hausdorff(a: np.ndarray, b: np.ndarray) -> float:
    return max(directed_hausdorff(a, b)[0], directed_hausdorff(b, a)[0])


def as_line(points: np.ndarray) -> np.ndarray:
    """A polyline as the shape it draws (dense points along its segments, not its vertices)."""
    return resample(points, 4000)


def test_a_drawing_plays_back_as_a_body_of_the_same_shape(tmp_path):
    """Hausdorff distance between the drawn path and the body's bones ≤ 1 % of the drawing's size."""
    path = tmp_path / "heron.svg"
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="400" height="300">'
                    '<g transform="translate(5 10) scale(1.5)">'
                    '<path d="M 30 180 C 80 60, 150 60, 200 140 S 250 200, 255 80" fill="none" stroke="black"/></g>'
                    '</svg>')
    take = read_drawing(path)
    (line,), joints, _ = drawing_lines(path)
    body = take.skeleton.forward_kinematics(take.rotations, take.roots)[0]
    assert joints == take.skeleton.joint_count == 48 and np.allclose(body[:, 2], 0)
    drawn = line - line[0]  # the body stands at the origin
    size = np.ptp(drawn, axis=0).max()
    assert hausdorff(as_line(body[:, :2]), drawn) <= 0.01 * size
    # and the metric bites: the same body with one joint bent by 20° is far off
    bent = take.rotations.copy()
    bent[0, 20] = [np.cos(0.17), 0, 0, np.sin(0.17)]
    moved = take.skeleton.forward_kinematics(bent, take.roots)[0]
    assert hausdorff(as_line(moved[:, :2]), drawn) > 0.03 * size


def test_every_frame_of_the_shipped_drawing_is_a_pose_of_the_scribbles_body():
    """installations/bodies/line.svg through [creature.body] (the motor graph's own poses)."""
    inst = load_installation(SCRIBBLE)
    graph = inst.specs[0].body.material().graph
    lines, _, _ = drawing_lines(ROOT / "installations" / "bodies" / "line.svg")
    poses = graph.poses
    assert len(poses) >= len(lines) and {"rest", "reach", "wave", "curl"} <= set().union(*poses.labels)
    for k in (0, 10, 25, 40):
        node = int(np.flatnonzero(np.isclose(poses.times, k * 0.08333))[0])  # the node of frame k
        body = poses.positions[node][:, :2]
        drawn = (lines[k] - lines[0][0]) * 0.01  # scale 0.01: user units to metres
        assert hausdorff(as_line(body), drawn) <= 0.01 * np.ptp(drawn, axis=0).max(), k


@pytest.mark.parametrize("text, message", [
    ("<svg xmlns='http://www.w3.org/2000/svg'><path d='M 0 0 L 10 0'></svg>", r":1: not well-formed SVG"),
    ("<svg xmlns='http://www.w3.org/2000/svg'><rect width='0' height='0'/></svg>", "holds no path"),
    ("<svg xmlns='http://www.w3.org/2000/svg'><path d='M 0 0 L 100 0'/><path d='M 0 0 L 150 0'/></svg>",
     "shape 1 is 100 long, the frames' mean is 125"),
    ("<svg xmlns='http://www.w3.org/2000/svg' data-joints='2'><path d='M 0 0 L 10 0'/></svg>", "data-joints='2'"),
    ("<svg xmlns='http://www.w3.org/2000/svg' data-frame-time='nan'><path d='M 0 0 L 10 0'/></svg>",
     "data-frame-time='nan'"),
])
def test_a_bad_drawing_is_a_clear_error(tmp_path, text, message):
    path = tmp_path / "bad.svg"
    path.write_text(text)
    with pytest.raises(DrawingError, match=re.escape(message) if not message.startswith(":") else message):
        read_drawing(path)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=300) | st.text(max_size=300).map(
    lambda s: f"<svg xmlns='http://www.w3.org/2000/svg'><path d='{s}'/></svg>".encode()))
def test_fuzzed_drawings_never_crash_the_reader(tmp_path, data):
    path = tmp_path / "fuzz.svg"
    path.write_bytes(data)
    try:
        take = read_drawing(path)
    except DrawingError as exc:
        assert str(path) in str(exc)
    else:
        assert np.isfinite(take.rotations).all() and np.isfinite(take.roots).all()


def test_a_bad_drawing_in_a_config_names_the_file(tmp_path):
    (tmp_path / "bodies").mkdir()
    (tmp_path / "bodies" / "line.svg").write_text("<svg><path d='M 0 0 L 10 0'></svg>")
    config = tmp_path / "scribble.toml"
    config.write_text(SCRIBBLE.read_text())
    done = subprocess.run([sys.executable, "-m", "creatures.cli", "offline", str(config), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 2 and "line.svg:1: not well-formed SVG" in done.stderr
    assert "creature.0.body" in done.stderr and not (tmp_path / "o").exists()


@pytest.fixture(scope="module")
def scribbled(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("scribble")
    inst = load_installation(SCRIBBLE)
    inst.settings.output.report = False
    run_offline(inst, out, duration=20.0)
    return out


def test_the_scribble_touches_the_notes_it_hears_with_its_tip(scribbled):
    from creatures.events import read_events

    events = read_events(scribbled / "events.jsonl")
    played = [e for e in events if e["kind"] == "note" and e.get("creature") == "scribble"]
    heard = [e for e in events if e["kind"] == "heard"]
    assert len(heard) >= 5 and len(played) >= 3
    pitches = {e["pitch"] for e in heard}
    assert np.mean([e["pitch"] in pitches for e in played]) >= 0.8  # it strikes what it placed in space


def test_lines_render_as_svg_the_bodies_the_log_holds(scribbled, tmp_path):
    import svgelements

    from creatures.view.rerender import load_replay, sampled
    from creatures.view.snapshot import scene

    done = subprocess.run([sys.executable, "-m", "creatures.cli", "render", str(scribbled), "--lines", "svg",
                           "--out", str(tmp_path), "--fps", "5"], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    files = sorted((tmp_path / "lines").glob("*.svg"))
    played = load_replay(scribbled)
    chosen = sampled(played.frames, 5.0)
    assert len(files) == sum(r for _, r in chosen)
    everything = np.concatenate([scene(m, played.hello)[0] for m, _ in chosen])
    page = Page.framing(everything, 640, 480)
    positions, parents, _ = scene(chosen[-1][0], played.hello)
    expected = page.project(positions)
    svg = svgelements.SVG.parse(files[-1])
    paths = [e for e in svg.elements() if isinstance(e, svgelements.Path)]
    assert len(paths) == len(strokes(parents)) == 1  # one pen line: the body is one unbroken line
    curves = [seg for seg in paths[0] if isinstance(seg, svgelements.CubicBezier)]
    assert len(curves) == len(strokes(parents)[0]) - 1  # a smooth segment between each two joints …
    ends = np.array([(curves[0].start.x, curves[0].start.y)] + [(c.end.x, c.end.y) for c in curves])
    assert np.abs(ends - expected[strokes(parents)[0]]).max() < 1e-3  # … through every joint
    assert (expected >= 0).all() and (expected[:, 0] <= 640).all() and (expected[:, 1] <= 480).all()


def test_the_line_renderers_svg_opens_in_a_browser(scribbled, tmp_path):
    if not Path(CHROMIUM).exists():
        pytest.skip(f"no Chromium at {CHROMIUM}")
    playwright = pytest.importorskip("playwright.sync_api")
    import imageio.v3 as iio

    subprocess.run([sys.executable, "-m", "creatures.cli", "render", str(scribbled), "--lines", "svg", "--out",
                    str(tmp_path), "--fps", "1"], check=True, capture_output=True, cwd=ROOT)
    svg = sorted((tmp_path / "lines").glob("*.svg"))[-1]
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 640, "height": 480})
        errors: list[str] = []
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        page.goto(svg.as_uri())
        shot = iio.imread(page.screenshot(), extension=".png")
        browser.close()
    ink = (shot[..., :3].mean(axis=2) < 100).mean()
    assert 0.001 < ink < 0.2 and not errors  # a drawn line on white: not blank, not a black page


def test_lines_render_as_postscript(scribbled, tmp_path):
    done = subprocess.run([sys.executable, "-m", "creatures.cli", "render", str(scribbled), "--lines", "ps",
                           "--out", str(tmp_path), "--fps", "1", "--width", "320", "--height", "240"],
                          capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    eps = sorted((tmp_path / "lines").glob("*.eps"))
    text = eps[0].read_text()
    assert text.startswith("%!PS-Adobe-3.0 EPSF-3.0\n%%BoundingBox: 0 0 320 240") and text.rstrip().endswith("%%EOF")
    assert text.count(" stroke") == 1 and text.count("curveto") == 47  # 48 joints, one line of 47 curves


def test_draw_puts_each_chain_in_one_stroke():
    parents = np.array([-1, 0, 1, 2, 1, 4])  # a trunk and a branch off joint 1
    assert strokes(parents) == [[0, 1, 2, 3], [1, 4, 5]]
    positions = np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [0, 3, 0], [1, 1, 0], [2, 1, 0]], float)
    page = Page.framing(positions, 100, 100)
    text = draw(page, positions, parents, [((0.0, 0.0, 0.0), 60.0)], "svg")
    assert text.count("<path") == 2 and text.count("<circle") == 1


def test_a_spline_pose_passes_smoothly_through_every_joint_in_3d():
    """The 3-D spline representation: each chain's curve goes through its joints, in order,
    with one tangent at each (C1: a limb bends, it does not kink), and straight bones stay
    straight."""
    rng = np.random.default_rng(3)
    joints = np.cumsum(rng.normal(size=(7, 3)), axis=0)
    segments = catmull_rom(joints)
    assert np.allclose(segments[:, 0], joints[:-1]) and np.allclose(segments[:, 3], joints[1:])
    out_tangent, in_tangent = segments[:-1, 3] - segments[:-1, 2], segments[1:, 1] - segments[1:, 0]
    assert np.allclose(out_tangent, in_tangent)
    line = np.outer(np.arange(5.0), [1.0, 2.0, -1.0])
    sampled = SplinePose.of(line, np.array([-1, 0, 1, 2, 3])).points(per_segment=6)[0]
    assert len(sampled) == 4 * 6 + 1 and np.allclose(np.cross(sampled, [1.0, 2.0, -1.0]), 0.0)
    a_pose = SplinePose.of(joints, np.array([-1, 0, 1, 2, 1, 4, 5]))
    assert [len(s) for s in a_pose.segments] == [3, 3]  # a trunk and a branch


def held_spectrum(positions: np.ndarray, body_shape: float, seconds: float = 1.0) -> np.ndarray:
    """Harmonic profile (first 8 partials of A3, summing to 1) of a string held for
    ``seconds`` while the body stands in ``positions``; the second half is measured."""
    from types import SimpleNamespace

    from creatures.kinds.parts import Voice, VoiceSpec

    rate, block = 22050, 512
    voice = Voice(VoiceSpec(voices=1, body_shape=body_shape), rate)
    voice.shape_as(list(range(len(positions))))
    voice.play(57, 100, 100.0)
    out = []
    for b in range(int(seconds * rate / block)):
        voice.feel(SimpleNamespace(positions=positions, time=b * block / rate))
        buffer = np.zeros(block)
        voice.render(buffer, b * block / rate)
        out.append(buffer)
    x = np.concatenate(out)[len(out) * block // 2:]
    magnitude = np.abs(np.fft.rfft(x * np.hanning(len(x))))
    bins = np.fft.rfftfreq(len(x), 1 / rate)
    partials = np.array([magnitude[np.argmin(abs(bins - 220.0 * h))] for h in range(1, 9)])
    return partials / partials.sum()


def test_a_string_body_sounds_its_pose():
    """The second connection: the string held in the drawn body's shape changes its spectrum
    with the pose (lying low, waving, curled), and does not without body_shape."""
    take = read_drawing(ROOT / "installations" / "bodies" / "line.svg")
    poses = take.skeleton.forward_kinematics(take.rotations, take.roots) * 0.01
    rest, wave, curl = (held_spectrum(poses[k], 10.0) for k in (0, 25, 47))
    for a, b in ((rest, wave), (wave, curl), (rest, curl)):
        assert np.abs(a - b).sum() > 0.3
    assert np.allclose(held_spectrum(poses[25], 10.0), wave)  # the same pose, the same timbre
    plain = [held_spectrum(poses[k], 0.0) for k in (0, 25, 47)]
    assert np.abs(plain[0] - plain[1]).sum() < 1e-9 and np.abs(plain[1] - plain[2]).sum() < 1e-9


def test_a_render_again_into_its_folder_leaves_no_frames_of_the_last(scribbled, tmp_path):
    """Drawn at 5 fps, then again into the same folder at 1 fps: the folder holds the second
    render's frames only (it kept the first's after them: a sequence of both); a file put
    among them that no render wrote is never removed: the render is refused, nothing changed."""
    from creatures.body.lines import render_lines
    from creatures.runtime.outputs import OutputDirectoryError

    first = render_lines(scribbled, tmp_path, fps=5.0)
    (tmp_path / "lines" / "notes.txt").write_text("mine")
    before = _tree(tmp_path / "lines")
    with pytest.raises(OutputDirectoryError, match="notes.txt"):
        render_lines(scribbled, tmp_path, fps=1.0)
    assert _tree(tmp_path / "lines") == before
    (tmp_path / "lines" / "notes.txt").unlink()
    second = render_lines(scribbled, tmp_path, fps=1.0)
    assert first > second > 0
    files = sorted(p.name for p in (tmp_path / "lines").iterdir())
    assert files == [f"frame_{n:06d}.svg" for n in range(second)]


def test_a_render_stopped_part_way_leaves_the_last_one_as_it_was(scribbled, tmp_path, monkeypatch):
    """Stopped after two drawings (Ctrl-C), a render again at 1 fps had written them over the
    first two of the last render's and left the rest after them: a sequence of both that
    looked whole. Now the folder is the last render's, byte for byte, and nothing is left aside."""
    from creatures.body import lines

    lines.render_lines(scribbled, tmp_path, fps=5.0)
    before = _tree(tmp_path)
    drawn = lines.draw

    def stopped(*args, **kwargs):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(1)
        return drawn(*args, **kwargs)

    calls: list[int] = []
    monkeypatch.setattr(lines, "draw", stopped)
    with pytest.raises(KeyboardInterrupt):
        lines.render_lines(scribbled, tmp_path, fps=1.0)
    assert len(calls) == 2 and _tree(tmp_path) == before
