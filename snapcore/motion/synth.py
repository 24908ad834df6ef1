"""Procedural humanoid motions: the embedded demo data and analytic test cases.

A BVH-compatible humanoid (CMU-like joint names, metres, Y up, facing +Z) performs a
few motions whose key events happen at documented times (the module constants below),
so other modules can be tested against a known answer: when the feet leave the ground,
when the kick lands, when one person's hands touch the other's chest.

The rig (skeleton, rotations, keyframe curves, IK) is in :mod:`snapcore.motion.synth_rig`;
this module holds the motions, the scenes and their ground truth (:func:`events`).

How a motion is made
--------------------
Each motion is a handful of keyframed curves (PCHIP: smooth, no overshoot, flat where
two keys are equal) sampled at every frame at once. Feet and, where they must meet a
target, hands are placed by analytic two-bone inverse kinematics, so a planted foot
stays exactly where it was put (no sliding) and the pusher's palms stay on the other
person's chest. Rotations are built as matrices and written as ZXY Euler angles in
degrees (the BVH channel order ``Zrotation Xrotation Yrotation``), rounded to
:data:`DECIMALS` places, which round-trips exactly through :func:`snapcore.motion.bvh.format_bvh`.

The seed varies amplitudes (stride length, crouch depth, arm swing, kick height...)
but never the event times, so the ``*_S`` constants hold for every seed.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from snapcore.errors import SceneError
from snapcore.motion.bvh import BVHDocument, write_bvh
from snapcore.motion.scene import Scene, character_from_bvh, yaw_matrix
from snapcore.motion.synth_rig import (
    ANKLE_HEIGHT,
    BALL,
    FOREARM,
    HIP_OFFSET,
    OFFSET,
    ROOT_HEIGHT_M,
    SHANK,
    SIDES,
    THIGH,
    UPPER_ARM,
    Pose,
    above_ground,
    arm_fk,
    cyclic,
    foot_on_ground,
    jitter,
    minjerk,
    nlerp,
    pchip,
    plant_feet,
    rotate,
    rx,
    solve_arm,
    solve_leg,
    to_document,
    unit,
    zxy,
)
from snapcore.schema import validate

__all__ = [
    "MOTIONS",
    "SCENES",
    "DEMO_SCENES",
    "DEFAULT_SECONDS",
    "humanoid_document",
    "synth_scene",
    "write_demo",
    "walk_heel_strikes",
    "events",
    "WALK_STRIDE_S",
    "WALK_FIRST_LEFT_STRIKE_S",
    "WALK_STANCE_FRACTION",
    "JUMP_TAKEOFF_S",
    "JUMP_LANDING_S",
    "KICK_IMPACT_S",
    "PUNCH_IMPACT_S",
    "PUSH_CONTACT_S",
    "PUSH_CONTACT_END_S",
    "PUSH_DISTANCE_M",
    "CHEST_DEPTH_M",
    "JACKS_PERIOD_S",
    "STATURE_M",
    "ROOT_HEIGHT_M",
]

# --------------------------------------------------------------------------- constants

#: Motions :func:`humanoid_document` makes.
MOTIONS = ("walk", "jump", "kick", "punch", "jumping_jacks", "idle")
#: Scenes :func:`synth_scene` makes ("push" has two characters).
SCENES = MOTIONS + ("push",)
#: Scenes :func:`write_demo` writes.
DEMO_SCENES = ("walk", "jump", "kick", "punch", "push")
#: Default clip length per scene, seconds (first to last frame).
DEFAULT_SECONDS = {
    "walk": 3.0,
    "jump": 3.0,
    "kick": 2.5,
    "punch": 2.5,
    "jumping_jacks": 3.0,
    "idle": 3.0,
    "push": 3.0,
}

#: Walk: seconds per stride (two steps); left heel strikes at
#: ``WALK_FIRST_LEFT_STRIKE_S + k * WALK_STRIDE_S``, right ones half a stride later.
WALK_STRIDE_S = 1.1
WALK_FIRST_LEFT_STRIKE_S = 0.2
#: Fraction of a stride each foot is on the ground (heel strike to toe-off).
WALK_STANCE_FRACTION = 0.6
#: Jump: the feet leave the ground at take-off and touch it again at landing (seconds).
JUMP_TAKEOFF_S = 1.3
JUMP_LANDING_S = 1.8
#: Kick (right leg, front kick): the leg is fully extended, foot highest and farthest
#: forward, at this time (seconds).
KICK_IMPACT_S = 1.05
#: Punch (right cross): the arm is fully extended at this time (seconds).
PUNCH_IMPACT_S = 1.2
#: Push: the pusher's palms touch the pushed person's chest from PUSH_CONTACT_S to
#: PUSH_CONTACT_END_S (seconds); the two start PUSH_DISTANCE_M apart (root to root),
#: facing each other, the pusher at the origin facing +Z (before ``facing_deg``).
PUSH_CONTACT_S = 1.3
PUSH_CONTACT_END_S = 1.6
PUSH_DISTANCE_M = 1.0
#: Front of the chest: this far ahead of the Spine1 joint along the person's facing (m).
CHEST_DEPTH_M = 0.12
#: Jumping jacks: seconds per jack (out and back in); the first starts at 0.3 s.
JACKS_PERIOD_S = 0.9
JACKS_START_S = 0.3

#: Standing height of the skeleton (floor to top of head), metres.
STATURE_M = 1.75

# --------------------------------------------------------------------------- motions


def _walk(t, rng):
    n = t.size
    pose = Pose(n)
    T = WALK_STRIDE_S
    step = 0.55 * jitter(rng, 0.04)
    stride = 2 * step
    v = stride / T
    swing_arm = 16.0 * jitter(rng, 0.2)
    phase_l = (t - WALK_FIRST_LEFT_STRIKE_S) / T  # heel strike of the left foot at integers
    phi = np.mod(phase_l, 1.0)
    # Root: constant speed forward, bobbing (highest at mid-stance), swaying over the
    # stance foot, pelvis turning with the swinging leg.
    z_root = v * t
    y_root = ROOT_HEIGHT_M - 0.043 + 0.022 * np.cos(4 * np.pi * (phi - 0.27))
    x_root = 0.02 * np.cos(2 * np.pi * (phi - 0.3))
    pose.root = np.stack([x_root, y_root, z_root], axis=1)
    yaw = -5.0 * np.cos(2 * np.pi * phi)
    roll = 2.5 * np.sin(2 * np.pi * (phi - 0.1))
    pose.local["Hips"] = zxy(roll, 0.0, yaw)
    pose.local["Spine"] = zxy(-roll * 0.6, 3.0, -0.5 * yaw)
    pose.local["Spine1"] = zxy(0.0, 2.0, -0.5 * yaw)
    pose.local["Neck"] = zxy(0.0, -3.0, 0.0)
    pose.local["Head"] = zxy(-0.4 * roll, -1.0, 0.0)
    # Feet: stance = heel roll (toes up) → flat → heel off (rolling on the ball); the
    # ball of each foot is planted where the root will be at that foot's mid-stance.
    pitch_keys = ([0.0, 0.08, 0.42, 0.6, 0.75, 0.92], [-12.0, 0.0, 0.0, 35.0, 5.0, -12.0])
    stance = WALK_STANCE_FRACTION
    for side, shift in (("Left", 0.0), ("Right", 0.5)):
        ph = phase_l - shift
        k = np.floor(ph)
        f = ph - k
        sx = SIDES[side] * 0.095

        def ball_at(cycle, shift=shift, sx=sx):  # ball of the foot planted in this cycle
            t_mid = (cycle + shift + 0.3) * T + WALK_FIRST_LEFT_STRIKE_S
            z = v * t_mid + BALL[2]
            return np.stack(
                [np.full_like(z, sx), np.full_like(z, ANKLE_HEIGHT + BALL[1]), z], axis=1
            )

        pitch = cyclic(f, *pitch_keys)
        ankle_st, rot_st = foot_on_ground(ball_at(k), pitch)
        # Swing: minimum-jerk from the toe-off ankle to the next heel-strike ankle.
        a0, _ = foot_on_ground(ball_at(k), np.full(n, pitch_keys[1][3]))
        a1, _ = foot_on_ground(ball_at(k + 1), np.full(n, pitch_keys[1][0]))
        u = (f - stance) / (1 - stance)
        s = minjerk(u)[:, None]
        uc = np.clip(u, 0, 1)
        lift = 0.07 * uc * (1 - uc) ** 2 * 27 / 4  # peaks early in the swing, at u = 1/3
        ankle_sw = a0 + (a1 - a0) * s + np.stack([0 * lift, lift, 0 * lift], axis=1)
        in_swing = (f >= stance)[:, None]
        ankle = np.where(in_swing, ankle_sw, ankle_st)
        rot = np.where(in_swing[..., None], rx(pitch), rot_st)
        solve_leg(pose, side, ankle, rot, toe_deg=np.maximum(pitch, 0.0))
        # Arms swing opposite to the leg of the same side.
        arm_phase = 2 * np.pi * (f - 0.5)
        flex = 4.0 + swing_arm * np.cos(arm_phase)
        arm_fk(pose, side, 8.0, flex, 18.0 + 0.6 * np.maximum(flex, 0))
    return pose


def _jump(t, rng):
    n = t.size
    pose = Pose(n)
    g = 9.81
    flight = JUMP_LANDING_S - JUMP_TAKEOFF_S
    v0 = g * flight / 2
    depth = 0.22 * jitter(rng, 0.15)
    # Take-off pose: legs almost straight, heels up 35 degrees (rolling on the balls).
    toe_pitch = 35.0
    ball_l = np.array([0.11, ANKLE_HEIGHT + BALL[1], BALL[2]])
    ball_r = ball_l * [-1, 1, 1]
    a_to, _ = foot_on_ground(ball_l[None], np.array([toe_pitch]))
    y_to = a_to[0, 1] + 0.985 * (THIGH + SHANK) - HIP_OFFSET[1]
    t_to, t_ld = JUMP_TAKEOFF_S, JUMP_LANDING_S
    tb = t_to - 0.3  # bottom of the crouch
    # Root height: hermite segments with the ballistic velocity at take-off/landing.
    y = np.full(n, ROOT_HEIGHT_M - 0.01)
    seg = (t >= 0.45) & (t < tb)
    y[seg] = pchip(t[seg], [0.45, tb], [ROOT_HEIGHT_M - 0.01, ROOT_HEIGHT_M - depth])
    y0, y1, m1, dt = ROOT_HEIGHT_M - depth, y_to, v0, t_to - tb
    seg = (t >= tb) & (t < t_to)
    u = (t[seg] - tb) / dt
    y[seg] = (2 * u**3 - 3 * u**2 + 1) * y0 + (-2 * u**3 + 3 * u**2) * y1 + (u**3 - u**2) * m1 * dt
    seg = (t >= t_to) & (t < t_ld)
    tau = t[seg] - t_to
    y[seg] = y_to + v0 * tau - 0.5 * g * tau**2
    tl, land_depth = t_ld + 0.3, 0.2 * jitter(rng, 0.15)
    seg = (t >= t_ld) & (t < tl)
    u = (t[seg] - t_ld) / (tl - t_ld)
    y0, y1, m0, dt = y_to, ROOT_HEIGHT_M - land_depth, -v0, tl - t_ld
    y[seg] = (
        (2 * u**3 - 3 * u**2 + 1) * y0
        + (-2 * u**3 + 3 * u**2) * y1
        + (u**3 - 2 * u**2 + u) * m0 * dt
    )
    seg = t >= tl
    y[seg] = pchip(t[seg], [tl, tl + 0.55], [ROOT_HEIGHT_M - land_depth, ROOT_HEIGHT_M - 0.01])
    pose.root = np.stack([np.zeros(n), y, np.zeros(n)], axis=1)
    lean = pchip(
        t, [0.45, tb, t_to, t_to + 0.25, t_ld, tl, tl + 0.55], [0.0, 25.0, 0.0, 0.0, 5.0, 22.0, 0.0]
    )
    pose.local["Hips"] = zxy(0.0, lean, 0.0)
    pose.local["Spine"] = zxy(0.0, 0.3 * lean, 0.0)
    pose.local["Neck"] = zxy(0.0, -0.8 * lean, 0.0)
    # Feet on the ground except in flight; heels rise before take-off, toes touch first.
    pitch = pchip(
        t,
        [0.0, tb + 0.05, t_to, t_to + 0.2, t_ld - 0.15, t_ld, t_ld + 0.12],
        [0.0, 0.0, toe_pitch, 20.0, 25.0, toe_pitch, 0.0],
    )
    air = (t > t_to) & (t < t_ld)
    u = np.clip((t - t_to) / flight, 0, 1)
    tuck = 0.16 * np.sin(np.pi * u) * air
    for side, ball in (("Left", ball_l), ("Right", ball_r)):
        ballf = np.broadcast_to(ball, (n, 3))
        ankle, rot = foot_on_ground(ballf, np.where(air, toe_pitch, pitch))
        ankle = ankle + np.stack([0 * y, (y - y_to + tuck) * air, 0 * y], axis=1)
        rot = np.where(air[:, None, None], rx(pitch), rot)
        solve_leg(pose, side, ankle, rot, toe_deg=np.where(air, 0.0, np.maximum(pitch, 0)))
    # Arms: swing back in the crouch, up through take-off, down after landing.
    amp = jitter(rng, 0.1)
    flex = pchip(
        t,
        [0.0, 0.45, tb, t_to, t_to + 0.2, t_ld, tl, tl + 0.55],
        [5.0, 5.0, -45.0 * amp, 150.0 * amp, 160.0 * amp, 60.0, 20.0, 5.0],
    )
    elbow = pchip(t, [0.0, tb, t_to, t_ld, tl + 0.55], [12.0, 10.0, 20.0, 30.0, 12.0])
    for side in SIDES:
        arm_fk(pose, side, 10.0, flex, elbow)
    return pose


def _kick(t, rng):
    n = t.size
    pose = Pose(n)
    ti = KICK_IMPACT_S
    height = jitter(rng, 0.08)
    ball_l = np.array([0.1, ANKLE_HEIGHT + BALL[1], BALL[2] + 0.02])
    ball_r = np.array([-0.1, ANKLE_HEIGHT + BALL[1], BALL[2] - 0.05])
    # Weight onto the left foot, pelvis tilting back as the right leg kicks.
    shift = pchip(t, [0.0, 0.3, 0.65, ti + 0.45, ti + 0.8, ti + 1.1], [0, 0, 1, 1, 0.3, 0])
    x = 0.0 + 0.07 * shift
    y = ROOT_HEIGHT_M - 0.03 - 0.03 * shift
    z = pchip(t, [0.0, 0.65, ti, ti + 0.5, ti + 1.1], [0.0, -0.02, 0.02, 0.0, 0.0])
    pose.root = np.stack([x, y, z], axis=1)
    tilt = pchip(
        t, [0.0, 0.6, ti - 0.1, ti + 0.15, ti + 0.6, ti + 1.0], [2.0, 0.0, -10.0, -12.0, -2.0, 2.0]
    )
    pose.local["Hips"] = zxy(-4.0 * shift, tilt, 8.0 * shift)
    pose.local["Spine"] = zxy(2.0 * shift, 6.0 - 0.6 * tilt, -4.0 * shift)
    pose.local["Spine1"] = zxy(0.0, 3.0, -3.0 * shift)
    pose.local["Neck"] = zxy(0.0, -4.0 - 0.3 * tilt, 0.0)
    # Left leg planted. The right ankle goes from its planted spot to where the kick's
    # keyframed leg angles put it and back, never letting the foot touch the floor
    # in between; IK then gives knee and hip.
    plant_feet(pose, ball_l, ball_r)
    keys_t = [0.0, 0.55, 0.8, ti - 0.16, ti, ti + 0.18, ti + 0.45, ti + 0.75]
    hip = pchip(t, keys_t, [0, 5, 60, 70, 82 * height, 70, 35, 5])
    knee = pchip(t, keys_t, [5, 10, 110, 115, 2, 95, 70, 10])
    point = pchip(t, keys_t, [0, 5, 30, 35, 45, 30, 15, 0])  # ankle plantarflexion
    w = pchip(t, [0.5, 0.7, ti + 0.5, ti + 0.85], [0.0, 1.0, 1.0, 0.0])
    r_root = pose.local["Hips"]
    hip_pos = pose.root + rotate(r_root, OFFSET["RightUpLeg"])
    thigh = r_root @ rx(-hip)
    kick_ankle = (
        hip_pos
        + rotate(thigh, np.array([0.0, -THIGH, 0.0]))
        + rotate(thigh @ rx(knee), np.array([0.0, -SHANK, 0.0]))
    )
    planted, flat = foot_on_ground(np.broadcast_to(ball_r, (n, 3)), np.zeros(n))
    ankle = planted + (kick_ankle - planted) * w[:, None]
    rot = nlerp(flat, thigh @ rx(knee) @ rx(point), w)
    ankle = above_ground(ankle, rot)
    solve_leg(pose, "Right", ankle, rot)
    # Guard up; the right arm swings back as the leg swings forward.
    for side in SIDES:
        back = shift if side == "Right" else 0 * shift
        arm_fk(pose, side, 22.0 + 10 * back, 22.0 - 55.0 * back, 125.0 - 60 * back)
    return pose


def _punch(t, rng):
    n = t.size
    pose = Pose(n)
    ti = PUNCH_IMPACT_S
    reach = 1.0 - 0.01 * rng.uniform()
    # Boxing stance: left foot forward, knees soft.
    ball_l = np.array([0.12, ANKLE_HEIGHT + BALL[1], BALL[2] + 0.16])
    ball_r = np.array([-0.14, ANKLE_HEIGHT + BALL[1], BALL[2] - 0.16])
    k = pchip(t, [0.0, ti - 0.25, ti, ti + 0.3, ti + 0.7], [0.0, -0.2, 1.0, 0.3, 0.0])
    x = 0.0 - 0.02 * k
    y = np.full(n, ROOT_HEIGHT_M - 0.05)
    z = 0.0 + 0.06 * k
    pose.root = np.stack([x, y, z], axis=1)
    pose.local["Hips"] = zxy(0.0, 4.0, -10.0 + 18.0 * k)
    pose.local["Spine"] = zxy(0.0, 5.0 + 3 * k, 10.0 * k)
    pose.local["Spine1"] = zxy(0.0, 4.0, 2.0 + 8.0 * k)
    pose.local["Neck"] = zxy(0.0, -6.0, 8.0 - 26.0 * k)
    heel = np.clip(k, 0, None) * 25.0  # the rear heel lifts as the hips turn
    plant_feet(pose, ball_l, ball_r, pitch_r=heel)
    # Guard: fists in front of the chin (relative to the chest, so they turn with it).
    r_chest, p_chest = pose.world("Spine1")
    pole_out = {s: rotate(r_chest, np.array([SIDES[s] * 0.6, -1.0, -0.6])) for s in SIDES}
    guard = {s: p_chest + rotate(r_chest, np.array([SIDES[s] * 0.13, 0.22, 0.24])) for s in SIDES}
    # The fist drives straight at chin height, ahead of the body's midline, to 98-99 % of
    # the arm's length from the (moving) shoulder: extended, never locked.
    _, shoulder = pose.world("RightArm")
    aim = unit(np.array([-0.03, 1.38, 1.2]) - shoulder)
    target = shoulder + aim * 0.99 * reach * (UPPER_ARM + FOREARM)
    w = pchip(t, [0.0, ti - 0.2, ti, ti + 0.06, ti + 0.4], [0.0, 0.0, 1.0, 1.0, 0.0])[:, None]
    wrist_r = guard["Right"] * (1 - w) + target * w
    solve_arm(pose, "Left", guard["Left"], pole_out["Left"])
    solve_arm(pose, "Right", wrist_r, pole_out["Right"])
    return pose


def _jumping_jacks(t, rng):
    n = t.size
    pose = Pose(n)
    T, t0 = JACKS_PERIOD_S, JACKS_START_S
    wide = 0.32 * jitter(rng, 0.1)
    up = 170.0 * jitter(rng, 0.03)
    c = np.clip((t - t0) / T, 0, None)
    active = t >= t0
    f = np.mod(c, 1.0)
    # Out-jump in [0, 0.15), feet apart [0.15, 0.5), in-jump [0.5, 0.65), together after.
    spread = np.where(active, cyclic(f, [0.0, 0.15, 0.5, 0.65], [0.0, 1.0, 1.0, 0.0]), 0.0)
    hop = np.where(
        active,
        np.sin(np.pi * np.clip(f / 0.15, 0, 1)) * (f < 0.15)
        + np.sin(np.pi * np.clip((f - 0.5) / 0.15, 0, 1)) * ((f >= 0.5) & (f < 0.65)),
        0.0,
    )
    squat = np.where(active, 0.5 + 0.5 * np.cos(2 * np.pi * (f - 0.3) / 0.35), 0.0)
    squat = np.where((f > 0.15) & (f < 0.5) | (f > 0.65), squat, 0.0) * active
    # The arms take longer than the legs: up over 0.4 of the period, down over 0.45.
    arms = np.where(active, cyclic(f, [0.0, 0.4, 0.5, 0.95], [0.0, 1.0, 1.0, 0.0]), 0.0)
    hop_h = 0.07
    y = ROOT_HEIGHT_M - 0.015 - 0.065 * spread + hop_h * hop - 0.04 * squat
    pose.root = np.stack([np.zeros(n), y, np.zeros(n)], axis=1)
    for side in SIDES:
        sx = SIDES[side] * (0.1 + wide * spread)
        ball = np.stack(
            [sx, np.full(n, ANKLE_HEIGHT + BALL[1] + hop_h * hop), np.full(n, BALL[2])], axis=1
        )
        ankle, rot = foot_on_ground(ball, np.zeros(n))
        solve_leg(pose, side, ankle, rot, pole=np.broadcast_to([0.0, 0.0, 1.0], (n, 3)))
        arm_fk(pose, side, 6.0 + (up - 6.0) * arms, 0.0, 0.0)
    return pose


def _idle(t, rng):
    n = t.size
    pose = Pose(n)
    breath = np.sin(2 * np.pi * t / (3.2 * jitter(rng, 0.1)))
    sway = np.sin(2 * np.pi * t / (4.5 * jitter(rng, 0.1)) + rng.uniform(0, 2 * np.pi))
    pose.root = np.stack(
        [0.025 * sway, ROOT_HEIGHT_M - 0.006 + 0.002 * breath, 0.005 * breath], axis=1
    )
    pose.local["Hips"] = zxy(1.5 * sway, 1.0, 2.0 * sway)
    pose.local["Spine"] = zxy(-1.5 * sway, 1.0 + 1.0 * breath, -1.0 * sway)
    pose.local["Spine1"] = zxy(0.0, 1.0 * breath, 0.0)
    pose.local["Head"] = zxy(0.0, -2.0 + 2.0 * breath, 6.0 * np.sin(2 * np.pi * t / 5.0))
    plant_feet(
        pose, [0.1, ANKLE_HEIGHT + BALL[1], BALL[2]], [-0.1, ANKLE_HEIGHT + BALL[1], BALL[2] - 0.03]
    )
    for side in SIDES:
        arm_fk(pose, side, 8.0 + 1.5 * breath, 4.0 + 2.0 * sway * SIDES[side], 14.0)
    return pose


_MAKERS = {
    "walk": _walk,
    "jump": _jump,
    "kick": _kick,
    "punch": _punch,
    "jumping_jacks": _jumping_jacks,
    "idle": _idle,
}


def _push(t, rng):
    """Two poses in the pusher's frame: A at the origin facing +Z, B ahead facing -Z."""
    n = t.size
    tc, te = PUSH_CONTACT_S, PUSH_CONTACT_END_S
    # --- B, the pushed person: stands, is shoved back, steps back with the left foot.
    b = Pose(n)
    shove = 0.18 * jitter(rng, 0.1)
    back = pchip(
        t, [0.0, tc, te, te + 0.5, te + 0.9], [0.0, 0.0, shove, shove + 0.14, shove + 0.16]
    )
    lean = pchip(
        t, [0.0, tc, tc + 0.2, te + 0.1, te + 0.6, te + 1.1], [1.0, 1.0, -7.0, -10.0, -4.0, 1.0]
    )
    b.root = np.stack([np.zeros(n), ROOT_HEIGHT_M - 0.015 - 0.02 * (back > 0.05), -back], axis=1)
    b.root[:, 1] = (
        ROOT_HEIGHT_M
        - 0.015
        - pchip(t, [0.0, tc, te, te + 0.5, te + 1.0], [0.0, 0.0, 0.04, 0.03, 0.0])
    )
    b.local["Hips"] = zxy(0.0, lean * 0.5, 0.0)
    b.local["Spine"] = zxy(0.0, lean * 0.5, 0.0)
    b.local["Neck"] = zxy(0.0, -0.6 * lean + 8 * (lean < -5), 0.0)
    yb = ANKLE_HEIGHT + BALL[1]
    step_l = pchip(t, [0.0, te - 0.2, te + 0.2], [0.0, 0.0, 1.0])
    step_r = pchip(t, [0.0, te + 0.2, te + 0.6], [0.0, 0.0, 1.0])
    lift_l = 0.06 * np.sin(np.pi * step_l)
    lift_r = 0.05 * np.sin(np.pi * step_r)
    ball_l = np.stack([np.full(n, 0.1), yb + lift_l, BALL[2] - 0.45 * step_l], axis=1)
    ball_r = np.stack([np.full(n, -0.1), yb + lift_r, BALL[2] - (shove + 0.12) * step_r], axis=1)
    plant_feet(b, ball_l, ball_r)
    arms = pchip(t, [0.0, tc, tc + 0.2, te + 0.5, te + 1.1], [0.0, 0.0, 1.0, 0.8, 0.0])
    for side in SIDES:
        arm_fk(b, side, 8.0 + 35.0 * arms, 5.0 + 30.0 * arms, 12.0 + 50.0 * arms)
    # --- A, the pusher: steps in with the right foot, the left one follows; leans
    # into the shove, then settles.
    a = Pose(n)
    adv = pchip(t, [0.0, 0.5, 1.05, tc, te, te + 0.7], [0.0, 0.0, 0.33, 0.42, 0.57, 0.50])
    lunge = pchip(t, [0.0, 0.5, 1.05, te, te + 0.6, te + 1.2], [0.0, 0.0, 0.05, 0.045, 0.02, 0.015])
    a.root = np.stack([np.zeros(n), ROOT_HEIGHT_M - 0.015 - lunge, adv], axis=1)
    lean_a = pchip(t, [0.0, 0.5, tc, te, te + 0.6, te + 1.2], [1.0, 1.0, 10.0, 14.0, 6.0, 3.0])
    a.local["Hips"] = zxy(0.0, 0.4 * lean_a, 0.0)
    a.local["Spine"] = zxy(0.0, 0.6 * lean_a, 0.0)
    a.local["Neck"] = zxy(0.0, -0.8 * lean_a, 0.0)
    step_r = pchip(t, [0.0, 0.5, 1.05], [0.0, 0.0, 1.0])
    step_l = pchip(t, [0.0, 1.02, 1.32], [0.0, 0.0, 1.0])
    ball_ar = np.stack(
        [np.full(n, -0.1), yb + 0.07 * np.sin(np.pi * step_r), BALL[2] + 0.65 * step_r], axis=1
    )
    ball_al = np.stack(
        [np.full(n, 0.1), yb + 0.05 * np.sin(np.pi * step_l), BALL[2] + 0.30 * step_l], axis=1
    )
    heel = pchip(t, [0.0, tc + 0.05, te, te + 0.4, te + 1.0], [0.0, 0.0, 15.0, 15.0, 0.0])
    plant_feet(a, ball_al, ball_ar, pitch_l=heel)
    # A's hands: hanging → ready in front of the chest → on B's chest → back down.
    b_rot, b_chest = b.world("Spine1")
    # B's pose is in B's own frame; in A's frame B stands PUSH_DISTANCE_M ahead, turned.
    turn = yaw_matrix(180.0)
    b_rot = turn @ b_rot
    b_chest = b_chest @ turn.T + np.array([0.0, 0.0, PUSH_DISTANCE_M])
    a_rot, a_chest = a.world("Spine1")
    w_ready = pchip(t, [0.0, 0.6, 1.05, te + 0.15, te + 0.9], [0.0, 0.0, 1.0, 1.0, 0.0])
    w_touch = pchip(t, [0.0, 0.95, tc, te, te + 0.25], [0.0, 0.0, 1.0, 1.0, 0.0])
    hand_rot = {}
    for side in SIDES:
        s = SIDES[side]
        # B faces -Z in A's frame, so B's left is A's right: A's left hand on B's right.
        on_b = b_chest + rotate(b_rot, np.array([-s * 0.11, -0.05, CHEST_DEPTH_M]))
        ready = a_chest + rotate(a_rot, np.array([s * 0.14, -0.04, 0.30]))
        hang = a_chest + rotate(a_rot, np.array([s * 0.27, -0.35, 0.06]))
        wrist = hang + (ready - hang) * w_ready[:, None]
        wrist = wrist + (on_b - wrist) * w_touch[:, None]
        # Elbows back while the arms hang, out and down while they push.
        pole = rotate(
            a_rot,
            np.array([s * 0.2, -0.3, -1.0]) + w_ready[:, None] * np.array([s * 0.5, -0.3, 0.6]),
        )
        solve_arm(a, side, wrist, pole)
        # Palm flat on B's chest: fingers up, palm (local -Y) facing B, thumb (local
        # +Z) toward the midline.
        r_fore, _ = a.world(f"{side}ForeArm")
        up = np.broadcast_to([0.0, 1.0, 0.0], (n, 3))
        into = -b_rot[:, :, 2]
        into = unit(into - into[:, 1:2] * up)
        x_axis = s * up
        flat = np.stack([x_axis, -into, np.cross(x_axis, -into)], axis=-1)
        hand_rot[side] = nlerp(r_fore, flat, np.clip(w_touch, 0, 1) * 0.9)
        a.local[f"{side}Hand"] = np.swapaxes(r_fore, -1, -2) @ hand_rot[side]
    return a, b


# --------------------------------------------------------------------------- output


def _times(name: str, seconds: float | None, fps: float) -> np.ndarray:
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise SceneError(f"fps must be a positive number, got {fps!r}")
    secs = DEFAULT_SECONDS[name] if seconds is None else float(seconds)
    if not (math.isfinite(secs) and secs > 0):
        raise SceneError(f"seconds must be a positive number, got {seconds!r}")
    n = int(round(secs * fps)) + 1
    return np.arange(n) / fps


def humanoid_document(
    motion: str,
    *,
    seconds: float | None = None,
    fps: float = 30.0,
    seed: int = 0,
    facing_deg: float = 0.0,
) -> BVHDocument:
    """A procedural humanoid performing ``motion``, as a BVH document in metres.

    Parameters
    ----------
    motion : {"walk", "jump", "kick", "punch", "jumping_jacks", "idle"}
    seconds : float, optional
        Clip length (first to last frame); default :data:`DEFAULT_SECONDS`. Event times
        (the ``*_S`` constants) do not depend on it; a short clip may end before them.
    fps : float
        Frames per second.
    seed : int
        Seeds small amplitude variations (never the event times).
    facing_deg : float
        Yaw about +Y (counter-clockwise seen from above); 0 faces +Z.

    Returns
    -------
    BVHDocument
        Y up, metres, root ``Hips`` with 6 channels, other joints ``Zrotation
        Xrotation Yrotation``; ``round(seconds * fps) + 1`` frames.
    """
    if motion not in _MAKERS:
        raise SceneError(f"unknown motion {motion!r}; expected one of {', '.join(MOTIONS)}")
    t = _times(motion, seconds, fps)
    pose = _MAKERS[motion](t, np.random.default_rng(seed))
    return to_document(pose, fps, facing_deg=facing_deg, path=f"{motion}.bvh")


def _push_documents(*, seconds=None, fps=30.0, seed=0, facing_deg=0.0):
    t = _times("push", seconds, fps)
    a, b = _push(t, np.random.default_rng(seed))
    yaw = yaw_matrix(facing_deg)
    doc_a = to_document(a, fps, facing_deg=facing_deg, path="push_pusher.bvh")
    doc_b = to_document(
        b,
        fps,
        facing_deg=facing_deg + 180.0,
        offset=yaw @ np.array([0.0, 0.0, PUSH_DISTANCE_M]),
        path="push_pushed.bvh",
    )
    return doc_a, doc_b


def synth_scene(name: str, *, fps: float = 30.0, seed: int = 0, facing_deg: float = 0.0) -> Scene:
    """A ready-made :class:`~snapcore.motion.scene.Scene` of a synthetic motion.

    Parameters
    ----------
    name : {"walk", "jump", "kick", "punch", "jumping_jacks", "idle", "push"}
        "push" has two characters, ``pusher`` (at the origin, facing +Z) and ``pushed``
        (:data:`PUSH_DISTANCE_M` ahead, facing the pusher).
    fps, seed, facing_deg
        As in :func:`humanoid_document`; ``facing_deg`` turns the whole scene about +Y
        through the origin.

    Returns
    -------
    Scene
        Ground at 0.0, ``scene.name == name``, ``frame_offset`` 0, default length.
    """
    if name == "push":
        docs = _push_documents(fps=fps, seed=seed, facing_deg=facing_deg)
        names: tuple[str, ...] = ("pusher", "pushed")
    elif name in _MAKERS:
        docs = (humanoid_document(name, fps=fps, seed=seed, facing_deg=facing_deg),)
        names = ("actor",)
    else:
        raise SceneError(f"unknown scene {name!r}; expected one of {', '.join(SCENES)}")
    chars = []
    for doc, cname in zip(docs, names):
        c = character_from_bvh(doc, scale=1.0, name=cname, fps=fps)
        c.meta["unit"] = "m"
        chars.append(c)
    return Scene(
        characters=chars,
        fps=float(fps),
        ground=0.0,
        name=name,
        meta={"source": "synth", "unit": "m", "seed": seed},
    )


_DESCRIPTIONS = {
    "walk": "Synthetic walk: three strides forward along +Z at about 1 m/s.",
    "jump": f"Synthetic vertical jump: take-off at {JUMP_TAKEOFF_S} s, landing at {JUMP_LANDING_S} s.",
    "kick": f"Synthetic right front kick, full extension at {KICK_IMPACT_S} s.",
    "punch": f"Synthetic right cross from a boxing guard, full extension at {PUNCH_IMPACT_S} s.",
    "push": (
        f"Synthetic two-person push: the pusher's palms on the other's chest from "
        f"{PUSH_CONTACT_S} s to {PUSH_CONTACT_END_S} s; the pushed person steps back."
    ),
    "jumping_jacks": "Synthetic jumping jacks.",
    "idle": "Synthetic idle standing.",
}


def _toml_manifest(name: str, fps: float, chars: list[tuple[str, str]]) -> str:
    lines = [
        f'name = "{name}"',
        f'description = "{_DESCRIPTIONS[name]}"',
        f"fps = {float(fps)!r}",
        "ground = 0.0",
        "drop_tpose = false",
        "",
    ]
    for file, cname in chars:
        lines += ["[[characters]]", f'file = "{file}"', f'name = "{cname}"', ""]
    return "\n".join(lines)


def write_demo(folder: str | os.PathLike, *, fps: float = 30.0, seed: int = 0) -> list[Path]:
    """Write the demo scenes (:data:`DEMO_SCENES`) into ``folder``.

    Each scene is its BVH file(s) and a TOML scene manifest (schema ``scene``) naming
    them by relative path; the output is deterministic.

    Returns
    -------
    list of Path
        The manifests, in :data:`DEMO_SCENES` order.
    """
    import tomllib

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    manifests = []
    for name in DEMO_SCENES:
        if name == "push":
            docs = _push_documents(fps=fps, seed=seed)
            chars = [("push_pusher.bvh", "pusher"), ("push_pushed.bvh", "pushed")]
        else:
            docs = (humanoid_document(name, fps=fps, seed=seed),)
            chars = [(f"{name}.bvh", "actor")]
        for doc, (file, _) in zip(docs, chars):
            write_bvh(doc, out / file)
        text = _toml_manifest(name, fps, chars)
        validate(tomllib.loads(text), "scene", source=str(out / f"{name}.toml"))
        path = out / f"{name}.toml"
        path.write_text(text, encoding="utf-8")
        manifests.append(path)
    return manifests


def events(name: str, *, seconds: float | None = None) -> dict:
    """The documented event times (seconds) of a synthetic scene: its ground truth.

    Parameters
    ----------
    name : str
        One of :data:`SCENES`.
    seconds : float, optional
        Clip length (default :data:`DEFAULT_SECONDS`); events after it are dropped.

    Returns
    -------
    dict
        walk: ``left_heel_strikes``, ``right_heel_strikes``, ``left_toe_offs``,
        ``right_toe_offs`` (arrays); jump: ``takeoff``, ``landing``; kick and punch:
        ``impact``; push: ``contact`` (start, end); jumping_jacks: ``jack_starts``
        (array, each jack lasting :data:`JACKS_PERIOD_S`); idle: nothing. The same for
        every seed and frame rate.
    """
    if name not in SCENES:
        raise SceneError(f"unknown scene {name!r}; expected one of {', '.join(SCENES)}")
    secs = DEFAULT_SECONDS[name] if seconds is None else float(seconds)
    if name == "walk":
        strikes = walk_heel_strikes(secs)
        out = {f"{side}_heel_strikes": strikes[side] for side in ("left", "right")}
        for side, first in (
            ("left", WALK_FIRST_LEFT_STRIKE_S),
            ("right", WALK_FIRST_LEFT_STRIKE_S - WALK_STRIDE_S / 2),
        ):
            k = np.arange(0, int(secs / WALK_STRIDE_S) + 2)
            offs = first + (k + WALK_STANCE_FRACTION - 1) * WALK_STRIDE_S
            out[f"{side}_toe_offs"] = np.round(offs[(offs >= 0) & (offs <= secs)], 9)
        return out
    table: dict[str, dict[str, float | tuple[float, float]]] = {
        "jump": {"takeoff": JUMP_TAKEOFF_S, "landing": JUMP_LANDING_S},
        "kick": {"impact": KICK_IMPACT_S},
        "punch": {"impact": PUNCH_IMPACT_S},
        "push": {"contact": (PUSH_CONTACT_S, PUSH_CONTACT_END_S)},
        "idle": {},
    }
    if name == "jumping_jacks":
        starts = JACKS_START_S + JACKS_PERIOD_S * np.arange(int(secs / JACKS_PERIOD_S) + 1)
        return {"jack_starts": np.round(starts[starts + JACKS_PERIOD_S <= secs + 1e-9], 9)}
    return {k: v for k, v in table[name].items() if np.min(v) <= secs}


def walk_heel_strikes(seconds: float | None = None) -> dict[str, np.ndarray]:
    """Heel-strike times (seconds) of each foot within a walk clip of ``seconds``."""
    secs = DEFAULT_SECONDS["walk"] if seconds is None else float(seconds)
    k = np.arange(-1, int(secs / WALK_STRIDE_S) + 2)
    left = WALK_FIRST_LEFT_STRIKE_S + k * WALK_STRIDE_S
    right = left + WALK_STRIDE_S / 2
    left, right = np.round(left, 9), np.round(right, 9)
    return {
        "left": left[(left >= 0) & (left <= secs)],
        "right": right[(right >= 0) & (right <= secs)],
    }
