"""The view in a real browser (issue 19): the OS's Chromium, driven by Playwright, shows a
running colony's bodies moving, its drives changing and its note list growing with no console
errors; and a replay's first frame puts every joint where the offscreen renderer puts it.

Needs /usr/bin/chromium (apt) and Playwright (pip; no `playwright install`: the OS's browser is
launched); skips with the reason otherwise.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import installations
from bench.live_parts import free_listening_port, free_udp_port, send_notes

CHROMIUM = os.environ.get("CREATURES_CHROMIUM", "/usr/bin/chromium")
pytestmark = pytest.mark.browser


def missing_browser() -> str | None:
    """Why the browser tests cannot run here, or None."""
    if not (Path(CHROMIUM).exists() or shutil.which(CHROMIUM)):
        return f"no Chromium at {CHROMIUM} (apt-get install chromium, or set CREATURES_CHROMIUM)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "Playwright is not installed (pip install playwright; the OS's Chromium is used, no download)"
    return None


@pytest.fixture(scope="module")
def browser():
    reason = missing_browser()
    if reason:
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        launched = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        yield launched
        launched.close()


def open_page(browser, url: str):
    """A page at ``url`` and the console errors and page errors it reports."""
    page = browser.new_page(viewport={"width": 1000, "height": 600})
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(url)
    return page, errors


def stage_pixels(page) -> np.ndarray:
    import imageio.v3 as iio

    box = page.locator("#stage").bounding_box()
    return iio.imread(page.screenshot(clip=box))[..., :3].astype(int)


@pytest.mark.slow
def test_the_live_page_of_a_running_colony_moves_changes_and_grows(browser, tmp_path):
    osc, view = free_udp_port(), free_listening_port()
    config = tmp_path / "show.toml"
    config.write_text(f'extends = "{installations.path("exchange")}"\nrealtime = false\n'
                      f'[audio]\noutput = false\n[osc]\nport = {osc}\n')
    colony = subprocess.Popen([sys.executable, "-m", "creatures.cli", "run", str(config), "--view", str(view),
                               "--duration", "180"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                              env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        for line in colony.stdout:
            if "running; Ctrl-C" in line:
                break
        sender = send_notes(osc, 40, 4.0, tmp_path / "sent.jsonl")  # a visitor plays for 10 s
        page, errors = open_page(browser, f"http://127.0.0.1:{view}/")
        page.wait_for_function("window.__view.frames > 3 && window.__view.notesSeen > 0", timeout=60_000)
        first = stage_pixels(page)
        before = page.evaluate("({frames: __view.frames, notes: __view.notesSeen, screen: __view.screen,"
                               " drives: __view.drives})")
        page.wait_for_function(f"window.__view.frames > {before['frames'] + 40} && "
                               f"window.__view.notesSeen > {before['notes']}", timeout=60_000)
        second = stage_pixels(page)
        after = page.evaluate("({frames: __view.frames, notes: __view.notesSeen, screen: __view.screen,"
                              " drives: __view.drives, mode: __view.hello.mode, status: __view.status,"
                              " listed: document.querySelectorAll('#notes li').length})")
        seen_errors = list(errors)  # while the colony ran (once it stops, the page's reconnecting is refused)
        sender.kill()
    finally:
        colony.terminate()
        colony.wait(60)
    assert after["mode"] == "live"
    # Bodies that move between two screenshots: pixels of the stage changed, and so did the
    # joints the page drew (its projected screen coordinates).
    assert (np.abs(first - second).max(axis=2) > 40).sum() > 50
    moved = [np.abs(np.array(after["screen"][n])[:, :2] - np.array(before["screen"][n])[:, :2]).max()
             for n in ("ada", "bo", "cy")]
    assert max(moved) > 2.0, moved
    # Drives that change over time: some creature's drive took more than one value.
    levels = [v for history in after["drives"].values() for _, d in history for v in d.values()]
    assert len(set(np.round(levels, 6))) > 3, after["drives"]
    # A note list that grows (heard from the visitor, played by the creatures).
    assert after["notes"] > before["notes"] >= 1
    assert after["listed"] == min(after["notes"], 200)
    assert seen_errors == []


@pytest.mark.gl
def test_the_replay_shows_the_first_frame_the_offscreen_renderer_draws(browser, tmp_path):
    from creatures.body.render import BodyRenderer, RenderUnavailable
    from creatures.runtime.offline import run_offline
    from creatures.runtime.schema import load_installation
    from creatures.view.rerender import load_replay
    from creatures.view.server import ReplaySource, ViewServer
    from creatures.view.snapshot import scene

    inst = load_installation(installations.path("exchange"))
    inst.settings.output.report = False
    run_offline(inst, tmp_path, duration=3.0)
    played = load_replay(tmp_path)
    positions, parents, _ = scene(played.frames[0], played.hello)
    width, height = 640, 480
    try:
        renderer = BodyRenderer(width, height)
    except RenderUnavailable as exc:
        pytest.skip(f"no GL platform: {exc}")
    with renderer:
        renderer.render(positions, parents)  # frames its camera on this first frame, as `creatures render` does
        camera = renderer.camera_pose
        projection = renderer._projection
    # Where the offscreen renderer puts each joint, in pixels (first row on top).
    clip = (projection @ np.linalg.inv(camera) @ np.c_[positions, np.ones(len(positions))].T).T
    ndc = clip[:, :3] / clip[:, 3:]
    pixels = np.c_[(ndc[:, 0] + 1) / 2 * width, (ndc[:, 1] + 1) / 2 * height]

    server = ViewServer(ReplaySource(played)).start()
    try:
        page, errors = open_page(browser, server.url)
        page.wait_for_function("window.__view.first !== null && window.__view.camera !== null", timeout=30_000)
        first = page.evaluate("__view.first")
        shown = np.array(page.evaluate(
            "([points, w, h]) => points.map(__view.projectorFor(w, h))", [positions.tolist(), width, height]))
    finally:
        server.close()
    assert first["t"] == played.frames[0]["t"]
    for name, joints in played.frames[0]["bodies"].items():  # the same joints…
        assert np.array(first["bodies"][name]) == pytest.approx(joints, abs=1e-6)
    assert shown[:, :2] == pytest.approx(pixels, abs=1e-3)  # …seen from the same camera
    assert errors == []


class _Scripted:
    """A view source that sends each browser its hello and then ``messages``, once."""

    def __init__(self, hello: dict, messages: list[dict]) -> None:
        self._hello, self.messages = hello, messages

    def hello(self) -> dict:
        return self._hello

    def greeting(self) -> list[str]:
        return []

    async def run(self, clients) -> None:
        pass

    async def serve(self, client) -> None:
        for message in self.messages:
            await client.queue.put(json.dumps(message))


def _run(title: str, name: str, t: float, status: dict) -> _Scripted:
    """A run of one creature without a body whose frame at ``t`` says its drive and a note."""
    events = [{"t": t, "kind": "motivation", "creature": name, "drives": {"hunger": 0.5}},
              {"t": t, "kind": "note", "creature": name, "pitch": 60, "velocity": 90, "duration": 0.5}]
    return _Scripted({"type": "hello", "title": title, "mode": "live", "status": status,
                      "creatures": [{"name": name, "kind": "authored", "parents": None, "place": [0, 0, 0]}]},
                     [{"type": "frame", "t": t, "bodies": {}, "marks": {}, "events": events, "status": {}}])


def test_a_kiosk_page_that_reconnects_to_the_next_run_shows_only_that_run(browser):
    """The run ends under a kiosk's page (a restart, a new config) and the next serves on the
    same port: the page reconnects and shows the new colony alone (it kept the old run's
    creatures' panels, notes and status, and its drive histories at the old run's times, so the
    new run's plotted off the scale for as long as the old one had run)."""
    from creatures.view.server import ViewServer

    first = ViewServer(_run("first run", "ada", 5000.0, {"sound": "on"})).start()
    try:
        page, errors = open_page(browser, first.url)
        page.wait_for_function("window.__view.notes.length === 1", timeout=30_000)
    finally:
        first.close()
    second = ViewServer(_run("second run", "bo", 1.0, {}), first.port).start()
    try:
        page.wait_for_function("window.__view.hello.title === 'second run' && window.__view.notes.length > 0 "
                               "&& !window.__view.closed", timeout=30_000)
        page.wait_for_function("[...document.querySelectorAll('#creatures .creature .name')]"
                               ".some((e) => e.textContent === 'bo')", timeout=30_000)  # its panel is drawn
        shown = page.evaluate("({drives: __view.drives, notes: __view.notes.map((n) => n.creature),"
                              " frames: __view.frames,"
                              " status: __view.status, listed: document.querySelectorAll('#notes li').length,"
                              " panels: [...document.querySelectorAll('#creatures .creature .name')]"
                              ".map((e) => e.textContent)})")
    finally:
        second.close()
    assert list(shown["drives"]) == ["bo"] and shown["drives"]["bo"] == [[1.0, {"hunger": 0.5}]]
    assert shown["notes"] == ["bo"] and shown["listed"] == 1
    assert shown["frames"] == 1  # this run's one frame: the status line's count went on from the last run's
    assert shown["panels"] == ["bo"]
    assert "sound" not in shown["status"]
    assert errors == [] or all("WebSocket" in e for e in errors)  # the refused reconnects while no run served


def test_creatures_named_like_an_objects_members_are_shown_as_any_other(browser):
    """A creature may be called ``constructor``, ``toString`` or ``__proto__`` (letters, digits, _
    and -): the page looked names up in plain objects, found Object.prototype's members there
    and threw on every message and every refresh (no panels, no notes, nothing drawn)."""
    from creatures.view.server import ViewServer

    names = ["constructor", "__proto__", "toString", "ada"]
    events = [e for n in names for e in (
        {"t": 1.0, "kind": "motivation", "creature": n, "drives": {"hunger": 0.5}},
        {"t": 1.0, "kind": "selection", "creature": n, "tuple": f"{n} sings"},
        {"t": 1.0, "kind": "note", "creature": n, "pitch": 60, "velocity": 90, "duration": 0.5})]
    hello = {"type": "hello", "title": "members", "mode": "live", "status": {},
             "creatures": [{"name": n, "kind": "authored", "parents": [-1, 0], "place": [i * 1.5, 0, 0]}
                           for i, n in enumerate(names)]}
    frame = {"type": "frame", "t": 1.0, "bodies": {n: [[0, 1, 0], [0, 0, 0]] for n in names}, "marks": {},
             "events": events, "status": {}}
    server = ViewServer(_Scripted(hello, [{"type": "trees", "t": None, "trees": {"ada": []}}, frame])).start()
    try:
        page, errors = open_page(browser, server.url)
        page.wait_for_function("window.__view.notes.length === 4 && window.__view.drawn > 0 && "
                               "document.querySelectorAll('#creatures .creature .action').length === 4 && "
                               "[...document.querySelectorAll('#creatures .creature .action')]"
                               ".every((e) => e.textContent.endsWith(' sings'))", timeout=30_000)
        shown = page.evaluate("({panels: [...document.querySelectorAll('#creatures .creature .name')]"
                              ".map((e) => e.textContent), screen: Object.keys(__view.screen),"
                              " drives: Object.keys(__view.drives), errors: __view.errors})")
    finally:
        server.close()
    assert shown["panels"] == names
    assert sorted(shown["screen"]) == sorted(names) and sorted(shown["drives"]) == sorted(names)
    assert shown["errors"] == [] and errors == []


def test_a_page_left_open_on_a_live_run_keeps_only_the_notes_it_lists(browser):
    """A live run never restarts: the page kept every note it was sent in ``__view.notes`` while
    listing only the last 200, so a kiosk's tab grew for as long as the run played (weeks)."""
    from creatures.view.server import ViewServer

    count = 600
    frames = [{"type": "frame", "t": 0.1 * i, "bodies": {}, "marks": {}, "status": {},
               "events": [{"t": 0.1 * i, "kind": "note", "creature": "ada", "pitch": 60 + i % 12, "velocity": 90,
                           "duration": 0.25}]} for i in range(count)]
    hello = {"type": "hello", "title": "long", "mode": "live", "status": {},
             "creatures": [{"name": "ada", "kind": "authored", "parents": None, "place": [0, 0, 0]}]}
    server = ViewServer(_Scripted(hello, frames)).start()
    try:
        page, errors = open_page(browser, server.url)
        page.wait_for_function(f"window.__view.frames === {count}", timeout=60_000)
        shown = page.evaluate("({kept: __view.notes.length, last: __view.notes[__view.notes.length - 1].t,"
                              " seen: __view.notesSeen, listed: document.querySelectorAll('#notes li').length})")
    finally:
        server.close()
    assert shown["kept"] == shown["listed"] == 200
    assert shown["seen"] == count
    assert shown["last"] == pytest.approx(0.1 * (count - 1))
    assert errors == []


def test_a_page_left_open_keeps_a_bounded_list_of_its_errors(browser):
    """``__view.errors`` took every uncaught error: one that recurs on each refresh (four a
    second) grew it without end on a kiosk left open for weeks. It keeps the first ones (the
    cause) and counts the rest."""
    from creatures.view.server import ViewServer

    server = ViewServer(_run("errors", "ada", 1.0, {})).start()
    try:
        page, _ = open_page(browser, server.url)
        page.wait_for_function("window.__view.notesSeen === 1", timeout=30_000)
        page.evaluate("for (let i = 0; i < 1000; i++) window.dispatchEvent(new ErrorEvent('error', {message: `e${i}`}))")
        shown = page.evaluate("({kept: __view.errors.length, first: __view.errors[0], seen: __view.errorsSeen})")
    finally:
        server.close()
    assert shown["kept"] == 100 and shown["first"] == "e0" and shown["seen"] == 1000


def test_a_damaged_record_does_not_stop_the_page_drawing(browser):
    """A replayed log may hold a record the page cannot read (a ``values`` event without its
    values: the log's reader checks only the fields it takes itself). Its panel refresh threw
    inside the animation frame before the next was asked for, so the page never drew again: a
    kiosk's picture froze on that frame for good."""
    from creatures.view.server import ViewServer

    hello = {"type": "hello", "title": "damaged", "mode": "replay", "status": {},
             "creatures": [{"name": "ada", "kind": "authored", "parents": [-1, 0], "place": [0, 0, 0]}]}
    frame = {"type": "frame", "t": 1.0, "bodies": {"ada": [[0, 1, 0], [0, 0, 0]]}, "marks": {}, "status": {},
             "events": [{"t": 1.0, "kind": "values", "creature": "ada"}]}
    server = ViewServer(_Scripted(hello, [frame])).start()
    try:
        page, _ = open_page(browser, server.url)
        page.wait_for_function("window.__view.errorsSeen > 0 && window.__view.drawn > 0", timeout=30_000)
        drawn = page.evaluate("__view.drawn")
        page.evaluate("__view.redraw()")
        page.wait_for_function(f"window.__view.drawn > {drawn}", timeout=5_000)
    finally:
        server.close()
