"""A terrier: a four-legged skeleton of 31 joints and the clips Duncan is trained on.

Thesis, "Duncan" and "simple shaping": the dog sits, lies down, begs and rolls over, and the
height of a beg is shaped by reward, so the beg clip holds "a continuous variety of
qualitatively similar animations" — front paws rising slowly from a low beg to a high one,
every frame labelled ``beg`` — and the motor graph can stop at any height. The walk is a
lateral-sequence gait (hind left, fore left, hind right, fore right) with root motion:
planted paws are solved by :func:`~creatures.body.generate.rig.planar_leg` against the
moving body, so a paw in contact does not slide.

A posture is a flat dict of numbers (root height and pitch, spine, paw targets, how far each
leg is lifted out of contact) so two postures blend by blending numbers; :func:`frame` turns
one into joint rotations. Planted legs are solved after blending (the paws stay put while
the body moves over them); lifted legs blend their angles.
"""

from __future__ import annotations

import math

import numpy as np

from creatures.body.generate.rig import FPS, Y, Z, Clip, Frame, Rig, planar_leg, smooth
from creatures.motor.pose import LOW_ENERGY
from creatures.motor.skeleton import Skeleton

LEGS = {  # leg → (upper joint, middle, lower, paw, bones (upper, middle, lower), bend, torso joint)
    "hl": ("hip_l", "stifle_l", "hock_l", "hind_paw_l", (0.15, 0.14, 0.07), -1.0, "pelvis"),
    "hr": ("hip_r", "stifle_r", "hock_r", "hind_paw_r", (0.15, 0.14, 0.07), -1.0, "pelvis"),
    "fl": ("shoulder_l", "elbow_l", "wrist_l", "front_paw_l", (0.14, 0.14, 0.07), 1.0, "chest"),
    "fr": ("shoulder_r", "elbow_r", "wrist_r", "front_paw_r", (0.14, 0.14, 0.07), 1.0, "chest"),
}
HIND_Z, FRONT_Z = -0.02, 0.40
"""Where the paws stand under the hips and shoulders (world z, the body's root at 0)."""

WALK_SPEED = 0.5
"""Metres per second of the walk."""
WALK_PERIOD = 0.8
"""Seconds of one gait cycle (12 frames at 15 fps)."""
DUTY = 0.6
"""Share of a cycle each paw is planted."""
PHASES = {"hl": 0.0, "fl": 0.25, "hr": 0.5, "fr": 0.75}
"""Lateral-sequence walk: each paw's offset in the cycle."""
SWING_LIFT = 0.05
"""Metres a paw rises at the middle of its swing."""


def skeleton() -> Skeleton:
    """The dog: pelvis root, spine, chest, neck, head and nose; a tail of three; four legs of
    upper, middle and lower bone with a paw and its toe (end sites make the end-effectors)."""
    r = Rig()
    r.chain(None, ("pelvis", (0.0, 0.0, 0.0)), ("spine", (0.0, 0.02, 0.18)), ("chest", (0.0, 0.0, 0.18)),
            ("neck", (0.0, 0.06, 0.08)), ("head", (0.0, 0.10, 0.05)), ("nose", (0.0, -0.02, 0.10)),
            ("nose_end", (0.0, -0.01, 0.04)))
    r.chain("pelvis", ("tail1", (0.0, 0.03, -0.05)), ("tail2", (0.0, 0.05, -0.06)), ("tail3", (0.0, 0.05, -0.06)),
            ("tail3_end", (0.0, 0.04, -0.05)))
    for leg, (upper, middle, lower, paw, bones, _, torso) in LEGS.items():
        side = 0.07 if leg.endswith("l") else -0.07
        r.chain(torso, (upper, (side, -0.02, -0.02) if torso == "pelvis" else (side, -0.04, 0.04)),
                (middle, (0.0, -bones[0], 0.0)), (lower, (0.0, -bones[1], 0.0)), (paw, (0.0, -bones[2], 0.0)),
                (f"{paw}_end", (0.0, 0.0, 0.04)))
    return r.skeleton()


def posture(**changes: float) -> dict[str, float]:
    """The standing dog with ``changes``; ``both_KEY`` sets hind and front, ``hind_KEY`` both
    hind legs, ``front_KEY`` both front legs (KEY: y, z, w3, lift, r1, r2, r3)."""
    p = {"x": 0.0, "y": 0.36, "z": 0.0, "pitch": 0.0, "roll": 0.0, "spine": 0.0, "look": 0.0,
         "tail": -0.5, "wag": 0.0}
    for leg in LEGS:
        rest = HIND_Z if leg[0] == "h" else FRONT_Z
        p.update({f"{leg}_y": 0.0, f"{leg}_z": rest, f"{leg}_w3": 0.0, f"{leg}_lift": 0.0,
                  f"{leg}_r1": 0.0, f"{leg}_r2": 0.0, f"{leg}_r3": 0.0})
    for key, value in changes.items():
        group, _, rest = key.partition("_")
        legs = {"hind": ("hl", "hr"), "front": ("fl", "fr"), "all": tuple(LEGS)}.get(group)
        for leg in legs or ():
            p[f"{leg}_{rest}"] = value
        if legs is None:
            p[key] = value
    return p


def blend(a: dict[str, float], b: dict[str, float], u: float) -> dict[str, float]:
    return {k: (1.0 - u) * a[k] + u * b[k] for k in a}


STAND = posture()
SIT = posture(y=0.16, z=0.03, pitch=-0.55, spine=-0.05, hind_z=0.02, hind_w3=-1.3, front_z=0.36)
LIE = posture(y=0.13, z=0.02, pitch=0.0, hind_z=0.10, hind_w3=-1.45, front_z=0.58, front_w3=-1.45, tail=-0.1)


def beg(height: float) -> dict[str, float]:
    """Sitting up with the front paws raised; ``height`` 0 (a low beg) … 1 (a high one)."""
    return posture(y=0.18, z=0.05, tail=0.4, pitch=-0.95 - 0.45 * height, spine=-0.1 * height, hind_z=0.02, hind_w3=-1.35,
                   front_lift=1.0, front_r1=-1.0 - 0.9 * height, front_r2=-0.1 - 0.6 * height,
                   front_r3=0.5 - 0.3 * height, front_z=0.36)


TUCKED = {**LIE, **{k: v for k, v in posture(all_lift=1.0, front_r1=-1.3, front_r2=-1.5, hind_r1=-1.5, hind_r2=1.5,
                                             all_r3=-1.5).items()
                    if k.endswith(("lift", "r1", "r2", "r3"))}, "y": 0.16}
"""Lying with every leg flat along the body (front legs forward, hind legs folded, paws
forward, as they already lie, so folding them never swings a paw through the ground): the
posture it rolls over in."""


def frame(sk: Skeleton, p: dict[str, float], t: float) -> Frame:
    """Joint rotations for posture ``p`` at clip time ``t`` (the tail wags on ``t``)."""
    f = Frame(root=np.array([p["x"], p["y"], p["z"]]))
    f.turn("pelvis", Z, p["roll"])
    f.pitch("pelvis", p["pitch"])
    f.pitch("spine", p["spine"])
    torso_pitch = {"pelvis": p["pitch"], "chest": p["pitch"] + p["spine"]}
    f.pitch("neck", -0.6 * torso_pitch["chest"] - 0.2)
    f.pitch("head", -0.4 * torso_pitch["chest"] + 0.35)
    f.turn("head", Y, p["look"])
    f.pitch("tail1", p["tail"])
    f.turn("tail1", Y, p["wag"] * math.sin(2.0 * math.pi * 2.0 * t))
    f.pitch("tail2", 0.3)
    world = sk.forward_kinematics(f.rotations(sk), f.root)
    for leg, (upper, middle, lower, paw, bones, bend, torso) in LEGS.items():
        hip = world[sk.index(upper)][[1, 2]]
        w3 = p[f"{leg}_w3"]
        ankle = np.array([p[f"{leg}_y"] + bones[2] * math.cos(w3), p[f"{leg}_z"] + bones[2] * math.sin(w3)])
        w1, w2 = planar_leg(hip, ankle, bones[0], bones[1], bend)
        lift = p[f"{leg}_lift"]
        w1, w2, w3 = ((1.0 - lift) * w + lift * p[f"{leg}_r{k}"] for k, w in ((1, w1), (2, w2), (3, w3)))
        f.pitch(upper, w1 - torso_pitch[torso])
        f.pitch(middle, w2 - w1)
        f.pitch(lower, w3 - w2)
        f.pitch(paw, -w3)
    return grounded(sk, f, {LEGS[leg][3]: p[f"{leg}_lift"] for leg in LEGS})


CLEARANCE = 0.01
"""Metres a lifted paw keeps above the ground (twice what counts as touching it)."""


def grounded(sk: Skeleton, f: Frame, lifts: dict[str, float]) -> Frame:
    """``f`` raised until no joint is below the ground and no paw lifted out of contact lower
    than its share of :data:`CLEARANCE` (all of it from a quarter lifted on, so a paw leaves
    the ground as its leg begins to fold, not dragged along it): a dog rolling over rests on
    its back, its tucked legs in the air (they otherwise swung 9 cm through the floor, and a
    paw touching it swept 8 cm a frame)."""
    heights = sk.forward_kinematics(f.rotations(sk), f.root)[:, 1]
    short = [CLEARANCE * min(1.0, 4.0 * lift) - heights[sk.index(paw)] for paw, lift in lifts.items() if lift > 0.0]
    raise_by = max(-float(heights.min()), *short, 0.0)
    if raise_by > 1e-6:
        f.root = f.root + np.array([0.0, raise_by, 0.0])
    return f


STEP = 0.02
"""Metres a planted paw must move between two key postures to be stepped there, not slid."""
STEP_LIFT = 0.04
"""Metres such a paw rises at the middle of its step."""


def stepped(a: dict[str, float], b: dict[str, float], u: float) -> dict[str, float]:
    """:func:`blend` of two key postures, with every paw planted in both that moves at least
    :data:`STEP` between them lifted on an arc: a dog lying down walks its front paws forward
    rather than dragging them (1.5 cm a frame, before: over the 1 cm a planted paw may move)."""
    p = blend(a, b, u)
    for leg in LEGS:
        if a[f"{leg}_lift"] == b[f"{leg}_lift"] == 0.0 and abs(b[f"{leg}_z"] - a[f"{leg}_z"]) >= STEP:
            p[f"{leg}_y"] += STEP_LIFT * math.sin(math.pi * u)
    return p


def _clip(sk: Skeleton, name: str, keys: list[tuple[float, dict[str, float]]]) -> Clip:
    """Frames at :data:`FPS` through key postures at the given seconds (eased between, paws
    that change place :func:`stepped`)."""
    times = [t for t, _ in keys]
    frames = []
    for i in range(int(round(times[-1] * FPS)) + 1):
        t = i / FPS
        k = min(int(np.searchsorted(times, t, side="right")) - 1, len(keys) - 2)
        (t0, a), (t1, b) = keys[k], keys[k + 1]
        frames.append(frame(sk, stepped(a, b, float(smooth((t - t0) / (t1 - t0)))), t))
    return Clip(name, frames)


def _held(clip: Clip, label: str, start: float, end: float, *, rest: bool = True) -> None:
    """Label the frames held between ``start`` and ``end`` seconds (and mark them low energy)."""
    frames = range(int(round(start * FPS)), int(round(end * FPS)) + 1)
    clip.label(label, frames)
    if rest:
        clip.label(LOW_ENERGY, frames)


def walk(sk: Skeleton, cycles: int = 2) -> Clip:
    """``cycles`` gait cycles with the root travelling at :data:`WALK_SPEED` along +z.

    Each paw is planted for :data:`DUTY` of the cycle at a fixed world place, then swings a
    stride ahead on an arc; the planted span is centred under its hip or shoulder.
    Labels ``walk 1`` … ``walk 4`` mark the quarters of every cycle: a cycle's last frame is
    its first again, so "get to the next quarter" is the one way on (``getTo "walk 1";
    getTo "walk 2"; …; cycle``), where a single label would be reached by standing still.
    """
    stride = WALK_SPEED * WALK_PERIOD
    frames = []
    count = int(round(cycles * WALK_PERIOD * FPS))
    for i in range(count + 1):
        t = i / FPS
        p = dict(STAND, z=WALK_SPEED * t, wag=0.3)
        for leg, offset in PHASES.items():
            cycle = t / WALK_PERIOD + offset
            n, u = math.floor(cycle + 1e-9), (cycle + 1e-9) % 1.0
            swing = 0.0 if u < DUTY else float(smooth((u - DUTY) / (1.0 - DUTY)))
            rest = HIND_Z if leg[0] == "h" else FRONT_Z
            start = rest - stride * offset + stride * DUTY / 2.0
            p[f"{leg}_z"] = start + stride * (n + swing)
            # The paw leaves and meets the ground steeply (√ of a sine arc): off the ground at once, not skimming it.
            p[f"{leg}_y"] = SWING_LIFT * math.sqrt(math.sin(math.pi * swing)) if u >= DUTY else 0.0
        frames.append(frame(sk, p, t))
    clip = Clip("walk", frames, root_motion=True)
    clip.label("walk", range(len(frames)))
    quarter = int(round(WALK_PERIOD * FPS / 4))
    for k in range(4):  # the cycle's four phases: a motor program steps through them to walk on
        clip.label(f"walk {k + 1}", range(k * quarter, len(frames), 4 * quarter))
    return clip


def clips(sk: Skeleton) -> list[Clip]:
    """stand, walk, sit, lie down, sit to lie down, beg, roll over (in that order in the file)."""
    stand = _clip(sk, "stand", [(0.0, STAND), (1.0, dict(STAND, look=0.4, wag=0.4)), (2.0, STAND)])
    _held(stand, "stand", 0.0, 2.0)
    sit = _clip(sk, "sit", [(0.0, STAND), (0.8, SIT), (2.0, SIT), (2.8, STAND)])
    _held(sit, "sit", 0.8, 2.0)
    lie = _clip(sk, "lie down", [(0.0, STAND), (0.8, LIE), (2.2, LIE), (3.2, STAND)])
    _held(lie, "lie down", 0.8, 2.2)
    down = _clip(sk, "sit to lie down", [(0.0, SIT), (0.8, LIE), (1.2, LIE)])  # front paws walk forward
    _held(down, "sit", 0.0, 0.0)
    _held(down, "lie down", 0.8, 1.2)
    rise = [(0.8 + 2.0 * k / 8, beg(k / 8)) for k in range(9)]  # in eight short steps: heights evenly spread
    begging = _clip(sk, "beg", [(0.0, SIT), (0.6, beg(0.0)), *rise, (3.0, beg(1.0)), (3.6, SIT)])
    _held(begging, "beg", 0.6, 3.0, rest=False)
    _held(begging, "sit", 0.0, 0.0)
    _held(begging, "sit", 3.6, 3.6)
    roll = _clip(sk, "roll over", [(0.0, LIE), (0.4, TUCKED), (0.6, TUCKED), (1.6, dict(TUCKED, roll=math.pi)),
                                   (2.6, dict(TUCKED, roll=2.0 * math.pi)), (2.8, dict(TUCKED, roll=2.0 * math.pi)),
                                   (3.2, dict(LIE, roll=2.0 * math.pi))])
    _held(roll, "roll over", 1.5, 1.7, rest=False)
    _held(roll, "lie down", 0.0, 0.0)
    _held(roll, "lie down", 3.2, 3.2)
    return [stand, walk(sk), sit, lie, down, begging, roll]


ABOUT = """The shipped dog (creatures/body/generate/dog.py): stand, walk (root motion), sit, lie down,
beg (front paws rising from low to high: every frame labelled beg), roll over; "low energy" marks rest."""
