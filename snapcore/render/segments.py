"""Body segment frames built from where the joints are, not from their rest rotations.

A skeleton's joint rotations are relative to its own rest pose, and rest poses differ
(BVH identity rests, T- and A-poses, Bandai's per-joint rotated rest, Z-up exporters):
a body aligned through them is aligned only as well as its rest pose matches the rig's
(the Bandai torso came out turned 90°). Joint *positions* are the same whatever the rest
convention, so each segment's frame here is made from them, by the same recipe on the
skeleton and on the body's rig (:mod:`snapcore.render.human`), and the rig segment is
turned by ``F_skeleton · F_rig^T``:

- the pelvis: its bone along the spine, its left axis the hip line (left hip - right hip);
- the chest: along its bone, left axis the shoulder line; the spine bones between blend
  the two lines by height; the neck takes the shoulder line;
- each limb segment (upper arm, forearm, thigh, shank): along its bone, left axis the
  *hinge* of its limb, the normal of the plane of the bend (elbow: upper arm x forearm;
  knee: thigh x shank); a nearly straight limb has no plane, so the hinge blends (by the
  bend angle, 8° to 30°) into a stand-in: for a leg the normal of the thigh and the
  foot (the knee bends across the foot's line), for an arm the rig's hinge carried by
  the chest (the smallest swing of the rig's arm onto the skeleton's);
- the foot and toes: along ankle → toe (toe → toe end), left axis the leg's hinge;
- the clavicle and hip-joint pieces: along their bone, facing as the chest / pelvis.

Where positions cannot say how a segment is twisted (a head with no eyes and no
head-top, a hand whose fingers lie along its axis), its frame is the joint's rotation
times a constant ``X`` calibrated on the clip: the chordal mean over frames of the
rotation that puts the segment, relative to its parent segment, as the rig has it. A
constant right factor is exactly what a rest convention changes in a rotation
(``R' = R C``), so ``R' X' = R X``: still no rest convention enters.

Every function is vectorised over frames: arrays (..., 3) in, (..., 3, 3) out, frames
as columns ``(x, y, z)`` with ``x`` the segment's left, ``y`` along it, ``z = x × y``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "axis_rotation",
    "rest_frame",
    "cross",
    "norm",
    "unit",
    "frame_x",
    "frame_z",
    "hinge",
    "swing_matrices",
    "mean_rotation",
    "BEND_FROM_DEG",
    "BEND_FULL_DEG",
]

#: A limb bent less than this has no bend plane (only the stand-in hinge is used) ...
BEND_FROM_DEG = 8.0
#: ... and from this bend on its plane alone gives the hinge.
BEND_FULL_DEG = 30.0


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` over the last axis of (..., 3) arrays (broadcast): ``np.cross``'s values
    (the same products and differences) without its axis handling, which cost more than
    the arithmetic on the retargeting's arrays (26 calls per posing)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def norm(v: np.ndarray, *, keepdims: bool = False) -> np.ndarray:
    """Euclidean length over the last axis: ``np.linalg.norm(v, axis=-1)``'s values (the
    same sum of squares) without its checks."""
    return np.sqrt(np.add.reduce(v * v, axis=-1, keepdims=keepdims))  # type: ignore[call-overload]


def unit(v: np.ndarray) -> np.ndarray:
    """``v`` scaled to unit length along its last axis (zero vectors stay zero)."""
    n = norm(v, keepdims=True)
    return v / np.where(n > 1e-12, n, 1.0)


def axis_rotation(axis: int, angle: float) -> np.ndarray:
    """The rotation by ``angle`` (radians) about coordinate axis ``axis``: (3, 3)."""
    u, v = [k for k in range(3) if k != axis][:: -1 if axis == 1 else 1]
    m = np.eye(3)
    m[u, u] = m[v, v] = np.cos(angle)
    m[v, u], m[u, v] = np.sin(angle), -np.sin(angle)
    return m


def rest_frame(axis: np.ndarray) -> np.ndarray:
    """A right-handed orthonormal frame (columns x, y, z) with y along ``axis``: (3, 3)."""
    y = unit(axis)
    helper = np.array([0.0, 0.0, 1.0]) if abs(y[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = unit(np.cross(y, helper))
    return np.stack([x, y, np.cross(x, y)], axis=1)


def _perp(y: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Unit component of ``ref`` perpendicular to unit ``y``; where ``ref`` is (nearly)
    parallel to ``y``, any fixed perpendicular (a degenerate reference has no twist)."""
    r = ref - y * np.sum(y * ref, axis=-1, keepdims=True)
    n = norm(r, keepdims=True)
    bad = n[..., 0] < 1e-9
    if np.any(bad):
        helper = np.where(np.abs(y[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        alt = helper - y * np.sum(y * helper, axis=-1, keepdims=True)
        r = np.where(bad[..., None], alt, r)
        n = norm(r, keepdims=True)
    return r / n


def _axis(y) -> np.ndarray:
    """Unit ``y``; a zero vector (a bone of no length in some frame) becomes +Y, so the
    frame stays a rotation."""
    y = unit(np.asarray(y, float))
    zero = norm(y) < 0.5
    return np.where(zero[..., None], [0.0, 1.0, 0.0], y) if np.any(zero) else y


def frame_x(y: np.ndarray, x_ref: np.ndarray) -> np.ndarray:
    """Frame with ``y`` along ``y`` and ``x`` towards ``x_ref``: (..., 3) → (..., 3, 3)."""
    y = _axis(y)
    x = _perp(y, np.broadcast_to(np.asarray(x_ref, float), y.shape))
    return np.stack([x, y, cross(x, y)], axis=-1)


def frame_z(y: np.ndarray, z_ref: np.ndarray) -> np.ndarray:
    """Frame with ``y`` along ``y`` and ``z`` towards ``z_ref``: (..., 3) → (..., 3, 3)."""
    y = _axis(y)
    z = _perp(y, np.broadcast_to(np.asarray(z_ref, float), y.shape))
    return np.stack([cross(y, z), y, z], axis=-1)


def swing_matrices(a: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Smallest rotations taking directions ``a`` to ``d``: (..., 3) → (..., 3, 3).

    Rodrigues' formula about ``a × d``; for opposite vectors (no unique smallest
    rotation) a half turn about an axis perpendicular to ``a``.
    """
    a, d = unit(np.asarray(a, float)), unit(np.asarray(d, float))
    a, d = np.broadcast_arrays(a, d)
    c = np.sum(a * d, axis=-1)[..., None, None]
    v = cross(a, d)
    k = np.zeros(v.shape + (3,))
    k[..., 0, 1], k[..., 0, 2] = -v[..., 2], v[..., 1]
    k[..., 1, 0], k[..., 1, 2] = v[..., 2], -v[..., 0]
    k[..., 2, 0], k[..., 2, 1] = -v[..., 1], v[..., 0]
    opposite = c[..., 0, 0] < -1 + 1e-9
    denom = np.where(opposite[..., None, None], 1.0, 1.0 + c)
    out = np.eye(3) + k + (k @ k) / denom
    if np.any(opposite):
        p = _perp(a, np.broadcast_to([1.0, 0.0, 0.0], a.shape))
        half = 2 * p[..., :, None] * p[..., None, :] - np.eye(3)
        out = np.where(opposite[..., None, None], half, out)
    return out


def hinge(proximal: np.ndarray, distal: np.ndarray, stand_in: np.ndarray) -> np.ndarray:
    """The hinge axis of a limb (unit, (..., 3)): the bend plane's normal
    ``proximal × distal``, blended into ``stand_in`` (unit, same sign convention) as the
    bend angle falls from :data:`BEND_FULL_DEG` to :data:`BEND_FROM_DEG`."""
    p, d = unit(proximal), unit(distal)
    n = cross(p, d)
    ang = np.degrees(np.arctan2(norm(n), np.sum(p * d, axis=-1)))
    w = np.clip((ang - BEND_FROM_DEG) / (BEND_FULL_DEG - BEND_FROM_DEG), 0.0, 1.0)
    w = (w * w * (3 - 2 * w))[..., None]  # smoothstep: no kink where the plane takes over
    s = unit(stand_in)
    s = s - p * np.sum(p * s, axis=-1, keepdims=True)  # both perpendicular to the bone
    out = w * unit(n) + (1 - w) * unit(s)
    # a stand-in opposite to the plane's normal (an arm bent backwards) could cancel it
    # half-way: take whichever of the two weighs more there
    weak = norm(out) < 0.2
    if np.any(weak):
        out = np.where(weak[..., None], np.where(w >= 0.5, unit(n), unit(s)), out)
    return unit(out)


def mean_rotation(m: np.ndarray) -> np.ndarray:
    """The rotation nearest (Frobenius) to the sum of rotations ``m`` (N, 3, 3): their
    chordal L2 mean (polar factor by SVD, a reflection turned into a rotation)."""
    u, _, vt = np.linalg.svd(np.sum(m, axis=0))
    r = u @ vt
    if np.linalg.det(r) < 0:
        u[:, -1] *= -1
        r = u @ vt
    return r
