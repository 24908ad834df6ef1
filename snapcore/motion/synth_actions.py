"""Procedural bows and two-handed cuts with free timing, and their key moments by rule.

The selectors' held-out checks need actions whose size, speed and place in the clip
vary: a shallow bow that fills most of its clip, a deep one early in a long rest, a
sword cut whose follow-through lasts longer than the cut. This module builds them on
the procedural rig of :mod:`snapcore.motion.synth_rig` (a person standing at rest with
breathing and sway, so that no frame is exactly still) and marks their key moments by
the written annotation rules of ``../shared/keymoments/DEFINITIONS.md`` applied to the
joint positions (:func:`bow_interval`, rule 1; :func:`slash_intervals`, rule 9), never
by any selector.

Times are seconds, angles degrees, lengths metres; every random choice is seeded.
"""

from __future__ import annotations

import numpy as np

from snapcore.errors import SceneError
from snapcore.motion.scene import Scene, character_from_bvh
from snapcore.motion.synth_rig import (
    ANKLE_HEIGHT,
    BALL,
    ROOT_HEIGHT_M,
    SIDES,
    Pose,
    arm_fk,
    minjerk,
    plant_feet,
    rotate,
    solve_arm,
    to_document,
    zxy,
)

__all__ = [
    "BOW_HANDS",
    "standing",
    "pose_scene",
    "bow_scene",
    "slash_scene",
    "bow_interval",
    "slash_intervals",
]

#: Where the hands are during a bow: along the thighs, turning with the trunk
#: ("sides"), hanging straight down ("hang"), or clasped in front of the belly
#: ("clasped", as in the shared not-confident style).
BOW_HANDS = ("sides", "hang", "clasped")


def _times(seconds: float, fps: float) -> np.ndarray:
    if not (np.isfinite(fps) and fps > 0 and np.isfinite(seconds) and seconds > 0):
        raise SceneError(f"seconds and fps must be positive numbers, got {seconds!r}, {fps!r}")
    return np.arange(int(round(seconds * fps)) + 1) / fps


def _ramp(t: np.ndarray, start: float, duration: float) -> np.ndarray:
    """Minimum-jerk 0 -> 1 from ``start`` over ``duration`` seconds (0 before, 1 after)."""
    return minjerk((t - start) / max(duration, 1e-9))


def standing(t: np.ndarray, rng: np.random.Generator) -> Pose:
    """A person standing at rest: breathing, swaying, feet planted, arms hanging.

    Parameters
    ----------
    t : ndarray of shape (F,)
        Seconds.
    rng : numpy.random.Generator
        Varies the breathing and sway periods and the sway's phase.
    """
    n = t.size
    pose = Pose(n)
    breath = np.sin(2 * np.pi * t / (3.0 + rng.uniform(0, 0.6)))
    sway = np.sin(2 * np.pi * t / (4.0 + rng.uniform(0, 1.0)) + rng.uniform(0, 2 * np.pi))
    pose.root = np.stack(
        [0.02 * sway, ROOT_HEIGHT_M - 0.006 + 0.002 * breath, 0.004 * breath], axis=1
    )
    pose.local["Hips"] = zxy(1.5 * sway, 1.0, 2.0 * sway)
    pose.local["Spine"] = zxy(-1.5 * sway, 1.0 + breath, -sway)
    plant_feet(
        pose, [0.1, ANKLE_HEIGHT + BALL[1], BALL[2]], [-0.1, ANKLE_HEIGHT + BALL[1], BALL[2] - 0.03]
    )
    for side in SIDES:
        arm_fk(pose, side, 8.0 + 1.5 * breath, 4.0 + 2.0 * sway * SIDES[side], 14.0)
    return pose


def pose_scene(pose: Pose, fps: float, name: str) -> Scene:
    """A one-character :class:`~snapcore.motion.scene.Scene` (ground 0) of ``pose``."""
    doc = to_document(pose, fps, path=f"{name}.bvh")
    c = character_from_bvh(doc, scale=1.0, name="actor", fps=fps)
    c.meta["unit"] = "m"
    return Scene(characters=[c], fps=float(fps), ground=0.0, name=name)


def bow_scene(
    *,
    seconds: float = 3.0,
    start_s: float = 0.3,
    down_s: float = 0.7,
    hold_s: float = 1.0,
    up_s: float = 0.7,
    depth_deg: float = 25.0,
    hands: str = "sides",
    sway_deg: float = 0.0,
    knee_deg: float = 0.0,
    fps: float = 30.0,
    seed: int = 0,
) -> Scene:
    """A bow: the trunk flexes forward from the hips, is held, and comes back up.

    Parameters
    ----------
    seconds : float
        Clip length.
    start_s, down_s, hold_s, up_s : float
        The bow starts at ``start_s``, reaches its depth after ``down_s``, holds it
        ``hold_s`` and is upright again ``up_s`` later (minimum-jerk ramps).
    depth_deg : float
        Flexion at the deepest: 60 % at the hips (the pelvis moving back to keep the
        weight over the feet), 25 % in the spine, 15 % in the neck. At 25 degrees the
        head drops about 6 cm (the shallow bows of the shared gestures: 5-12 cm).
    hands : {"sides", "hang", "clasped"}
        See :data:`BOW_HANDS`.
    sway_deg : float
        Amplitude of a small arm sway (about 1.3 Hz) through the whole clip.
    knee_deg : float
        Knee flexion at the deepest (a bow with soft knees).
    fps : float
    seed : int
        Seeds the rest pose's breathing and sway and the sway's phase.
    """
    if hands not in BOW_HANDS:
        raise SceneError(f"hands must be one of {', '.join(BOW_HANDS)}, got {hands!r}")
    t = _times(seconds, fps)
    rng = np.random.default_rng(seed)
    pose = standing(t, rng)
    w = _ramp(t, start_s, down_s) - _ramp(t, start_s + down_s + hold_s, up_s)
    flex = depth_deg * w
    hip = 0.6 * flex
    pose.local["Hips"] = pose.local["Hips"] @ zxy(0.0, hip, 0.0)
    pose.local["Spine"] = pose.local["Spine"] @ zxy(0.0, 0.15 * flex, 0.0)
    pose.local["Spine1"] = zxy(0.0, 0.1 * flex, 0.0)
    pose.local["Neck"] = zxy(0.0, 0.15 * flex, 0.0)
    # the pelvis moves back as the trunk goes forward (the weight stays over the feet),
    # and down with the knees
    back = 0.25 * np.sin(np.deg2rad(flex))
    drop = 0.45 * (1 - np.cos(np.deg2rad(knee_deg * w)))
    pose.root = pose.root + np.stack([np.zeros_like(t), -drop, -back], axis=1)
    plant_feet(
        pose, [0.1, ANKLE_HEIGHT + BALL[1], BALL[2]], [-0.1, ANKLE_HEIGHT + BALL[1], BALL[2] - 0.03]
    )
    sway = sway_deg * np.sin(2 * np.pi * 1.3 * t + rng.uniform(0, 2 * np.pi))
    trunk = hip + 0.25 * flex
    for side in SIDES:
        if hands == "sides":
            arm_fk(pose, side, 8.0, 4.0 + sway, 14.0)
        elif hands == "hang":
            arm_fk(pose, side, 8.0, 4.0 - trunk + sway, 14.0)
    if hands == "clasped":
        r_chest, p_chest = pose.world("Spine1")
        for side, s in SIDES.items():
            grip = p_chest + rotate(r_chest, np.array([s * 0.04, -0.08, 0.22]))
            grip[:, 1] += 0.03 * np.sin(np.deg2rad(sway))
            pole = rotate(r_chest, np.array([s * 1.0, -0.5, -0.5]))
            solve_arm(pose, side, grip, pole)
    return pose_scene(pose, fps, "bow")


def slash_scene(
    *,
    cuts_s=(1.0,),
    seconds: float = 3.0,
    raise_s: float = 0.5,
    top_s: float = 0.15,
    cut_s: float = 0.25,
    follow_s: float = 1.0,
    back_s: float = 0.6,
    lean_deg: float = 15.0,
    lunge_m: float = 0.05,
    step_m: float = 0.0,
    top_deg: float = 175.0,
    end_deg: float = 45.0,
    fps: float = 30.0,
    seed: int = 0,
) -> Scene:
    """Two-handed sword cuts from a guard: raise overhead, cut down, follow through.

    Parameters
    ----------
    cuts_s : sequence of float
        When each cut starts (the hands leave the top); the raise before it starts
        ``raise_s + top_s`` earlier. Cuts must not overlap.
    seconds : float
        Clip length.
    raise_s, top_s, cut_s : float
        The raise from the guard to overhead, the hold at the top, the cut itself
        (minimum jerk: the hands are fastest, and farthest in front of the shoulders,
        half-way, ``cut_s / 2`` after the cut starts).
    follow_s : float
        The follow-through: the hands settle a little lower in front, the trunk leans
        ``lean_deg`` forward and the knees give ``lunge_m``, held until the return to
        the guard over ``back_s``. The lean and the lunge keep deepening for 0.4 s
        after the cut (the body's momentum carries on).
    step_m : float
        With each cut the front (right) foot steps this far forward, landing as the
        cut ends, and the rear foot follows it early in the follow-through (0: the
        feet stay planted).
    top_deg, end_deg : float
        The hands' angle (see Notes) at the top of the raise and at the end of the cut
        (they settle 10 degrees lower in the follow-through).
    fps : float
    seed : int
        Seeds the rest pose's breathing and sway.

    Notes
    -----
    Both hands hold the grip on an arc about the mid-point of the shoulders, at
    angle ``a`` from straight down (guard 40, top ``top_deg``, end of the cut
    ``end_deg``, then 10 degrees lower) and distance ``r`` (0.42, 0.45, 0.56, 0.52 m). Feet stay planted, the
    right one forward.
    """
    t = _times(seconds, fps)
    rng = np.random.default_rng(seed)
    pose = standing(t, rng)
    guard, top, end = 40.0, float(top_deg), float(end_deg)
    settle = end - 10.0
    r_guard, r_top, r_end, r_settle = 0.42, 0.45, 0.56, 0.52
    ang = np.full_like(t, guard)
    rad = np.full_like(t, r_guard)
    lean = np.zeros_like(t)
    front = np.zeros_like(t)
    rear = np.zeros_like(t)
    lift_f = np.zeros_like(t)
    lift_r = np.zeros_like(t)
    for c in sorted(float(x) for x in cuts_s):
        f = _ramp(t, c - 0.1, cut_s + 0.1)
        r = _ramp(t, c + cut_s + 0.1, 0.35)
        front += step_m * f
        rear += step_m * r
        lift_f += 0.05 * np.sin(np.pi * f) * (step_m > 0)
        lift_r += 0.04 * np.sin(np.pi * r) * (step_m > 0)
        up = _ramp(t, c - top_s - raise_s, raise_s)
        cut = _ramp(t, c, cut_s)
        st = _ramp(t, c + cut_s, 0.4)
        back = _ramp(t, c + cut_s + follow_s, back_s)
        ang += (
            (top - guard) * up + (end - top) * cut + (settle - end) * st + (guard - settle) * back
        )
        rad += (
            (r_top - r_guard) * up
            + (r_end - r_top) * cut
            + (r_settle - r_end) * st
            + (r_guard - r_settle) * back
        )
        # the body's momentum carries the lean and the lunge on into the follow-through
        lean += (_ramp(t, c, cut_s + 0.4) - back) * lean_deg - 4.0 * (up - cut)
    pose.local["Hips"] = pose.local["Hips"] @ zxy(0.0, 0.5 * lean, 0.0)
    pose.local["Spine"] = pose.local["Spine"] @ zxy(0.0, 0.5 * lean, 0.0)
    pose.local["Neck"] = zxy(0.0, -0.4 * lean, 0.0)
    give = lunge_m * np.clip(lean / max(lean_deg, 1e-9), 0, 1)
    ahead = 0.5 * (front + rear)
    pose.root = pose.root + np.stack([np.zeros_like(t), -give, 0.5 * give + ahead], axis=1)
    yb = ANKLE_HEIGHT + BALL[1]
    ones = np.ones_like(t)
    plant_feet(
        pose,
        np.stack([0.12 * ones, yb + lift_r, BALL[2] - 0.18 + rear], axis=1),
        np.stack([-0.12 * ones, yb + lift_f, BALL[2] + 0.15 + front], axis=1),
    )
    _, sh_l = pose.world("LeftArm")
    _, sh_r = pose.world("RightArm")
    mid = 0.5 * (sh_l + sh_r)
    a = np.deg2rad(ang)
    grip = mid + rad[:, None] * np.stack([np.zeros_like(a), -np.cos(a), np.sin(a)], axis=1)
    r_chest, _ = pose.world("Spine1")
    for side, s in SIDES.items():
        pole = rotate(r_chest, np.array([s * 1.0, -0.6, -0.3]))
        solve_arm(pose, side, grip + np.array([s * 0.035, 0.0, 0.0]), pole)
    return pose_scene(pose, fps, "slash")


# --------------------------------------------------------------------------- rules


def _run_around(mask: np.ndarray, k: int) -> tuple[int, int]:
    """The maximal run of True frames of ``mask`` that contains frame ``k``."""
    a = k
    while a > 0 and mask[a - 1]:
        a -= 1
    b = k
    while b < mask.size - 1 and mask[b + 1]:
        b += 1
    return a, b


def bow_interval(scene: Scene) -> tuple[int, int]:
    """Rule 1 (bow) of the key-moment definitions: frames ``(a, b)``, inclusive.

    The head (joint ``Head``) within 30 % of its lowest drop: drop = standing head
    height - head height, standing = the larger of the medians of the first and last
    5 frames; the frames whose drop is at least 0.7 of the largest, contiguous around
    the lowest frame.
    """
    c = scene.characters[0]
    y = c.positions[:, c.skeleton.index("Head"), 1]
    standing_h = max(float(np.median(y[:5])), float(np.median(y[-5:])))
    drop = standing_h - y
    k = int(np.argmax(drop))
    return _run_around(drop >= 0.7 * drop[k], k)


def slash_intervals(scene: Scene) -> list[tuple[int, int]]:
    """Rule 9 (two-handed sword cut): one interval ``(a, b)`` per cut, inclusive.

    Raises are the runs where the mean height of the two hands (joints ``LeftHand``,
    ``RightHand``) rises at least 80 % of the clip's largest rise over rest (the median
    of the first 3 frames); each cut runs from the first frame of its raise at 95 % of
    that raise's peak rise to the hands' speed peak from the raise's peak to 0.6 s after the raise.
    """
    c = scene.characters[0]
    hands = [c.skeleton.index("LeftHand"), c.skeleton.index("RightHand")]
    x = c.positions[:, hands]
    rise = x[:, :, 1].mean(axis=1)
    rise = rise - np.median(rise[:3])
    speed = np.linalg.norm(np.gradient(x, axis=0), axis=2).mean(axis=1) * scene.fps
    big = rise >= 0.8 * rise.max()
    d = np.diff(np.r_[0, big.astype(np.int8), 0])
    out: list[tuple[int, int]] = []
    for s, e in zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()):
        peak = float(rise[s:e].max())
        a = s + int(np.flatnonzero(rise[s:e] >= 0.95 * peak)[0])
        k = s + int(np.argmax(rise[s:e]))
        stop = min(rise.size, e + int(round(0.6 * scene.fps)) + 1)
        b = k + int(np.argmax(speed[k:stop]))
        out.append((a, b))
    return out
