"""The procedural humanoid's rig: skeleton, rotations, keyframe curves and IK.

The building blocks of :mod:`snapcore.motion.synth`: a BVH-compatible humanoid (CMU-like joint
names, metres, Y up, facing +Z, 1.75 m tall), rotation matrices in the BVH channel
order, PCHIP keyframe curves, a :class:`Pose` (local rotations and root translation for
every frame), analytic two-bone inverse kinematics for legs and arms, and the
conversion of a pose to a :class:`~snapcore.motion.bvh.BVHDocument`. Everything works on all
frames at once.

Conventions: the character faces +Z and its left is +X; in the rest pose (T-pose) a
left arm lies along +X and a leg along -Y. Angles in degrees, lengths in metres.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from snapcore.motion.bvh import BVHDocument
from snapcore.motion.scene import yaw_matrix

#: Decimal places of every written channel value (1e-6 m, 1e-6 degree).
DECIMALS = 6
#: Fraction of an arm's length beyond which arm IK saturates smoothly (see :func:`two_bone`).
IK_SOFT_REACH = 0.97


# --------------------------------------------------------------------------- skeleton

#: Bone lengths (m). Thigh and shank follow Drillis & Contini (0.245 H, 0.246 H), so the
#: foundation's stature estimate (thigh + shank) / 0.491 gives 1.75 m.
THIGH = 0.43
SHANK = 0.43
UPPER_ARM = 0.29
FOREARM = 0.25
HIP_OFFSET = np.array([0.09, -0.06, 0.0])
ANKLE_HEIGHT = 0.08
#: Root (pelvis) height when standing straight, metres.
ROOT_HEIGHT_M = ANKLE_HEIGHT + SHANK + THIGH + 0.06
# Foot points in the ankle (Foot joint) frame: ball of the foot (the ToeBase joint),
# toe tip (its end site), heel (not a joint; the pivot of the heel strike).
BALL = np.array([0.0, -0.07, 0.13])
TOE_TIP = np.array([0.0, -0.08, 0.19])
HEEL = np.array([0.0, -0.075, -0.05])

# (name, parent, offset); parents precede children in depth-first order, which is the
# order format_bvh writes and parse_bvh reads back. End sites are "<parent>_End".
JOINTS = [
    ("Hips", None, (0.0, 0.0, 0.0)),
    ("Spine", "Hips", (0.0, 0.10, 0.0)),
    ("Spine1", "Spine", (0.0, 0.14, 0.0)),
    ("Neck", "Spine1", (0.0, 0.21, 0.0)),
    ("Head", "Neck", (0.0, 0.10, 0.0)),
    ("Head_End", "Head", (0.0, 0.19, 0.0)),
    ("LeftShoulder", "Spine1", (0.02, 0.17, 0.0)),
    ("LeftArm", "LeftShoulder", (0.17, 0.0, 0.0)),
    ("LeftForeArm", "LeftArm", (UPPER_ARM, 0.0, 0.0)),
    ("LeftHand", "LeftForeArm", (FOREARM, 0.0, 0.0)),
    ("LeftHand_End", "LeftHand", (0.17, 0.0, 0.0)),
    ("RightShoulder", "Spine1", (-0.02, 0.17, 0.0)),
    ("RightArm", "RightShoulder", (-0.17, 0.0, 0.0)),
    ("RightForeArm", "RightArm", (-UPPER_ARM, 0.0, 0.0)),
    ("RightHand", "RightForeArm", (-FOREARM, 0.0, 0.0)),
    ("RightHand_End", "RightHand", (-0.17, 0.0, 0.0)),
    ("LeftUpLeg", "Hips", tuple(HIP_OFFSET)),
    ("LeftLeg", "LeftUpLeg", (0.0, -THIGH, 0.0)),
    ("LeftFoot", "LeftLeg", (0.0, -SHANK, 0.0)),
    ("LeftToeBase", "LeftFoot", tuple(BALL)),
    ("LeftToeBase_End", "LeftToeBase", tuple(TOE_TIP - BALL)),
    ("RightUpLeg", "Hips", tuple(HIP_OFFSET * [-1, 1, 1])),
    ("RightLeg", "RightUpLeg", (0.0, -THIGH, 0.0)),
    ("RightFoot", "RightLeg", (0.0, -SHANK, 0.0)),
    ("RightToeBase", "RightFoot", tuple(BALL)),
    ("RightToeBase_End", "RightToeBase", tuple(TOE_TIP - BALL)),
]
NAMES = tuple(j[0] for j in JOINTS)
INDEX = {n: i for i, n in enumerate(NAMES)}
PARENT = {n: p for n, p, _ in JOINTS}
OFFSET = {n: np.array(o, dtype=float) for n, _, o in JOINTS}
END_SITE = tuple(n.endswith("_End") for n in NAMES)
ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
JOINT_CHANNELS = ("Zrotation", "Xrotation", "Yrotation")
SIDES = {"Left": 1.0, "Right": -1.0}  # sign of the side's X in the character frame

# --------------------------------------------------------------------------- helpers


def rx(deg):
    """Rotations about X by ``deg`` degrees, (..., 3, 3) for ``deg`` of shape (...)."""
    a = np.deg2rad(np.asarray(deg, dtype=float))
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2
    )


def ry(deg):
    """Rotations about Y by ``deg`` degrees, (..., 3, 3)."""
    a = np.deg2rad(np.asarray(deg, dtype=float))
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2
    )


def rz(deg):
    """Rotations about Z by ``deg`` degrees, (..., 3, 3)."""
    a = np.deg2rad(np.asarray(deg, dtype=float))
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2
    )


def zxy(z=0.0, x=0.0, y=0.0):
    """BVH ``Zrotation Xrotation Yrotation`` angles (degrees) to matrices."""
    z, x, y = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (z, x, y)))
    return rz(z) @ rx(x) @ ry(y)


def rotate(r, v):
    """Rotate vectors ``v`` (..., 3) by matrices ``r`` (..., 3, 3)."""
    return np.einsum("...ij,...j->...i", r, v)


def unit(v):
    """Vectors (..., 3) scaled to unit length (zero vectors stay ~zero)."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-12)


def pchip(t, times, values):
    """PCHIP through keyframes ``(times, values)``, held constant outside them.

    ``values`` may be (K,) or (K, D); returns (F,) or (F, D). Same curve as
    ``scipy.interpolate.PchipInterpolator`` (Fritsch & Carlson 1980, with SciPy's
    end-point rule), written out because building SciPy's object costs ~1 ms and a
    motion uses dozens of curves.
    """
    x = np.asarray(times, dtype=float)
    y = np.asarray(values, dtype=float)
    flat = y.ndim == 1
    y = y.reshape(len(x), -1)
    h = np.diff(x)[:, None]  # (K-1, 1)
    delta = np.diff(y, axis=0) / h  # (K-1, D)
    d = np.zeros_like(y)
    if len(x) == 2:
        d[:] = delta
    else:
        w1 = 2 * h[1:] + h[:-1]
        w2 = h[1:] + 2 * h[:-1]
        same = (np.sign(delta[:-1]) * np.sign(delta[1:])) > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            hm = (w1 + w2) / (w1 / delta[:-1] + w2 / delta[1:])
        d[1:-1] = np.where(same, hm, 0.0)
        for end, (h0, h1, m0, m1) in (
            (0, (h[0], h[1], delta[0], delta[1])),
            (-1, (h[-1], h[-2], delta[-1], delta[-2])),
        ):
            de = ((2 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
            de = np.where(np.sign(de) != np.sign(m0), 0.0, de)
            de = np.where((np.sign(m0) != np.sign(m1)) & (np.abs(de) > 3 * np.abs(m0)), 3 * m0, de)
            d[end] = de
    tc = np.clip(np.asarray(t, dtype=float), x[0], x[-1])
    i = np.clip(np.searchsorted(x, tc, side="right") - 1, 0, len(x) - 2)
    hi = h[i]
    u = ((tc - x[i]) / hi[:, 0])[:, None]
    out = (
        (2 * u**3 - 3 * u**2 + 1) * y[i]
        + (u**3 - 2 * u**2 + u) * hi * d[i]
        + (-2 * u**3 + 3 * u**2) * y[i + 1]
        + (u**3 - u**2) * hi * d[i + 1]
    )
    return out[:, 0] if flat else out


def cyclic(phase, keys, values):
    """PCHIP through keys over one period of ``phase`` (in [0, 1)), periodically."""
    keys = np.asarray(keys, dtype=float)
    values = np.asarray(values, dtype=float)
    k = np.concatenate([keys - 1, keys, keys + 1])
    v = np.concatenate([values, values, values])
    return pchip(np.mod(phase, 1.0), k, v)


def minjerk(u):
    """Minimum-jerk ramp 0→1 on u in [0, 1] (zero velocity and acceleration at both ends)."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10 - 15 * u + 6 * u**2)


def jitter(rng, spread):
    """A factor in [1 - spread, 1 + spread]."""
    return 1.0 + spread * rng.uniform(-1.0, 1.0)


def nlerp(ra, rb, w):
    """Blend rotation matrices (F, 3, 3) with weights w (F,) (normalised quaternion lerp)."""
    qa = Rotation.from_matrix(ra).as_quat()
    qb = Rotation.from_matrix(rb).as_quat()
    sign = np.where(np.sum(qa * qb, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    w = np.asarray(w, dtype=float)[..., None]
    q = (1 - w) * qa + w * sign * qb
    return Rotation.from_quat(q / np.linalg.norm(q, axis=-1, keepdims=True)).as_matrix()


# --------------------------------------------------------------------------- pose


class Pose:
    """Local joint rotations (F, 3, 3) and root translation (F, 3) of one character."""

    def __init__(self, n: int):
        self.n = n
        eye = np.broadcast_to(np.eye(3), (n, 3, 3))
        self.local = {name: eye.copy() for name, end in zip(NAMES, END_SITE) if not end}
        self.root = np.zeros((n, 3))

    def world(self, name: str):
        """World rotation (F, 3, 3) and position (F, 3) of joint ``name``."""
        chain: list[str] = []
        j: str | None = name
        while j is not None:
            chain.append(j)
            j = PARENT[j]
        chain.reverse()
        rot = self.local[chain[0]]
        pos = self.root
        for j in chain[1:]:
            pos = pos + rotate(rot, OFFSET[j])
            rot = rot @ self.local[j] if j in self.local else rot
        return rot, pos


def two_bone(start, target, l1, l2, pole, *, soft=False):
    """Analytic two-bone IK.

    Returns unit directions of the first and second bone (F, 3), the bend angle
    between them in degrees (F,) and the unit bend direction (F, 3): the direction,
    perpendicular to the first bone, toward which the second bone turns (away from
    ``pole``, the side the middle joint points to).
    """
    d_vec = target - start
    d = np.linalg.norm(d_vec, axis=-1)
    full = l1 + l2
    if soft:
        # Saturate smoothly near full extension (arms): a target out of reach straightens
        # the limb gradually instead of snapping it straight. Legs stay exact, so a
        # planted foot is exactly where it was put.
        knee = IK_SOFT_REACH * full
        sat = knee + (full - knee) * np.tanh((d - knee) / (full - knee))
        d = np.where(d > knee, sat, d)
    d = np.clip(d, abs(l1 - l2) + 1e-6, full * (1 - 1e-9))
    n = unit(d_vec)
    p = pole - np.sum(pole * n, axis=-1, keepdims=True) * n
    p = unit(p)
    a = (l1**2 - l2**2 + d**2) / (2 * d)
    h = np.sqrt(np.maximum(l1**2 - a**2, 0.0))
    u1 = (a[:, None] * n + h[:, None] * p) / l1
    u1 = unit(u1)
    inner = np.arccos(np.clip((l1**2 + l2**2 - d**2) / (2 * l1 * l2), -1.0, 1.0))
    bend = np.degrees(np.pi - inner)
    b = -(p - np.sum(p * u1, axis=-1, keepdims=True) * u1)
    return u1, unit(b), bend


def solve_leg(pose: Pose, side: str, ankle, foot_rot, toe_deg=0.0, pole=None):
    """Set the hip, knee, ankle and toe rotations so the ankle reaches ``ankle`` (F, 3)
    with world foot orientation ``foot_rot`` (F, 3, 3); knees point along ``pole``."""
    r_root = np.broadcast_to(pose.local["Hips"], (pose.n, 3, 3))
    hip = pose.root + rotate(r_root, OFFSET[f"{side}UpLeg"])
    if pole is None:
        pole = unit(rotate(r_root, np.array([0.0, 0.0, 1.0])) + foot_rot[:, :, 2])
    u1, b, bend = two_bone(hip, ankle, THIGH, SHANK, pole)
    # Thigh frame: rest bone axis -Y maps to u1, the knee bends (Rx > 0) toward -Z.
    thigh = np.stack([np.cross(u1, b), -u1, -b], axis=-1)
    pose.local[f"{side}UpLeg"] = np.swapaxes(r_root, -1, -2) @ thigh
    knee = rx(bend)
    pose.local[f"{side}Leg"] = knee
    shank = thigh @ knee
    pose.local[f"{side}Foot"] = np.swapaxes(shank, -1, -2) @ foot_rot
    pose.local[f"{side}ToeBase"] = rx(np.broadcast_to(-np.asarray(toe_deg, dtype=float), (pose.n,)))


def solve_arm(pose: Pose, side: str, wrist, pole, hand_rot=None):
    """Set shoulder and elbow rotations so the wrist reaches ``wrist`` (F, 3); the elbow
    points along ``pole``. ``hand_rot`` (F, 3, 3) is the hand's world orientation
    (default: in line with the forearm)."""
    sign = SIDES[side]
    r_parent, _ = pose.world(f"{side}Shoulder")
    _, shoulder = pose.world(f"{side}Arm")
    u1, b, bend = two_bone(shoulder, wrist, UPPER_ARM, FOREARM, pole, soft=True)
    # Upper-arm frame: rest bone axis (sign * X) maps to u1, the elbow bends toward +Z
    # (Ry(-bend) for the left arm, Ry(+bend) for the right).
    upper = np.stack([sign * u1, np.cross(b, sign * u1), b], axis=-1)
    pose.local[f"{side}Arm"] = np.swapaxes(r_parent, -1, -2) @ upper
    elbow = ry(-sign * bend)
    pose.local[f"{side}ForeArm"] = elbow
    if hand_rot is not None:
        pose.local[f"{side}Hand"] = np.swapaxes(upper @ elbow, -1, -2) @ hand_rot


def arm_fk(pose: Pose, side: str, abduct, flex, elbow, twist=0.0):
    """Arm angles in degrees: ``abduct`` away from the body in the frontal plane (0 =
    hanging, 90 = horizontal), ``flex`` forward (0 = down, 90 = forward), ``elbow``
    flexion; sets the shoulder and elbow rotations."""
    s = SIDES[side]
    n = pose.n
    abduct, flex, elbow, twist = (
        np.broadcast_to(np.asarray(v, dtype=float), (n,)) for v in (abduct, flex, elbow, twist)
    )
    pose.local[f"{side}Arm"] = zxy(-s * (90.0 - abduct), twist, -s * flex)
    pose.local[f"{side}ForeArm"] = ry(-s * elbow)


def foot_on_ground(ball, pitch, yaw=0.0):
    """Ankle position (F, 3) and foot orientation (F, 3, 3) of a foot whose ball would
    rest at ``ball`` (F, 3) when flat, rolled by ``pitch`` degrees (> 0: heel up,
    rolling about the ball; < 0: toes up, rolling about the heel)."""
    pitch = np.asarray(pitch, dtype=float)
    rot = ry(yaw) @ rx(pitch)
    pivot = np.where((pitch < 0)[:, None], HEEL, BALL)  # (F, 3) in the foot frame
    pivot_world = ball + rotate(ry(yaw), pivot - BALL)
    return pivot_world - rotate(rot, pivot), rot


def above_ground(ankle, rot):
    """``ankle`` (F, 3) raised where needed so no point of the foot (ankle, heel, ball,
    toe tip; orientation ``rot`` (F, 3, 3)) is below the floor (y = 0)."""
    pts = np.stack([np.zeros(3), HEEL, BALL, TOE_TIP])  # (4, 3)
    low = (ankle[:, None, 1] + np.einsum("fij,kj->fki", rot, pts)[..., 1]).min(axis=1)
    out = ankle.copy()
    out[:, 1] += np.maximum(-low, 0.0)
    return out


def plant_feet(pose, ball_l, ball_r, pitch_l=None, pitch_r=None):
    """Solve both legs for feet on the ground at the given ball positions."""
    for side, ball, pitch in (("Left", ball_l, pitch_l), ("Right", ball_r, pitch_r)):
        ball = np.broadcast_to(np.asarray(ball, dtype=float), (pose.n, 3))
        p = np.zeros(pose.n) if pitch is None else np.asarray(pitch, dtype=float)
        ankle, rot = foot_on_ground(ball, p)
        solve_leg(pose, side, ankle, rot, toe_deg=np.maximum(p, 0.0))


# --------------------------------------------------------------------------- output


def to_document(
    pose: Pose,
    fps: float,
    *,
    facing_deg: float = 0.0,
    offset=(0.0, 0.0, 0.0),
    path: str | None = None,
) -> BVHDocument:
    """BVH document of ``pose`` turned by ``facing_deg`` about +Y, then moved by ``offset``."""
    yaw = yaw_matrix(facing_deg)
    root_pos = pose.root @ yaw.T + np.asarray(offset, dtype=float)
    joints = [name for name, end in zip(NAMES, END_SITE) if not end]
    rots = np.stack(
        [np.broadcast_to(pose.local[name], (pose.n, 3, 3)) for name in joints], axis=1
    )  # (F, Jr, 3, 3)
    rots[:, 0] = yaw @ rots[:, 0]
    angles = continuous_euler(rots)  # (F, Jr, 3)
    channels = [
        () if end else (ROOT_CHANNELS if name == "Hips" else JOINT_CHANNELS)
        for name, end in zip(NAMES, END_SITE)
    ]
    cols = np.concatenate([root_pos, angles.reshape(pose.n, -1)], axis=1)
    motion = np.round(cols, DECIMALS) + 0.0  # "+ 0.0" turns -0.0 into 0.0
    parents = np.array([-1 if (p := PARENT[n]) is None else INDEX[p] for n in NAMES])
    return BVHDocument(
        names=NAMES,
        parents=parents,
        offsets=np.array([OFFSET[n] for n in NAMES]),
        channels=tuple(channels),
        end_site=np.array(END_SITE, dtype=bool),
        frame_time=1.0 / fps,
        motion=motion,
        path=path,
    )


def continuous_euler(r):
    """ZXY Euler angles (F, J, 3), degrees, of rotations (F, J, 3, 3), continuous over F.

    SciPy keeps the middle (X) angle in [-90, 90]; a knee bent past 90 degrees would
    then jump to the equivalent ``(z + 180, 180 - x, y + 180)``. Both triples are the
    same rotation, so we switch branch wherever the canonical one jumps (Z and Y both
    leap by more than 90 degrees between frames) and unwrap the 360-degree turns.
    """
    f, j = r.shape[:2]
    e = Rotation.from_matrix(r.reshape(-1, 3, 3)).as_euler("ZXY", degrees=True).reshape(f, j, 3)
    alt = np.stack(
        [e[..., 0] + 180.0, np.where(e[..., 1] >= 0, 180.0, -180.0) - e[..., 1], e[..., 2] + 180.0],
        axis=-1,
    )
    alt[..., [0, 2]] = (alt[..., [0, 2]] + 180.0) % 360.0 - 180.0

    def wrapped(d):
        return np.abs((d + 180.0) % 360.0 - 180.0)

    d = np.diff(e, axis=0)
    leap = (wrapped(d[..., 0]) > 90) & (wrapped(d[..., 2]) > 90)  # (F-1, J)
    first = np.abs(alt[0][:, [0, 2]]).sum(-1) < np.abs(e[0][:, [0, 2]]).sum(-1) - 1e-9
    flips = np.concatenate([np.zeros((1, j), dtype=int), np.cumsum(leap, axis=0)], axis=0)
    use_alt = (flips + first.astype(int)) % 2 == 1
    out = np.where(use_alt[..., None], alt, e)
    return np.unwrap(out, period=360.0, axis=0)
