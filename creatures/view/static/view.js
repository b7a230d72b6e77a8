// The creatures' live view (docs/view.md): bodies on a 2-D canvas under a perspective camera
// that is the offscreen renderer's own (creatures/body/render.py: look_at, yfov π/3.5, framed
// on the first frame as BodyRenderer.frame_camera frames it), so a replay's first frame puts
// every joint where `creatures render` puts it. Drag orbits, the wheel zooms, shift-drag pans,
// "projection" (or ?projection, or key p) shows the bodies alone, fullscreen, for a kiosk.
"use strict";

const YFOV = Math.PI / 3.5, ZNEAR = 0.05, HISTORY = 60, NOTES_SHOWN = 200;
// Tables keyed by a creature's (or a drive's) name, which a config chooses: no prototype, and
// read from a received message only through own(), so a creature called "constructor" or
// "__proto__" (a valid name) is a name like any other, not Object.prototype's member.
const byName = () => Object.create(null);
const own = (table, key) => (table != null && Object.hasOwn(table, key) ? table[key] : undefined);
const view = window.__view = {
  hello: null, frame: null, first: null, frames: 0, drawn: 0, camera: null, screen: byName(),
  drives: byName(), values: byName(), actions: byName(), percepts: byName(), trees: byName(), notes: [], notesSeen: 0, status: {},
  errors: [], errorsSeen: 0,
  project: null, size: null, drawMs: 0,
};
const ERRORS_KEPT = 100; // the first ones (the cause); one that recurs each refresh must not grow a kiosk's tab
window.addEventListener("error", (e) => {
  view.errorsSeen += 1;
  if (view.errors.length < ERRORS_KEPT) view.errors.push(String(e.message));
});

const stage = document.getElementById("stage"), ctx = stage.getContext("2d");
view.redraw = () => { dirty = true; }; // the next animation frame draws, new frame or not (the bench's hook)
const statusLine = document.getElementById("status"), notesList = document.getElementById("notes");
let dirty = true, panels = byName();

// -- vectors and the camera --------------------------------------------------------------
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const unit = (a) => { const n = Math.hypot(a[0], a[1], a[2]); return [a[0] / n, a[1] / n, a[2] / n]; };

function frameCamera(points) {
  // BodyRenderer.frame_camera: from the front, far enough to see all of it.
  const low = [Infinity, Infinity, Infinity], high = [-Infinity, -Infinity, -Infinity];
  for (const p of points) for (let k = 0; k < 3; k++) { low[k] = Math.min(low[k], p[k]); high[k] = Math.max(high[k], p[k]); }
  const centre = [0, 1, 2].map((k) => 0.5 * (low[k] + high[k]));
  const size = Math.max(high[0] - low[0], high[1] - low[1], high[2] - low[2], 0.5);
  const offset = [0.25 * size, 0.3 * size, 1.7 * size], distance = Math.hypot(...offset);
  return { target: centre, distance, yaw: Math.atan2(offset[0], offset[2]), pitch: Math.asin(offset[1] / distance) };
}

function eyeOf(c) {
  return add(c.target, [c.distance * Math.cos(c.pitch) * Math.sin(c.yaw), c.distance * Math.sin(c.pitch),
                        c.distance * Math.cos(c.pitch) * Math.cos(c.yaw)]);
}

function projector(c, width, height) {
  // render.look_at + render.perspective, to pixels with the first row on top.
  const eye = eyeOf(c), back = unit(sub(eye, c.target)), right = unit(cross([0, 1, 0], back)), up = cross(back, right);
  const t = Math.tan(YFOV / 2), aspect = width / height;
  return (p) => {
    const r = sub(p, eye), z = -dot(r, back);
    if (z < ZNEAR) return null;
    return [(dot(r, right) / (aspect * t * z) + 1) / 2 * width, (1 - dot(r, up) / (t * z)) / 2 * height, z];
  };
}
view.projectorFor = (width, height) => projector(view.camera, width, height);

function pitchColour(pitch, alpha = 1) {
  const octave = Math.min(Math.max((Math.floor(pitch / 12) - 2) / 7, 0), 1);
  const h = ((Math.round(pitch) % 12) + 12) % 12 / 12, s = 0.85, v = 0.45 + 0.55 * octave;
  const i = Math.floor(h * 6), f = h * 6 - i, p = v * (1 - s), q = v * (1 - s * f), u = v * (1 - s * (1 - f));
  const [r, g, b] = [[v, u, p], [q, v, p], [p, v, u], [p, q, v], [u, p, v], [v, p, q]][i % 6];
  return `rgba(${Math.round(r * 255)},${Math.round(g * 255)},${Math.round(b * 255)},${alpha})`;
}

// -- the scene: every body at its place, as creatures/view/snapshot.py scene() ------------
function scene(frame) {
  const bodies = [], marks = [];
  for (const c of view.hello.creatures) {
    const joints = own(frame.bodies, c.name);
    if (joints && c.parents) bodies.push({ name: c.name, parents: c.parents, joints: joints.map((p) => add(p, c.place)) });
    for (const m of own(frame.marks, c.name) || []) marks.push({ at: add(m.slice(0, 3), c.place), pitch: m[3] });
  }
  return { bodies, marks };
}

function resize() {
  const r = stage.getBoundingClientRect(), w = Math.max(1, Math.round(r.width)), h = Math.max(1, Math.round(r.height));
  if (stage.width !== w || stage.height !== h) { stage.width = w; stage.height = h; dirty = true; }
}

function draw() {
  const began = performance.now();
  paint();
  view.drawMs += performance.now() - began; // the bench's measure of headroom beyond the display's rate
}

function paint() {
  resize();
  const w = stage.width, h = stage.height;
  ctx.fillStyle = "#14141a";
  ctx.fillRect(0, 0, w, h);
  if (view.frame && !view.camera) {
    ctx.fillStyle = "#667"; ctx.font = "14px system-ui"; ctx.fillText("no bodies in this colony", 16, 28);
  }
  if (!view.frame || !view.camera) return;
  const project = view.project = projector(view.camera, w, h);
  view.size = [w, h];
  floor(project);
  // One path for a body's bones and one for its joints, bodies far to near (2,000 single
  // strokes for 50 bodies cost ~17 ms a frame; a hundred paths a few).
  const { bodies, marks } = scene(view.frame), scale = h / (2 * Math.tan(YFOV / 2)), items = [];
  view.screen = byName();
  for (const body of bodies) {
    const screen = body.joints.map(project), seen = screen.filter((s) => s);
    view.screen[body.name] = screen;
    if (seen.length) items.push({ screen, parents: body.parents, z: seen.reduce((a, s) => a + s[2], 0) / seen.length });
  }
  for (const m of marks) { const s = project(m.at); if (s) items.push({ mark: s, z: s[2], colour: pitchColour(m.pitch) }); }
  items.sort((x, y) => y.z - x.z);
  ctx.lineCap = "round";
  for (const it of items) {
    if (it.mark) {
      ctx.fillStyle = it.colour;
      ctx.beginPath(); ctx.arc(it.mark[0], it.mark[1], Math.max(2, 0.06 * scale / it.z), 0, 2 * Math.PI); ctx.fill();
      continue;
    }
    const { screen, parents } = it;
    ctx.strokeStyle = "#b8b3a6"; ctx.lineWidth = Math.max(1, 2 * 0.025 * scale / it.z);
    ctx.beginPath();
    parents.forEach((parent, j) => {
      if (parent >= 0 && screen[j] && screen[parent]) { ctx.moveTo(screen[parent][0], screen[parent][1]); ctx.lineTo(screen[j][0], screen[j][1]); }
    });
    ctx.stroke();
    ctx.fillStyle = "#d9d1bf";
    ctx.beginPath();
    const r = Math.max(1.5, 0.04 * scale / it.z);
    for (const s of screen) if (s) { ctx.moveTo(s[0] + r, s[1]); ctx.arc(s[0], s[1], r, 0, 2 * Math.PI); }
    ctx.fill();
  }
  view.drawn += 1;
}

function floor(project) {
  ctx.strokeStyle = "#262630"; ctx.lineWidth = 1;
  for (let i = -5; i <= 5; i++) for (const [a, b] of [[[i, 0, -5], [i, 0, 5]], [[-5, 0, i], [5, 0, i]]]) {
    const p = project(a), q = project(b);
    if (p && q) { ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke(); }
  }
}

// -- panels: drives and values over time, the current action, percepts ------------------
function panel(name) {
  if (panels[name]) return panels[name];
  const box = document.createElement("div");
  box.className = "creature";
  box.innerHTML = `<h2><span class="name"></span> <span class="action"></span></h2><div class="legend drives"></div>` +
    `<canvas class="drives"></canvas><div class="legend values"></div><canvas class="values"></canvas>` +
    `<div class="percepts"></div>`;
  box.querySelector(".name").textContent = name;
  document.getElementById("creatures").appendChild(box);
  return (panels[name] = { box, action: box.querySelector(".action"), percepts: box.querySelector(".percepts"),
                           drives: box.querySelector("canvas.drives"), values: box.querySelector("canvas.values"),
                           driveLegend: box.querySelector(".legend.drives"), valueLegend: box.querySelector(".legend.values") });
}

const SERIES = ["#e86", "#6c8", "#69e", "#dc5", "#c7d", "#5cc", "#aaa", "#e9b"];

function plot(canvas, legend, history) {
  const w = (canvas.width = canvas.clientWidth || 300), h = (canvas.height = canvas.clientHeight || 54);
  const c = canvas.getContext("2d");
  c.clearRect(0, 0, w, h);
  if (history.length < 1) return;
  const names = Object.keys(history[history.length - 1][1]), t1 = history[history.length - 1][0];
  const t0 = Math.max(history[0][0], t1 - HISTORY), span = Math.max(t1 - t0, 1);
  let low = Infinity, high = -Infinity;
  for (const [, v] of history) for (const n of names) if (own(v, n) != null) { low = Math.min(low, v[n]); high = Math.max(high, v[n]); }
  if (high - low < 1e-9) { high += 0.5; low -= 0.5; }
  names.forEach((n, k) => {
    c.strokeStyle = SERIES[k % SERIES.length]; c.beginPath();
    history.forEach(([t, v], i) => {
      const x = (t - t0) / span * w, y = h - 2 - (own(v, n) - low) / (high - low) * (h - 4);
      i ? c.lineTo(x, y) : c.moveTo(x, y);
    });
    c.stroke();
  });
  legend.replaceChildren(...names.map((n, k) => {  // names come from configs: text, never markup
    const span = document.createElement("span");
    span.style.color = SERIES[k % SERIES.length];
    span.textContent = `${n} ${fmt(history[history.length - 1][1][n])}`;
    return span;
  }));
}
const fmt = (x) => (x == null ? "–" : Math.abs(x) >= 100 ? x.toFixed(0) : x.toFixed(3));

function remember(store, name, t, value) {
  const h = (store[name] = store[name] || []);
  h.push([t, value]);
  while (h.length && h[0][0] < t - HISTORY) h.shift();
}

function take(event) {
  const who = event.creature;
  switch (event.kind) {
    case "motivation": remember(view.drives, who, event.t, event.drives); break;
    case "values": remember(view.values, who, event.t, event.values); break;
    case "selection": view.actions[who] = event.tuple; break;
    case "percepts": view.percepts[who] = event.sizes; break;
    case "note": case "heard": {
      view.notes.push(event); view.notesSeen += 1;  // the last NOTES_SHOWN kept, as listed: a live run never restarts
      if (view.notes.length > NOTES_SHOWN) view.notes.splice(0, view.notes.length - NOTES_SHOWN);
      const li = document.createElement("li");
      li.textContent = `${event.t.toFixed(2)} s  ${event.kind === "note" ? who + " played" : "heard from " + event.source}  ` +
        `pitch ${event.pitch} vel ${event.velocity ?? ""} dur ${Number(event.duration).toFixed(2)}`;
      li.style.color = pitchColour(event.pitch);
      notesList.prepend(li);
      while (notesList.children.length > NOTES_SHOWN) notesList.lastChild.remove();
      break;
    }
    case "xruns": view.status.underruns = event.underruns; view.status.overruns = event.overruns; break;
    case "timing": view.status.late_ticks = event.late_ticks; view.status.ticks = event.ticks; break;
    default: break;
  }
}

function refreshPanels() {
  for (const c of view.hello.creatures) {
    const p = panel(c.name);
    p.action.textContent = view.actions[c.name] || "";
    plot(p.drives, p.driveLegend, view.drives[c.name] || []);
    plot(p.values, p.valueLegend, view.values[c.name] || []);
    const sizes = view.percepts[c.name] || {}, lines = [];
    const walk = (node, depth) => { lines.push(`${"  ".repeat(depth)}${node.name} (${node.size})`); node.children.forEach((n) => walk(n, depth + 1)); };
    for (const tree of own(view.trees, c.name) || []) walk(tree, 0);
    p.percepts.textContent = (lines.length ? "percept trees\n" + lines.join("\n") + "\n" : "") +
      (Object.keys(sizes).length ? "percepts now\n" : "") + Object.entries(sizes).map(([k, v]) => `  ${k}: ${v}`).join("\n");
  }
  const s = view.status, t = view.frame ? view.frame.t.toFixed(2) : "–";
  statusLine.textContent = `${view.hello.mode} · t ${t} s · ${view.frames} frames · dropped ${s.dropped ?? 0}` +
    (s.underruns != null ? ` · underruns ${s.underruns} overruns ${s.overruns}` : "") +
    (s.late_ticks != null ? ` · late ticks ${s.late_ticks}/${s.ticks}` : "") + (s.sound ? ` · sound ${s.sound}` : "") +
    (view.closed ? " · disconnected" : "");
}

// -- the websocket ------------------------------------------------------------------------
function reset() {
  view.drives = byName(); view.values = byName(); view.actions = byName(); view.percepts = byName(); view.notes = []; view.notesSeen = 0; view.first = null;
  notesList.textContent = "";
}

function newRun(hello) {
  // A hello after another is the next run (the page reconnects when a run serves again): its
  // clock starts anew and its colony may differ, so nothing of the last one is kept but the
  // camera, and that only for the same colony (a projector's framing survives a restart).
  reset();
  if (JSON.stringify(hello.creatures) !== JSON.stringify(view.hello.creatures)) view.camera = null;
  view.frame = null; view.frames = 0; view.trees = byName(); view.status = {};  // the status line counts this run's
  for (const p of Object.values(panels)) p.box.remove();
  panels = byName();
}

function connect() {
  const socket = new WebSocket(`ws://${location.host}/ws`);
  socket.onmessage = (e) => {
    const m = JSON.parse(e.data);
    if (m.type === "hello") {
      if (view.hello) newRun(m);
      view.hello = m;
      document.getElementById("title").textContent = m.title || "creatures";
      Object.assign(view.status, m.status || {});
    } else if (m.type === "trees") {
      view.trees = m.trees;
    } else if (m.type === "restart") {
      reset();
    } else if (m.type === "frame") {
      view.frame = m; view.frames += 1;
      if (!view.first) view.first = m;
      if (!view.camera) { const s = scene(m); const pts = s.bodies.flatMap((b) => b.joints); if (pts.length) view.camera = frameCamera(pts); }
      Object.assign(view.status, m.status || {});
      for (const event of m.events) take(event);
      dirty = true;
    }
  };
  socket.onclose = () => { view.closed = true; if (view.hello) refreshPanels(); setTimeout(connect, 2000); };
  socket.onopen = () => { view.closed = false; };
}

// -- camera controls ----------------------------------------------------------------------
let dragging = null;
stage.addEventListener("pointerdown", (e) => { dragging = { x: e.clientX, y: e.clientY, pan: e.shiftKey }; stage.setPointerCapture(e.pointerId); });
stage.addEventListener("pointerup", () => { dragging = null; });
stage.addEventListener("pointermove", (e) => {
  if (!dragging || !view.camera) return;
  const dx = e.clientX - dragging.x, dy = e.clientY - dragging.y, c = view.camera;
  dragging.x = e.clientX; dragging.y = e.clientY;
  if (dragging.pan) {
    const eye = eyeOf(c), back = unit(sub(eye, c.target)), right = unit(cross([0, 1, 0], back)), up = cross(back, right);
    const k = c.distance / stage.height;
    c.target = add(c.target, add(right.map((v) => -v * dx * k), up.map((v) => v * dy * k)));
  } else {
    c.yaw -= dx * 0.01;
    c.pitch = Math.min(1.5, Math.max(-1.5, c.pitch + dy * 0.01));
  }
  dirty = true;
});
stage.addEventListener("wheel", (e) => { if (view.camera) { view.camera.distance *= Math.exp(e.deltaY * 0.001); dirty = true; } e.preventDefault(); }, { passive: false });

function projection(on) {
  document.body.classList.toggle("projection", on);
  if (on && document.documentElement.requestFullscreen) document.documentElement.requestFullscreen().catch(() => {});
  if (!on && document.fullscreenElement) document.exitFullscreen().catch(() => {});
  dirty = true;
}
document.getElementById("projection").onclick = () => projection(true);
document.getElementById("reset").onclick = () => { view.camera = null; if (view.frame) { const s = scene(view.frame); view.camera = frameCamera(s.bodies.flatMap((b) => b.joints)); } dirty = true; };
document.addEventListener("keydown", (e) => {
  if (e.key === "p") projection(!document.body.classList.contains("projection"));
  if (e.key === "Escape") projection(false);
  if (e.key === "r") document.getElementById("reset").onclick();
});
document.addEventListener("fullscreenchange", () => { if (!document.fullscreenElement) document.body.classList.remove("projection"); dirty = true; });
if (new URLSearchParams(location.search).has("projection")) projection(true);

let lastPanels = 0;
function animate(now) {
  // Asked for first: an error below (a damaged record in a replayed log) reaches the error
  // handler and costs this frame only; asked for last, it stopped the page drawing for good.
  requestAnimationFrame(animate);
  if (dirty) { dirty = false; draw(); }
  if (view.hello && now - lastPanels > 250) { lastPanels = now; refreshPanels(); }
}
window.addEventListener("resize", () => { dirty = true; });
connect();
requestAnimationFrame(animate);
