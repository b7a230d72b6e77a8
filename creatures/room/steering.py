"""Steering behaviours (Reynolds 1999; REACT 2.2.2 "Steering behaviours"; OpenSteer), each
one small function from the steering creatures (a :class:`Scene`) to one force per creature.

Every function is vectorised over the M creatures that steer on this sub-step: arrays in,
an (M, 2) force out, no loop over creatures. Forces are in OpenSteer's units, a desired change
of velocity (m/s): seek-like behaviours return ``desired_velocity - velocity``, pushes
(separation, avoidance) return a vector of up to ``max_speed``. :mod:`.combine` weighs them
into one and the vehicle truncates that to its maximum force.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from creatures.room.index import Neighbourhood
from creatures.room.space import Room
from creatures.room.vehicle import EPS, dot, norms, unit


@dataclass
class Scene:
    """What the M steering creatures know this sub-step: their own rows of the crowd, their
    neighbours (``near``; their positions and velocities gathered as (M, k, 2)), and the room."""

    who: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    heading: np.ndarray
    max_speed: np.ndarray
    radius: np.ndarray
    near: Neighbourhood
    nbr_pos: np.ndarray
    nbr_vel: np.ndarray
    nbr_radius: np.ndarray
    room: Room
    accel: np.ndarray
    """Each one's largest acceleration, max force / mass (m/s²): path following brakes by it."""

    def forward(self) -> np.ndarray:
        """Direction of travel: the velocity's, or the heading when at rest."""
        moving = norms(self.vel) > 1e-6
        return np.where(moving[:, None], unit(self.vel), self.heading)


def _desired(s: Scene, direction: np.ndarray, speed: np.ndarray | None = None) -> np.ndarray:
    """Reynolds' steering = desired velocity − velocity, the desired one along ``direction``."""
    speed = s.max_speed if speed is None else speed
    return unit(direction) * speed[:, None] - s.vel


# -- one target ----------------------------------------------------------------------------
def seek(s: Scene, target: np.ndarray) -> np.ndarray:
    """Head for ``target`` (M, 2) at full speed (REACT "Seek")."""
    return _desired(s, target - s.pos)


def flee(s: Scene, threat: np.ndarray, *, panic: float = np.inf) -> np.ndarray:
    """Run from ``threat`` at full speed while it is nearer than ``panic`` m (REACT "Flee")."""
    away = s.pos - threat
    near = norms(away) < panic
    return np.where(near[:, None], _desired(s, away), 0.0)


def arrival(s: Scene, target: np.ndarray, *, slowing: float = 1.0, response: float = 0.25) -> np.ndarray:
    """Seek that slows linearly inside ``slowing`` m and stops on the target (REACT "Arrival").

    The velocity error is divided by ``response`` (s): with Reynolds' plain ``desired − velocity``
    the approach is a spring damped at half the critical rate and overshoots by ~15 %; tracking
    the desired speed within a quarter second makes the last metre an exponential glide."""
    offset = target - s.pos
    d = norms(offset)
    speed = s.max_speed * np.minimum(d / slowing, 1.0)
    return (offset / np.maximum(d, EPS)[:, None] * speed[:, None] - s.vel) / response


def _predicted(s: Scene, other: np.ndarray, other_vel: np.ndarray, horizon: float) -> np.ndarray:
    """Where ``other`` will be when we could reach it (time ≈ distance / speed, capped)."""
    t = np.minimum(norms(other - s.pos) / np.maximum(s.max_speed, EPS), horizon)
    return other + other_vel * t[:, None]


def pursuit(s: Scene, quarry: np.ndarray, quarry_vel: np.ndarray, *, horizon: float = 2.0) -> np.ndarray:
    """Seek where the quarry is going, not where it is (REACT "Pursuit")."""
    return seek(s, _predicted(s, quarry, quarry_vel, horizon))


def evasion(s: Scene, threat: np.ndarray, threat_vel: np.ndarray, *, horizon: float = 2.0,
            panic: float = np.inf) -> np.ndarray:
    """Flee from where the threat is going (REACT "Evasion")."""
    return flee(s, _predicted(s, threat, threat_vel, horizon), panic=panic)


def wander(s: Scene, angle: np.ndarray, noise: np.ndarray, *, rate: float, radius: float = 0.5,
           distance: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Steer toward a point on a circle ahead whose angle drifts at random (REACT "Wander":
    a random displacement added to the previous one, so the path meanders instead of
    jittering). ``noise`` is one standard normal per creature; ``rate`` (rad/√s, already
    times √dt by the caller) sets how fast the angle drifts. Returns (force, new angle)."""
    angle = angle + rate * noise
    fwd = s.forward()
    side = np.stack([-fwd[:, 1], fwd[:, 0]], axis=1)
    target = fwd * distance + (fwd * np.cos(angle)[:, None] + side * np.sin(angle)[:, None]) * radius
    return _desired(s, target), angle


# -- the neighbours (flocking: Reynolds 1987) -----------------------------------------------
GOLDEN = np.pi * (3.0 - np.sqrt(5.0))
"""The golden angle, rad: the directions two bodies at one point part in (:func:`apart`)."""


def apart(me: np.ndarray, other: np.ndarray) -> np.ndarray:
    """The offset, ``EPS`` long, from body ``other`` to body ``me`` when they stand at one point
    (clones of one ``at``, or two bodies pushed into one corner by the walls): it has no
    direction, and separation's push along it was zero, so they never parted. Each pair parts
    along its own direction (the golden angle × the sum of their indices), opposite for the
    two of it."""
    angle = GOLDEN * (me + other)
    sign = np.where(me > other, EPS, -EPS)
    return np.stack([np.cos(angle), np.sin(angle)], axis=-1) * sign[..., None]


def separation(s: Scene, *, reach: float = 3.0) -> np.ndarray:
    """Push away from neighbours nearer than ``reach`` × the two bodies' radii, harder the
    closer they are (REACT "Separation"): each contributes its direction away × (reach·r / d − 1);
    from one at the same point, the pair's own direction (:func:`apart`)."""
    offset = s.pos[:, None, :] - s.nbr_pos
    d = norms(offset)
    together = s.near.mask & (d < EPS)
    if together.any():
        offset = np.where(together[..., None], apart(s.who[:, None], s.near.index), offset)
        d = norms(offset)
    personal = reach * (s.radius[:, None] + s.nbr_radius)
    safe = np.maximum(d, EPS)
    factor = np.where(s.near.mask & (d < personal), (personal / safe - 1.0) / safe, 0.0)  # weight / distance
    return np.einsum("mkc,mk->mc", offset, factor) * s.max_speed[:, None]


def cohesion(s: Scene) -> np.ndarray:
    """Seek the centre of the neighbours (REACT "Cohesion")."""
    n = s.near.mask.sum(1)
    centre = np.einsum("mkc,mk->mc", s.nbr_pos, s.near.mask.astype(float)) / np.maximum(n, 1)[:, None]
    return np.where((n > 0)[:, None], seek(s, centre), 0.0)


def alignment(s: Scene) -> np.ndarray:
    """Match the neighbours' mean direction of travel at full speed (REACT "Alignment")."""
    n = s.near.mask.sum(1)
    mean = np.einsum("mkc,mk->mc", unit(s.nbr_vel), s.near.mask.astype(float))
    return np.where((n > 0)[:, None] & (norms(mean) > EPS)[:, None], _desired(s, mean), 0.0)


# -- avoiding what is in the way -------------------------------------------------------------
def obstacle_avoidance(s: Scene, *, lookahead: float = 1.5, margin: float = 0.2) -> np.ndarray:
    """Steer sideways from the nearest obstacle in the corridor ahead, ``lookahead`` seconds
    of travel long and a body plus ``margin`` m wide (REACT "Obstacle avoidance"); zero when
    the way is clear. The margin keeps a creature that has just cleared the corridor from
    being pulled straight back to graze the rim by whatever it was seeking."""
    room = s.room
    if not room.obstacles:
        return np.zeros_like(s.pos)
    fwd = s.forward()
    side = np.stack([-fwd[:, 1], fwd[:, 0]], axis=1)
    rel = room.centres[None, :, :] - s.pos[:, None, :]  # (M, O, 2)
    along = dot(rel, fwd[:, None, :])
    lateral = dot(rel, side[:, None, :])
    reach = room.radii[None, :] + s.radius[:, None] + margin
    span = np.maximum(norms(s.vel), 0.2 * s.max_speed)[:, None] * lookahead + reach
    threat = (along > -reach) & (along < span) & (np.abs(lateral) < reach)
    nearest = np.argmin(np.where(threat, along, np.inf), axis=1)
    any_threat = threat.any(1)
    rows = np.arange(len(nearest))
    lat, alo, spn = lateral[rows, nearest], along[rows, nearest], span[rows, nearest]
    urgency = np.clip(1.0 - alo / spn, 0.2, 1.0)
    away = np.where(lat > 0, -1.0, 1.0)  # obstacle to our left: steer right
    return np.where(any_threat[:, None], side * (away * urgency * s.max_speed)[:, None], 0.0)


def wall_avoidance(s: Scene, *, lookahead: float = 1.0, margin: float = 0.5) -> np.ndarray:
    """Push in from any wall the creature would be within ``margin`` m of after ``lookahead``
    seconds of travel (REACT "Wall following / containment"), harder the deeper it would go."""
    future = s.pos + s.vel * lookahead
    low = s.radius[:, None] + margin
    high = s.room.size[None, :] - low
    depth = np.clip(low - future, 0.0, None) - np.clip(future - high, 0.0, None)
    return depth / margin * s.max_speed[:, None]


def agent_avoidance(s: Scene, *, horizon: float = 2.0, margin: float = 0.1) -> np.ndarray:
    """Unaligned collision avoidance (REACT "Agent avoidance"): find the neighbour whose
    closest approach, on both present velocities, comes soonest within ``horizon`` s and nearer
    than the two radii plus ``margin``; steer away from where it will be then."""
    dp = s.nbr_pos - s.pos[:, None, :]
    dv = s.nbr_vel - s.vel[:, None, :]
    t = np.clip(-dot(dp, dv) / np.maximum(dot(dv, dv), EPS), 0.0, None)
    miss = norms(dp + dv * t[..., None])
    threat = s.near.mask & (t < horizon) & (miss < s.radius[:, None] + s.nbr_radius + margin)
    first = np.argmin(np.where(threat, t, np.inf), axis=1)
    any_threat = threat.any(1)
    rows = np.arange(len(first))
    tf = t[rows, first]
    me = s.pos + s.vel * tf[:, None]
    them = s.nbr_pos[rows, first] + s.nbr_vel[rows, first] * tf[:, None]
    away = me - them
    urgency = 1.0 - tf / horizon
    return np.where(any_threat[:, None], unit(away) * (urgency * s.max_speed)[:, None], 0.0)


# -- following what the director laid down ---------------------------------------------------
def path_following(s: Scene, points: np.ndarray, radius: float, *, lead: float = 1.0,
                   response: float = 0.25) -> np.ndarray:
    """Stay within ``radius`` of the polyline ``points`` (P, 2), going along it to its end
    (REACT "Path following"; REACTPath's radius is how far the agent may deviate).

    Pure pursuit: seek the point ``lead`` m on along the path from the body's nearest point of
    it, so a body off the path comes back on a slant and one on it keeps to it. Before a bend
    the desired speed falls, braking at half the vehicle's acceleration ``a`` (max force /
    mass; the other half steers), from ``lead`` before it, to the speed at which the turn fits
    inside the path: an arc of radius R at full force, v = sqrt(a R), with R the largest arc
    whose inside cut of a turn by θ stays within ``radius`` (R = radius · cos(θ/2) / (1 −
    cos(θ/2))); and to rest at the end. Reynolds' version keeps only the position predicted a
    second ahead on the path: the body itself strayed up to 1.2 m from a 0.5 m path at 2 m/s
    (tests/test_room_steering.py)."""
    at, seg, _ = project(points, s.pos)
    ahead = along_path(points, seg, at, lead)
    walked = np.cumsum(norms(points[1:] - points[:-1]))[seg] - norms(points[seg + 1] - at)  # `at`, along the path
    where, fits = _bends(points)
    to_bend = where[None, :] - walked[:, None]
    to_bend[:, -1] = np.maximum(to_bend[:, -1], norms(points[-1] - s.pos))  # past the end: back to it
    a = s.accel[:, None]
    braking = np.maximum(np.where(fits[None, :] > 0, to_bend - 2 * lead, to_bend), 0.0)  # the end: to rest on it
    allowed = np.sqrt(a * fits[None, :] * radius / 2 + a * braking)
    speed = np.minimum(s.max_speed, np.where(to_bend > -radius, allowed, np.inf).min(axis=1))
    return _desired(s, ahead - s.pos, speed) / response


def _bends(points: np.ndarray, *, straight: float = np.radians(5.0)) -> tuple[np.ndarray, np.ndarray]:
    """Where the path turns by more than ``straight``, and its end: the distance along it and
    the radius of the arc that fits there, per metre of the path's radius (0 at the end)."""
    d = points[1:] - points[:-1]
    cumulative = np.cumsum(norms(d))
    heading = np.arctan2(d[:, 1], d[:, 0])
    turn = np.abs((np.diff(heading) + np.pi) % (2 * np.pi) - np.pi)
    sharp = np.flatnonzero(turn > straight)
    half = np.cos(turn[sharp] / 2)
    return (np.concatenate([cumulative[sharp], cumulative[-1:]]),
            np.concatenate([half / np.maximum(1.0 - half, EPS), np.zeros(1)]))


def project(points: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest point of the polyline ``points`` to each of ``q`` (M, 2): the point, the index
    of its segment and that segment's unit tangent."""
    a, b = points[:-1], points[1:]  # (S, 2)
    ab = b - a
    t = ((q[:, None, :] - a[None]) * ab[None]).sum(-1) / np.maximum((ab * ab).sum(-1), EPS)[None]
    t = np.clip(t, 0.0, 1.0)
    foot = a[None] + t[..., None] * ab[None]  # (M, S, 2)
    seg = np.argmin(norms(q[:, None, :] - foot), axis=1)
    rows = np.arange(len(q))
    return foot[rows, seg], seg, unit(ab)[seg]


def along_path(points: np.ndarray, seg: np.ndarray, at: np.ndarray, lead: float) -> np.ndarray:
    """The point ``lead`` m further along the polyline from ``at`` (on segment ``seg``),
    clamped to the end."""
    lengths = norms(points[1:] - points[:-1])
    cumulative = np.concatenate([[0.0], np.cumsum(lengths)])
    walked = cumulative[seg] + norms(at - points[seg]) + lead
    walked = np.clip(walked, 0.0, cumulative[-1])
    i = np.clip(np.searchsorted(cumulative, walked, side="right") - 1, 0, len(lengths) - 1)
    frac = (walked - cumulative[i]) / np.maximum(lengths[i], EPS)
    return points[i] + (points[i + 1] - points[i]) * frac[:, None]


def flow_following(s: Scene, field: np.ndarray, cell: float | tuple[float, float], *,
                   lookahead: float = 0.5) -> np.ndarray:
    """Match the flow field's direction where we will be in ``lookahead`` s (REACT
    "Flow field following"; REACTFlowfield, painted by the director). ``field`` is (rows,
    cols, 2) of directions over cells ``cell`` m square (or (across, deep) m) from the room's corner."""
    future = s.pos + s.vel * lookahead
    rows, cols = field.shape[:2]
    across, deep = np.broadcast_to(np.asarray(cell, dtype=float), (2,))
    j = np.clip((future[:, 0] / across).astype(int), 0, cols - 1)
    i = np.clip((future[:, 1] / deep).astype(int), 0, rows - 1)
    direction = field[i, j]
    return np.where((norms(direction) > EPS)[:, None], _desired(s, direction), 0.0)


def leader_following(s: Scene, leader: np.ndarray, leader_vel: np.ndarray, leader_heading: np.ndarray, *,
                     behind: float = 1.0, slowing: float = 1.0, clear: float = 1.0) -> np.ndarray:
    """Arrive at a point ``behind`` m behind the leader, and get out of its way when in the
    corridor ``clear`` m ahead of it (REACT "Leader following"; followers' spacing comes from
    separation, combined by the caller)."""
    back = unit(np.where((norms(leader_vel) > 1e-6)[:, None], leader_vel, leader_heading))
    follow = arrival(s, leader - back * behind, slowing=slowing)
    rel = s.pos - leader
    ahead = dot(rel, back)
    lateral = norms(rel - back * ahead[:, None])
    in_way = (ahead > 0) & (ahead < clear) & (lateral < s.radius * 2 + clear / 2)
    return follow + np.where(in_way[:, None], evasion(s, leader, leader_vel), 0.0)
