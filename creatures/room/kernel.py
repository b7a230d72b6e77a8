"""The crowd's sub-steps compiled: steering, combining, the vehicle's step and the room's
containment for the whole crowd over many sub-steps in one call (numba; STYLE.md, hot paths
compiled).

Why: a sub-step of fifteen singers in numpy costs ~0.5 ms, nearly all of it the dispatch of
some 300 small array operations, and a room lives 100 sub-steps a second (50 for each 0.5 s
tick of a rehearsed week): flock's gallery week cost ~3 hours of CPU in numpy. The numpy
functions of :mod:`.steering`, :mod:`.combine`, :mod:`.vehicle` and :mod:`.space` stay the
reference, documented and tested one by one against REACT's descriptions; this is the same
arithmetic per creature, in the same order, and ``tests/test_room_kernel.py`` holds it to the
numpy crowd's paths (within 1e-9 m) for every behaviour, every policy, level of detail and a
shared room's remote creatures. A recipe naming a path or field the room does not have runs in
numpy, whose call says what is missing (:meth:`Program.of`; the config loader refuses it first).

Neighbours come from a grid of cells at least one ``reach`` wide rebuilt each sub-step (a
counting sort: O(n + cells)), searched 3 × 3 cells round each creature: the ``k`` nearest
within ``reach``, as the kd-tree of :mod:`.index` gives the numpy crowd (REACT 2.5.1; a grid
is the kd-tree's equal at a crowd's even density, and a few lines of compiled code). The
cells are widened until there are at most :data:`CELLS_PER_BODY` per body (:func:`_layout`):
cells one reach wide over a large floor cost more than the crowd (300 creatures with a
0.1 m reach in a 1000 m square room built 10⁸ cells, 800 MB and 3.4 s, every sub-step).

The crowd's random numbers are drawn before the call (:func:`draws`) in the numpy crowd's
order, so a seed traces the same paths on either path.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass

import numba
import numpy as np

from creatures.room import steering as st
from creatures.room.director import FlowField, Path
from creatures.room.recipe import NAMED_TARGETS, WANDER_RATE, Recipe, Surroundings
from creatures.room.steering import GOLDEN
from creatures.room.vehicle import EPS

PARAMS: dict[str, tuple[str, ...]] = {
    "seek": (), "flee": ("panic",), "arrival": ("slowing", "response"), "pursuit": ("horizon",),
    "evasion": ("horizon", "panic"), "wander": ("rate", "radius", "distance"), "separation": ("reach",),
    "cohesion": (), "alignment": (), "obstacle_avoidance": ("lookahead", "margin"),
    "wall_avoidance": ("lookahead", "margin"), "agent_avoidance": ("horizon", "margin"),
    "path_following": ("lead", "response"), "flow_following": ("lookahead",),
    "leader_following": ("behind", "slowing", "clear"),
}
"""The compiled behaviours, by code (their order), and each one's parameters in the slots the
kernel reads; their defaults are :mod:`.steering`'s (``wander``'s rate: the recipe's)."""

CODES = {name: code for code, name in enumerate(PARAMS)}
(SEEK, FLEE, ARRIVAL, PURSUIT, EVASION, WANDER, SEPARATION, COHESION, ALIGNMENT, OBSTACLE, WALL, AGENT, PATH, FLOW,
 LEADER) = range(15)
DIRECTOR = {"path_following": "path", "flow_following": "field"}
"""The behaviours that follow what the director laid down, and the parameter naming it."""
POLICIES = {"weighted": 0, "budget": 1, "dithering": 2}
POINT, CREATURE = len(NAMED_TARGETS), len(NAMED_TARGETS) + 1
"""Target kinds beyond the named ones (visitor, player, loud, note, centre: 0–4)."""


def _defaults(name: str) -> tuple[float, ...]:
    params = inspect.signature(getattr(st, name)).parameters
    return tuple(WANDER_RATE if p == "rate" else float(params[p].default) for p in PARAMS[name])


@dataclass(frozen=True)
class Program:
    """The crowd's recipes as arrays the kernel reads: per group its behaviours' span
    (``start``, ``count``), policy, neighbours and reach, and how many wander (each draws one
    normal per steering member); per behaviour its code, weight, probability, target (kind,
    creature index, point), parameter slots and, for wander, its ordinal in the group."""

    start: np.ndarray
    count: np.ndarray
    policy: np.ndarray
    k: np.ndarray
    reach: np.ndarray
    wanders: np.ndarray
    code: np.ndarray
    weight: np.ndarray
    probability: np.ndarray
    target: np.ndarray
    creature: np.ndarray
    point: np.ndarray
    par: np.ndarray
    ordinal: np.ndarray
    data: np.ndarray
    """Per behaviour: which of the director's paths or fields it follows (-1: none)."""
    paths: tuple[np.ndarray, ...]
    """Every path's points (P, 2), where each starts in them (paths + 1), the distance along its
    path of each point, each path's radius, its bends' distance along it and what fits there
    (steering._bends), and where each path's bends start in those (paths + 1)."""
    fields: tuple[np.ndarray, ...]
    """Every flow field's cells' directions, one after another (cells, 2), where each starts,
    its rows and columns, and its cells' size across and deep."""

    @classmethod
    def of(cls, recipes: list[Recipe], around: Surroundings | None = None) -> "Program | None":
        """The recipes compiled (``around``: where the director's paths and fields are), or None
        when one has a behaviour only numpy steers by."""
        around = around or Surroundings()
        path_names, field_names = list(around.paths), list(around.fields)
        data: list[int] = []
        rows: list[tuple] = []
        start, count, policy, k, reach, wanders = [], [], [], [], [], []
        for recipe in recipes:
            start.append(len(rows))
            count.append(len(recipe.behaviours))
            policy.append(POLICIES[recipe.combine])
            k.append(recipe.neighbours)
            reach.append(recipe.reach)
            ordinal = 0
            for b in recipe.behaviours:
                params = dict(b.params)
                target = params.pop("target", "visitor")
                named = params.pop(DIRECTOR[b.name], None) if b.name in DIRECTOR else None
                names = path_names if b.name == "path_following" else field_names
                if set(params) - set(PARAMS[b.name]) or (b.name in DIRECTOR and named not in names):
                    return None  # numpy's call names the stray parameter or the missing path
                data.append(names.index(named) if b.name in DIRECTOR else -1)
                values = [float(params.get(p, d)) for p, d in zip(PARAMS[b.name], _defaults(b.name))]
                if isinstance(target, str):
                    kind, who, point = NAMED_TARGETS.index(target), -1, (0.0, 0.0)
                elif isinstance(target, (int, np.integer)):
                    kind, who, point = CREATURE, int(target), (0.0, 0.0)
                else:
                    kind, who, point = POINT, -1, tuple(float(x) for x in target)
                rows.append((CODES[b.name], b.weight, b.probability, kind, who, point,
                             values + [0.0] * (3 - len(values)), ordinal if b.name == "wander" else -1))
                ordinal += b.name == "wander"
            wanders.append(ordinal)
        col = list(zip(*rows)) if rows else [()] * 8
        i64 = lambda x: np.array(x, dtype=np.int64)  # noqa: E731
        return cls(i64(start), i64(count), i64(policy), i64(k), np.array(reach, float), i64(wanders),
                   i64(col[0]), np.array(col[1], float), np.array(col[2], float), i64(col[3]), i64(col[4]),
                   np.array(col[5], float).reshape(-1, 2), np.array(col[6], float).reshape(-1, 3), i64(col[7]),
                   i64(data), _paths([around.paths[n] for n in path_names]),
                   _fields([around.fields[n] for n in field_names]))

    @property
    def dithers(self) -> np.ndarray:
        return self.policy == POLICIES["dithering"]


def _paths(paths: list[Path]) -> tuple[np.ndarray, ...]:
    points = [np.asarray(p.points, float) for p in paths]
    bends = [st._bends(p) for p in points]
    along = [np.concatenate([[0.0], np.cumsum(st.norms(p[1:] - p[:-1]))]) for p in points]
    ends = lambda parts: np.concatenate([[0], np.cumsum([len(x) for x in parts])]).astype(np.int64)  # noqa: E731
    return (np.concatenate(points or [np.zeros((0, 2))]), ends(points), np.concatenate(along or [np.zeros(0)]),
            np.array([p.radius for p in paths], float), np.concatenate([w for w, _ in bends] or [np.zeros(0)]),
            np.concatenate([f for _, f in bends] or [np.zeros(0)]), ends([w for w, _ in bends]))


def _fields(fields: list[FlowField]) -> tuple[np.ndarray, ...]:
    cells = [np.broadcast_to(np.asarray(f.cell, float), (2,)) for f in fields]
    flat = [np.asarray(f.directions, float).reshape(-1, 2) for f in fields]
    return (np.concatenate(flat or [np.zeros((0, 2))]),
            np.concatenate([[0], np.cumsum([len(x) for x in flat])]).astype(np.int64),
            np.array([f.directions.shape[0] for f in fields], np.int64),
            np.array([f.directions.shape[1] for f in fields], np.int64),
            np.array([c[0] for c in cells], float), np.array([c[1] for c in cells], float))


def draws(program: Program, groups: np.ndarray, steer: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Each sub-step's random numbers, (S, D) padded, in the numpy crowd's order: group by
    group, one normal per steering member for each wander, then a dithering group's
    uniforms (behaviours × members). Normals alone are drawn in one call (a Generator's
    stream is the same cut in one piece or many)."""
    members = np.stack([(steer & (groups == g)).sum(1) for g in range(len(program.start))], axis=1) \
        if len(program.start) else np.zeros((len(steer), 0), np.int64)
    members = members * (program.count > 0)
    normals = members * program.wanders
    if not program.dithers.any():
        per = normals.sum(1)
        flat = rng.standard_normal(int(per.sum()))
        if (per == per[0]).all():
            return flat.reshape(len(per), -1)
        out = np.zeros((len(per), int(per.max())))
        ends = np.cumsum(per)
        for s, (a, b) in enumerate(zip(ends - per, ends)):
            out[s, :b - a] = flat[a:b]
        return out
    rows = []
    for s in range(len(steer)):
        parts = []
        for g in range(len(program.start)):
            m = int(members[s, g])
            if m:
                parts.append(rng.standard_normal(int(normals[s, g])))
                if program.dithers[g]:
                    parts.append(rng.random(int(program.count[g]) * m))
        rows.append(np.concatenate(parts) if parts else np.zeros(0))
    out = np.zeros((len(rows), max(len(r) for r in rows)))
    for s, r in enumerate(rows):
        out[s, :len(r)] = r
    return out


@numba.njit(cache=True, inline="always")
def _unit(x: float, y: float) -> tuple[float, float]:
    m = max(math.hypot(x, y), EPS)
    return x / m, y / m


@numba.njit(cache=True, inline="always")
def _desired(dx: float, dy: float, speed: float, vx: float, vy: float) -> tuple[float, float]:
    ux, uy = _unit(dx, dy)
    return ux * speed - vx, uy * speed - vy


@numba.njit(cache=True, inline="always")
def _truncate(x: float, y: float, limit: float) -> tuple[float, float]:
    scale = min(1.0, limit / max(math.hypot(x, y), EPS))
    return x * scale, y * scale


CELLS_PER_BODY = 4
"""Most grid cells per body (remote ones included) in the kernel's neighbour search."""


@numba.njit(cache=True)
def _layout(reach: float, size_x: float, size_y: float, n: int) -> tuple[float, int, int]:
    """The neighbour grid's cell side and its columns and rows: at least ``reach`` (so the 3 × 3
    cells round a body hold every neighbour within reach), and wide enough that the floor has
    at most :data:`CELLS_PER_BODY` cells per body (the grid is built every sub-step)."""
    cell = max(reach, 1e-3, math.sqrt(size_x * size_y / (CELLS_PER_BODY * max(n, 1))))
    return cell, max(int(math.ceil(size_x / cell)), 1), max(int(math.ceil(size_y / cell)), 1)


@numba.njit(cache=True)
def _grid(px: np.ndarray, py: np.ndarray, cell: float, nx: int, ny: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points sorted by cell (counting sort): each cell's first row in ``order`` and each point's cell."""
    n = len(px)
    where = np.empty(n, np.int64)
    first = np.zeros(nx * ny + 1, np.int64)
    for j in range(n):
        cx = min(max(int(math.floor(px[j] / cell)), 0), nx - 1)
        cy = min(max(int(math.floor(py[j] / cell)), 0), ny - 1)
        where[j] = cy * nx + cx
        first[where[j] + 1] += 1
    for c in range(nx * ny):
        first[c + 1] += first[c]
    fill = first[:-1].copy()
    order = np.empty(n, np.int64)
    for j in range(n):
        order[fill[where[j]]] = j
        fill[where[j]] += 1
    return order, first, where


@numba.njit(cache=True, inline="always")
def _nearest_k(i: int, px: np.ndarray, py: np.ndarray, order: np.ndarray, first: np.ndarray, where: np.ndarray,
               nx: int, ny: int, k: int, reach: float, index: np.ndarray, dist: np.ndarray) -> int:
    """The ``k`` nearest of the points to point ``i`` within ``reach``, nearest first, into
    ``index`` (and their squared distances into ``dist``); returns how many."""
    found, reach2 = 0, reach * reach
    if k == 0:
        return 0
    c = where[i]
    cx, cy = c % nx, c // nx
    for gy in range(max(cy - 1, 0), min(cy + 2, ny)):
        for gx in range(max(cx - 1, 0), min(cx + 2, nx)):
            g = gy * nx + gx
            for r in range(first[g], first[g + 1]):
                j = order[r]
                if j == i:
                    continue
                dx, dy = px[j] - px[i], py[j] - py[i]
                d = dx * dx + dy * dy  # squared: the order is the same, without hypot's care
                if d >= reach2 or (found == k and d >= dist[k - 1]):
                    continue
                slot = min(found, k - 1)
                while slot > 0 and dist[slot - 1] > d:
                    dist[slot], index[slot] = dist[slot - 1], index[slot - 1]
                    slot -= 1
                dist[slot], index[slot] = d, j
                found = min(found + 1, k)
    return found


@numba.njit(cache=True, inline="always")
def _target(kind: int, who: int, px: float, py: float, i: int, x: float, y: float, pos: np.ndarray, vel: np.ndarray,
            size: np.ndarray, visitors: np.ndarray, visitor_vel: np.ndarray, player: np.ndarray, loud: np.ndarray,
            notes: np.ndarray) -> tuple[bool, float, float, float, float]:
    """recipe.target_of for one creature: (present, x, y, vx, vy)."""
    if kind == 4:
        return True, size[0] / 2, size[1] / 2, 0.0, 0.0
    if kind == 5:
        return True, px, py, 0.0, 0.0
    if kind == 6:
        return i != who, pos[who, 0], pos[who, 1], vel[who, 0], vel[who, 1]
    points = visitors if kind == 0 else player if kind == 1 else loud if kind == 2 else notes
    if len(points) == 0:
        return False, x, y, 0.0, 0.0
    best, near = np.inf, 0
    for j in range(len(points)):
        d = (x - points[j, 0]) ** 2 + (y - points[j, 1]) ** 2
        if d < best:
            best, near = d, j
    if kind == 0:
        return True, points[near, 0], points[near, 1], visitor_vel[near, 0], visitor_vel[near, 1]
    return True, points[near, 0], points[near, 1], 0.0, 0.0


@numba.njit(cache=True, inline="always")
def _flee(x: float, y: float, tx: float, ty: float, panic: float, speed: float, vx: float,
          vy: float) -> tuple[float, float]:
    ax, ay = x - tx, y - ty
    if math.hypot(ax, ay) < panic:
        return _desired(ax, ay, speed, vx, vy)
    return 0.0, 0.0


@numba.njit(cache=True, inline="always")
def _obstacle(x: float, y: float, vx: float, vy: float, fx: float, fy: float, r: float, speed: float,
              centres: np.ndarray, radii: np.ndarray, lookahead: float, margin: float) -> tuple[float, float]:
    sx, sy = -fy, fx
    best, lat, alo, spn = np.inf, 0.0, 0.0, 1.0
    for o in range(len(radii)):
        rx, ry = centres[o, 0] - x, centres[o, 1] - y
        along = rx * fx + ry * fy
        lateral = rx * sx + ry * sy
        reach = radii[o] + r + margin
        span = max(math.hypot(vx, vy), 0.2 * speed) * lookahead + reach
        if along > -reach and along < span and abs(lateral) < reach and along < best:
            best, lat, alo, spn = along, lateral, along, span
    if best == np.inf:
        return 0.0, 0.0
    urgency = min(max(1.0 - alo / spn, 0.2), 1.0)
    away = -1.0 if lat > 0 else 1.0
    return sx * (away * urgency * speed), sy * (away * urgency * speed)


@numba.njit(cache=True)
def _steer(code: int, me: int, x: float, y: float, vx: float, vy: float, hx: float, hy: float, speed: float, r: float,
           dt: float, p0: float, p1: float, p2: float, present: bool, tx: float, ty: float, tvx: float, tvy: float,
           noise: float, angle: float, rows: np.ndarray, near: np.ndarray, found: int, size: np.ndarray,
           centres: np.ndarray, radii: np.ndarray) -> tuple[float, float, float]:
    """One behaviour's force on creature ``me`` (the per-creature arithmetic of :mod:`.steering`)
    and its wander angle after. Its target (``present``, at ``tx, ty`` moving ``tvx, tvy``)
    comes resolved; ``rows`` are the crowd's and the remote creatures' x, y, vx, vy, radius
    (5, N), ``near`` the ``found`` neighbours' columns. Scalars in, scalars out: a call that
    passed the crowd's arrays cost ~0.2 µs a creature a behaviour in argument handling alone."""
    fx, fy = _unit(vx, vy) if math.hypot(vx, vy) > 1e-6 else (hx, hy)  # Scene.forward
    nothing = (0.0, 0.0, angle)
    if code <= EVASION:
        if not present:
            return nothing
        if code == PURSUIT or code == EVASION:  # steering._predicted
            t = min(math.hypot(tx - x, ty - y) / max(speed, EPS), p0)
            tx, ty = tx + tvx * t, ty + tvy * t
        if code == SEEK or code == PURSUIT:
            ax, ay = _desired(tx - x, ty - y, speed, vx, vy)
        elif code == FLEE or code == EVASION:
            ax, ay = _flee(x, y, tx, ty, p0 if code == FLEE else p1, speed, vx, vy)
        else:  # arrival
            ox, oy = tx - x, ty - y
            d = math.hypot(ox, oy)
            want = speed * min(d / p0, 1.0)
            m = max(d, EPS)
            ax, ay = (ox / m * want - vx) / p1, (oy / m * want - vy) / p1
        return ax, ay, angle
    if code == WANDER:
        a = angle + p0 * math.sqrt(dt) * noise
        sx, sy = -fy, fx
        c, s = math.cos(a), math.sin(a)
        ax, ay = _desired(fx * p2 + (fx * c + sx * s) * p1, fy * p2 + (fy * c + sy * s) * p1, speed, vx, vy)
        return ax, ay, a
    if code == OBSTACLE:
        if len(radii) == 0:
            return nothing
        ax, ay = _obstacle(x, y, vx, vy, fx, fy, r, speed, centres, radii, p0, p1)
        return ax, ay, angle
    if code == WALL:
        low = r + p1
        gx, gy = x + vx * p0, y + vy * p0
        dx = max(low - gx, 0.0) - max(gx - (size[0] - low), 0.0)
        dy = max(low - gy, 0.0) - max(gy - (size[1] - low), 0.0)
        return dx / p1 * speed, dy / p1 * speed, angle
    allx, ally, allvx, allvy, allr = rows[0], rows[1], rows[2], rows[3], rows[4]
    sx, sy, first = 0.0, 0.0, np.inf
    for q in range(found):
        j = near[q]
        if code == SEPARATION:
            ox, oy = x - allx[j], y - ally[j]
            d = math.hypot(ox, oy)
            if d < EPS:  # steering.apart: one point, the pair's own direction
                a, sign = GOLDEN * (me + j), EPS if me > j else -EPS
                ox, oy = math.cos(a) * sign, math.sin(a) * sign
                d = math.hypot(ox, oy)
            personal = p0 * (r + allr[j])
            safe = max(d, EPS)
            if d < personal:
                factor = (personal / safe - 1.0) / safe
                sx, sy = sx + ox * factor, sy + oy * factor
        elif code == COHESION:
            sx, sy = sx + allx[j], sy + ally[j]
        elif code == ALIGNMENT:
            ux, uy = _unit(allvx[j], allvy[j])
            sx, sy = sx + ux, sy + uy
        else:  # agent avoidance: the neighbour met soonest
            dpx, dpy = allx[j] - x, ally[j] - y
            dvx, dvy = allvx[j] - vx, allvy[j] - vy
            t = max(-(dpx * dvx + dpy * dvy) / max(dvx * dvx + dvy * dvy, EPS), 0.0)
            if t < p0 and math.hypot(dpx + dvx * t, dpy + dvy * t) < r + allr[j] + p1 and t < first:
                first = t
                sx = (x + vx * t) - (allx[j] + allvx[j] * t)
                sy = (y + vy * t) - (ally[j] + allvy[j] * t)
    if code == SEPARATION:
        return sx * speed, sy * speed, angle
    if code == COHESION:
        if found == 0:
            return nothing
        ax, ay = _desired(sx / found - x, sy / found - y, speed, vx, vy)
        return ax, ay, angle
    if code == ALIGNMENT:
        if found == 0 or math.hypot(sx, sy) <= EPS:
            return nothing
        ax, ay = _desired(sx, sy, speed, vx, vy)
        return ax, ay, angle
    if first == np.inf:
        return nothing
    ux, uy = _unit(sx, sy)
    urgency = 1.0 - first / p0
    return ux * (urgency * speed), uy * (urgency * speed), angle


@numba.njit(cache=True)
def _follow_path(x: float, y: float, vx: float, vy: float, speed: float, accel: float, lead: float, response: float,
                 p: int, paths: tuple) -> tuple[float, float]:
    """steering.path_following for one creature on path ``p`` of :attr:`Program.paths`."""
    points, starts, along, radii, where, fits, bend_starts = paths
    a0, a1 = starts[p], starts[p + 1]
    radius = radii[p]
    best, seg, fx, fy = np.inf, 0, x, y
    for k in range(a0, a1 - 1):  # steering.project
        ax, ay = points[k, 0], points[k, 1]
        abx, aby = points[k + 1, 0] - ax, points[k + 1, 1] - ay
        t = min(max(((x - ax) * abx + (y - ay) * aby) / max(abx * abx + aby * aby, EPS), 0.0), 1.0)
        footx, footy = ax + t * abx, ay + t * aby
        d = math.hypot(x - footx, y - footy)
        if d < best:
            best, seg, fx, fy = d, k, footx, footy
    total = along[a1 - 1]
    walked = min(max(along[seg] + math.hypot(fx - points[seg, 0], fy - points[seg, 1]) + lead, 0.0), total)
    i = a0  # steering.along_path: the segment the walked distance ends on
    while i < a1 - 2 and along[i + 1] <= walked:
        i += 1
    frac = (walked - along[i]) / max(math.hypot(points[i + 1, 0] - points[i, 0], points[i + 1, 1] - points[i, 1]),
                                     EPS)
    hx = points[i, 0] + (points[i + 1, 0] - points[i, 0]) * frac
    hy = points[i, 1] + (points[i + 1, 1] - points[i, 1]) * frac
    at = along[seg + 1] - math.hypot(points[seg + 1, 0] - fx, points[seg + 1, 1] - fy)
    limit = np.inf
    b0, b1 = bend_starts[p], bend_starts[p + 1]
    for b in range(b0, b1):
        to_bend = where[b] - at
        if b == b1 - 1:  # the end: back to it from past it
            to_bend = max(to_bend, math.hypot(points[a1 - 1, 0] - x, points[a1 - 1, 1] - y))
        braking = max(to_bend - 2 * lead if fits[b] > 0 else to_bend, 0.0)
        if to_bend > -radius:
            limit = min(limit, math.sqrt(accel * fits[b] * radius / 2 + accel * braking))
    ax, ay = _desired(hx - x, hy - y, min(speed, limit), vx, vy)
    return ax / response, ay / response


@numba.njit(cache=True)
def _follow_field(x: float, y: float, vx: float, vy: float, speed: float, lookahead: float, f: int,
                  fields: tuple) -> tuple[float, float]:
    """steering.flow_following for one creature on field ``f`` of :attr:`Program.fields`."""
    flat, starts, rows, cols, across, deep = fields
    gx, gy = x + vx * lookahead, y + vy * lookahead
    j = min(max(int(gx / across[f]), 0), cols[f] - 1)
    i = min(max(int(gy / deep[f]), 0), rows[f] - 1)
    c = starts[f] + i * cols[f] + j
    dx, dy = flat[c, 0], flat[c, 1]
    if math.hypot(dx, dy) > EPS:
        return _desired(dx, dy, speed, vx, vy)
    return 0.0, 0.0


@numba.njit(cache=True)
def _follow_leader(x: float, y: float, vx: float, vy: float, speed: float, r: float, lx: float, ly: float,
                   lvx: float, lvy: float, hx: float, hy: float, behind: float, slowing: float,
                   clear: float) -> tuple[float, float]:
    """steering.leader_following for one creature (arrival behind the leader, evasion from its way)."""
    bx, by = _unit(lvx, lvy) if math.hypot(lvx, lvy) > 1e-6 else _unit(hx, hy)
    ox, oy = lx - bx * behind - x, ly - by * behind - y  # arrival, response 0.25
    d = math.hypot(ox, oy)
    want = speed * min(d / slowing, 1.0)
    m = max(d, EPS)
    fx, fy = (ox / m * want - vx) / 0.25, (oy / m * want - vy) / 0.25
    rx, ry = x - lx, y - ly
    ahead = rx * bx + ry * by
    lateral = math.hypot(rx - bx * ahead, ry - by * ahead)
    if ahead > 0 and ahead < clear and lateral < r * 2 + clear / 2:  # evasion: horizon 2 s, no panic distance
        t = min(math.hypot(lx - x, ly - y) / max(speed, EPS), 2.0)
        ex, ey = _flee(x, y, lx + lvx * t, ly + lvy * t, np.inf, speed, vx, vy)
        fx, fy = fx + ex, fy + ey
    return fx, fy


@numba.njit(cache=True, inline="always")
def _contain(i: int, pos: np.ndarray, vel: np.ndarray, r: float, size: np.ndarray, centres: np.ndarray,
             radii: np.ndarray) -> None:
    """Room.contain for one body: the walls, then the obstacles it overlaps (each pushed from
    where the walls left it), then the walls again."""
    for a in range(2):
        low, high = r, size[a] - r
        if pos[i, a] < low:
            pos[i, a] = low
            vel[i, a] = max(vel[i, a], 0.0)
        elif pos[i, a] > high:
            pos[i, a] = high
            vel[i, a] = min(vel[i, a], 0.0)
    x0, y0 = pos[i, 0], pos[i, 1]
    pushed = False
    for o in range(len(radii)):
        dx, dy = x0 - centres[o, 0], y0 - centres[o, 1]
        dist = math.hypot(dx, dy)
        reach = r + radii[o]
        if dist < reach:
            nx, ny = (dx / dist, dy / dist) if dist > 1e-12 else (1.0, 0.0)
            pos[i, 0], pos[i, 1] = centres[o, 0] + nx * reach, centres[o, 1] + ny * reach
            into = vel[i, 0] * nx + vel[i, 1] * ny
            if into < 0:
                vel[i, 0] -= into * nx
                vel[i, 1] -= into * ny
            pushed = True
    if pushed:
        for a in range(2):
            pos[i, a] = min(max(pos[i, a], r), size[a] - r)


@numba.njit(cache=True)
def substeps(dt: float, steer: np.ndarray, noise: np.ndarray, pos: np.ndarray, vel: np.ndarray, heading: np.ndarray,
             mass: np.ndarray, max_force: np.ndarray, max_speed: np.ndarray, radius: np.ndarray,
             max_turn: np.ndarray, force: np.ndarray, angle: np.ndarray, gain: np.ndarray, groups: np.ndarray,
             others: np.ndarray, size: np.ndarray, centres: np.ndarray, radii: np.ndarray,
             g_start: np.ndarray, g_count: np.ndarray, g_policy: np.ndarray, g_k: np.ndarray, g_reach: np.ndarray,
             g_wanders: np.ndarray, code: np.ndarray, weight: np.ndarray, probability: np.ndarray,
             tkind: np.ndarray, twho: np.ndarray, tpoint: np.ndarray, par: np.ndarray, ordinal: np.ndarray,
             data: np.ndarray, paths: tuple, fields: tuple, visitors: np.ndarray, visitor_vel: np.ndarray,
             player: np.ndarray, loud: np.ndarray, notes: np.ndarray) -> None:
    """``len(steer)`` sub-steps of ``dt``: on each, the remote ``others`` move on by their
    velocity, the creatures ``steer[s]`` marks steer (the rest keep their last ``force``),
    then every creature moves and is kept in the room (Crowd.step, Vehicles.step, Room.contain)."""
    n, o_n, groups_n = len(pos), len(others), len(g_start)
    total = n + o_n
    rows = np.empty((5, total))
    allx, ally, allvx, allvy, allr = rows[0], rows[1], rows[2], rows[3], rows[4]
    cell, nx, ny = _layout(g_reach.max() if groups_n else 1.0, size[0], size[1], total)
    kmax = max(g_k.max() if groups_n else 1, 1)
    near, dist = np.empty(kmax, np.int64), np.empty(kmax)
    members, base, rank = np.zeros(groups_n, np.int64), np.zeros(groups_n, np.int64), np.zeros(n, np.int64)
    forces = np.empty((max(g_count.max() if groups_n else 1, 1), 2))
    for s in range(len(steer)):
        for j in range(o_n):
            others[j, 0] += others[j, 2] * dt
            others[j, 1] += others[j, 3] * dt
        if steer[s].any():
            for j in range(n):
                allx[j], ally[j], allvx[j], allvy[j], allr[j] = pos[j, 0], pos[j, 1], vel[j, 0], vel[j, 1], radius[j]
            for j in range(o_n):
                row = others[j]
                allx[n + j], ally[n + j], allvx[n + j], allvy[n + j], allr[n + j] = row[0], row[1], row[2], row[3], row[6]
            order, first, where = _grid(allx, ally, cell, nx, ny)
            members[:] = 0
            for i in range(n):
                if steer[s, i]:
                    rank[i] = members[groups[i]]
                    members[groups[i]] += 1
            cursor = 0
            for g in range(groups_n):
                if members[g] and g_count[g]:
                    base[g] = cursor
                    cursor += members[g] * (g_wanders[g] + (g_count[g] if g_policy[g] == 2 else 0))
            for i in range(n):
                if not steer[s, i]:
                    continue
                g = groups[i]
                count = g_count[g]
                if count == 0:
                    force[i, 0], force[i, 1] = 0.0, 0.0
                    continue
                found = _nearest_k(i, allx, ally, order, first, where, nx, ny, g_k[g], g_reach[g], near, dist)
                m, j = members[g], rank[i]
                for k in range(count):
                    b = g_start[g] + k
                    z = noise[s, base[g] + ordinal[b] * m + j] if ordinal[b] >= 0 else 0.0
                    present, tx, ty, tvx, tvy = True, 0.0, 0.0, 0.0, 0.0
                    if code[b] <= EVASION or code[b] == LEADER:
                        present, tx, ty, tvx, tvy = _target(tkind[b], twho[b], tpoint[b, 0], tpoint[b, 1], i,
                                                            pos[i, 0], pos[i, 1], pos, vel, size, visitors,
                                                            visitor_vel, player, loud, notes)
                    if code[b] == PATH:
                        fx, fy = _follow_path(pos[i, 0], pos[i, 1], vel[i, 0], vel[i, 1], max_speed[i],
                                              max_force[i] / mass[i], par[b, 0], par[b, 1], data[b], paths)
                    elif code[b] == FLOW:
                        fx, fy = _follow_field(pos[i, 0], pos[i, 1], vel[i, 0], vel[i, 1], max_speed[i], par[b, 0],
                                               data[b], fields)
                    elif code[b] == LEADER:
                        fx, fy = 0.0, 0.0
                        if present:
                            hx, hy = (heading[twho[b], 0], heading[twho[b], 1]) if tkind[b] == CREATURE else (1.0, 0.0)
                            fx, fy = _follow_leader(pos[i, 0], pos[i, 1], vel[i, 0], vel[i, 1], max_speed[i],
                                                    radius[i], tx, ty, tvx, tvy, hx, hy, par[b, 0], par[b, 1],
                                                    par[b, 2])
                    else:
                        fx, fy, angle[i] = _steer(code[b], i, pos[i, 0], pos[i, 1], vel[i, 0], vel[i, 1],
                                                  heading[i, 0], heading[i, 1], max_speed[i], radius[i], dt,
                                                  par[b, 0], par[b, 1], par[b, 2], present, tx, ty, tvx, tvy, z,
                                                  angle[i], rows, near, found, size, centres, radii)
                    forces[k, 0], forces[k, 1] = fx * gain[i, k], fy * gain[i, k]
                policy = g_policy[g]
                tx, ty, left, open_ = 0.0, 0.0, max_force[i], True
                for k in range(count):
                    w = weight[g_start[g] + k]
                    fx, fy = forces[k, 0], forces[k, 1]
                    if policy == 0:
                        tx, ty = tx + w * fx, ty + w * fy
                    elif policy == 1:
                        fx, fy = w * fx, w * fy
                        length = math.hypot(fx, fy)
                        take = min(length, left)
                        scale = take / max(length, EPS)
                        tx, ty = tx + fx * scale, ty + fy * scale
                        left -= take
                    elif open_ and math.hypot(fx, fy) > EPS and \
                            noise[s, base[g] + g_wanders[g] * m + k * m + j] < probability[g_start[g] + k]:
                        tx, ty, open_ = w * fx, w * fy, False
                if policy != 1:
                    tx, ty = _truncate(tx, ty, max_force[i])
                force[i, 0], force[i, 1] = tx, ty
        for i in range(n):
            ax, ay = _truncate(force[i, 0], force[i, 1], max_force[i])
            vx, vy = _truncate(vel[i, 0] + ax / mass[i] * dt, vel[i, 1] + ay / mass[i] * dt, max_speed[i])
            vel[i, 0], vel[i, 1] = vx, vy
            pos[i, 0] += vx * dt
            pos[i, 1] += vy * dt
        for i in range(n):
            vx, vy = vel[i, 0], vel[i, 1]
            if math.hypot(vx, vy) > 1e-3:  # Vehicles.face
                have = math.atan2(heading[i, 1], heading[i, 0])
                turn = (math.atan2(vy, vx) - have + math.pi) % (2 * math.pi) - math.pi
                limit = max_turn[i] * dt
                new = have + min(max(turn, -limit), limit)
                heading[i, 0], heading[i, 1] = math.cos(new), math.sin(new)
            _contain(i, pos, vel, radius[i], size, centres, radii)


@numba.njit(cache=True)
def _all_nearest(px: np.ndarray, py: np.ndarray, k: int, reach: float, size_x: float, size_y: float,
                 index: np.ndarray) -> None:
    cell, nx, ny = _layout(reach, size_x, size_y, len(px))
    order, first, where = _grid(px, py, cell, nx, ny)
    near, dist = np.empty(k, np.int64), np.empty(k)
    for i in range(len(px)):
        found = _nearest_k(i, px, py, order, first, where, nx, ny, k, reach, near, dist)
        index[i, :found] = near[:found]
        index[i, found:] = len(px)


def nearest(pos: np.ndarray, k: int, reach: float, size: np.ndarray) -> np.ndarray:
    """Each point's ``k`` nearest others within ``reach`` by the kernel's grid, nearest first,
    padded with ``len(pos)`` (:class:`creatures.room.index.Neighbourhood`'s convention): what
    a sub-step asks of it, for the benchmark and the tests to hold against the kd-tree."""
    pos = np.ascontiguousarray(pos, dtype=float)
    index = np.empty((len(pos), k), np.int64)
    _all_nearest(pos[:, 0].copy(), pos[:, 1].copy(), k, reach, float(size[0]), float(size[1]), index)
    return index
