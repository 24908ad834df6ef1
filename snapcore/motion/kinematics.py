"""Forward kinematics of BVH skeletons, vectorised over all frames at once.

Pure functions over arrays: channel values in, world positions and rotations out. The
only Python loop runs over joints (tens), never over frames (thousands); Euler angles of
every joint that shares a rotation order are converted in one SciPy call.
"""

from __future__ import annotations

import numpy as np

from snapcore.errors import SceneError

__all__ = [
    "ChannelLayout",
    "channel_layout",
    "local_transforms",
    "local_rows",
    "forward_kinematics",
    "forward_kinematics_rows",
    "rows_to_matrix",
    "joint_depths",
    "rest_positions",
    "euler_to_matrix",
    "euler_to_quat",
    "quat_mul",
    "quat_rotate",
    "quat_to_matrix",
    "matrix_to_quat",
    "joints_from_world",
    "trs_matrix",
]

_AXIS = {"X": 0, "Y": 1, "Z": 2}


class ChannelLayout:
    """Where each joint's rotation and position channels sit in a motion row.

    Attributes
    ----------
    rot_order : tuple of str, length J
        Intrinsic Euler order per joint as the channels appear (``"ZXY"``), ``""`` if
        the joint has no rotation channels. BVH channel order means intrinsic
        rotations applied left to right: ``R = R_Z @ R_X @ R_Y`` for ``ZXY``.
    rot_cols : ndarray of int, shape (J, 3)
        Motion columns of the three angles in ``rot_order`` order; ``-1`` if absent.
    pos_cols : ndarray of int, shape (J, 3)
        Motion columns of the x, y, z position channels; ``-1`` where absent.
    """

    def __init__(self, rot_order, rot_cols, pos_cols):
        self.rot_order = tuple(rot_order)
        self.rot_cols = np.asarray(rot_cols, dtype=int)
        self.pos_cols = np.asarray(pos_cols, dtype=int)


def channel_layout(channels) -> ChannelLayout:
    """Build the :class:`ChannelLayout` of per-joint channel-name tuples."""
    j_count = len(channels)
    rot_order, rot_cols = [], np.full((j_count, 3), -1, dtype=int)
    pos_cols = np.full((j_count, 3), -1, dtype=int)
    col = 0
    for j, chans in enumerate(channels):
        order = ""
        for c in chans:
            axis = c[0].upper()
            if c.endswith("rotation"):
                rot_cols[j, len(order)] = col
                order += axis
            else:
                pos_cols[j, _AXIS[axis]] = col
            col += 1
        if order and len(order) < 3:
            # One or two rotation channels: pad with the missing axes at angle 0.
            missing = [a for a in "XYZ" if a not in order]
            order += "".join(missing[: 3 - len(order)])
        rot_order.append(order)
    return ChannelLayout(rot_order, rot_cols, pos_cols)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions ``(..., 4)`` stored ``(w, x, y, z)``."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` ``(..., 3)`` by unit quaternions ``q`` ``(..., 4)``."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` ``(w, x, y, z)`` to rotation matrices ``(..., 3, 3)``."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz, wx, wy, wz = x * y, x * z, y * z, w * x, w * y, w * z
    m = np.empty(q.shape[:-1] + (3, 3))
    m[..., 0, 0] = 1 - 2 * (yy + zz)
    m[..., 0, 1] = 2 * (xy - wz)
    m[..., 0, 2] = 2 * (xz + wy)
    m[..., 1, 0] = 2 * (xy + wz)
    m[..., 1, 1] = 1 - 2 * (xx + zz)
    m[..., 1, 2] = 2 * (yz - wx)
    m[..., 2, 0] = 2 * (xz - wy)
    m[..., 2, 1] = 2 * (yz + wx)
    m[..., 2, 2] = 1 - 2 * (xx + yy)
    return m


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` to unit quaternions ``(..., 4)`` ``(w, x, y, z)``.

    SciPy's conversion (Markley's method: accurate for every angle, and it projects a
    slightly non-orthogonal matrix onto the nearest rotation); the sign is SciPy's
    choice, ``q`` and ``-q`` being the same rotation.
    """
    from scipy.spatial.transform import Rotation

    m = np.asarray(m, dtype=float)
    q = Rotation.from_matrix(m.reshape(-1, 3, 3)).as_quat()  # (x, y, z, w)
    return np.roll(q, 1, axis=-1).reshape(m.shape[:-2] + (4,))


def euler_to_quat(order: str, angles: np.ndarray) -> np.ndarray:
    """Intrinsic Euler angles to unit quaternions ``(..., 4)`` ``(w, x, y, z)``.

    Parameters
    ----------
    order : str
        Three axis letters, e.g. ``"ZXY"``: ``R = R_Z(a0) @ R_X(a1) @ R_Y(a2)``, which is
        what BVH channel order means (SciPy's ``Rotation.from_euler("ZXY", ...)`` with
        upper-case, intrinsic axes is the same rotation).
    angles : ndarray of shape (..., 3)
        Radians, in ``order`` order.
    """
    angles = np.asarray(angles, dtype=float)
    halves = [0.5 * angles[..., k] for k in range(3)]
    qw, qx, qy, qz = _compose_axes(order, [(np.cos(h), np.sin(h)) for h in halves])
    return np.stack([qw, qx, qy, qz], axis=-1)


def _compose_axes(order: str, cos_sin) -> tuple[np.ndarray, ...]:
    """The four components of the identity composed with each axis's rotation in turn.

    ``cos_sin`` holds, per letter of ``order``, the cosine and sine of half its angle
    (arrays of one shape). This is ``quat_mul(q, e)`` term by term on separate
    component arrays (no moveaxis and stack per axis), zero terms included so that
    every sum, the sign of a zero too, is the one ``quat_mul`` gives.
    """
    shape = np.shape(cos_sin[0][0])
    zero = np.zeros(shape)
    qw, qx, qy, qz = np.ones(shape), zero, zero, zero
    for (c, s), axis in zip(cos_sin, order):
        e = [c, zero, zero, zero]
        e[1 + _AXIS[axis]] = s
        bw, bx, by, bz = e
        qw, qx, qy, qz = (
            qw * bw - qx * bx - qy * by - qz * bz,
            qw * bx + qx * bw + qy * bz - qz * by,
            qw * by - qx * bz + qy * bw + qz * bx,
            qw * bz + qx * by - qy * bx + qz * bw,
        )
    return qw, qx, qy, qz


def euler_to_matrix(order: str, angles: np.ndarray) -> np.ndarray:
    """Intrinsic Euler angles ``(..., 3)`` (radians) to matrices ``(..., 3, 3)``."""
    return quat_to_matrix(euler_to_quat(order, angles))


def local_transforms(layout: ChannelLayout, offsets, motion):
    """Local rotations and translations of every joint at every frame.

    Parameters
    ----------
    layout : ChannelLayout
    offsets : ndarray of shape (J, 3)
        Rest offsets (any unit; translations come out in the same unit).
    motion : ndarray of shape (F, C)
        Channel values; angles in degrees.

    Returns
    -------
    quat : ndarray of shape (F, J, 4)
        Local rotation of each joint relative to its parent, unit quaternion (w, x, y, z).
    trans : ndarray of shape (F, J, 3)
        Local translation: the offset, with position channels replacing components
        (BVH semantics for the root and for 6-channel joints).
    """
    quat, trans = local_rows(layout, offsets, motion)
    return (
        np.ascontiguousarray(quat.transpose(2, 1, 0)),
        np.ascontiguousarray(trans.transpose(2, 1, 0)),
    )


def local_rows(layout: ChannelLayout, offsets, motion):
    """:func:`local_transforms` component-major: each joint's component a row of frames.

    Returns
    -------
    quat : ndarray of shape (4, J, F)
        Local rotations, unit quaternions (w, x, y, z).
    trans : ndarray of shape (3, J, F)
        Local translations.

    Notes
    -----
    The channels are transposed once to rows of frames, so every angle, sine and
    product runs on contiguous rows. A row of angles that is zero at every frame (a
    finger BVH exporters keep still: 54 of the salsa dancers' 129 rotation channels)
    takes ``cos = 1`` and ``sin = angle`` (the sign of a zero kept) without the
    trigonometry, which is what ``np.cos`` and ``np.sin`` return there. The results
    are :func:`euler_to_quat`'s to the bit.
    """
    motion = np.asarray(motion, dtype=float)
    f_count, j_count = motion.shape[0], len(layout.rot_order)
    rows = np.ascontiguousarray(motion.T)  # (C, F)
    quat = np.empty((4, j_count, f_count))
    quat[0] = 1.0
    quat[1:] = 0.0
    by_order: dict[str, list[int]] = {}
    for j, order in enumerate(layout.rot_order):
        if order:
            by_order.setdefault(order, []).append(j)
    for order, joints in by_order.items():
        cols = layout.rot_cols[joints]  # (Jg, 3), -1 for padded axes (angle 0)
        cos_sin = []
        for k in range(3):
            half = np.zeros((len(joints), f_count))
            have = np.flatnonzero(cols[:, k] >= 0)
            half[have] = np.deg2rad(rows[cols[have, k]])
            half *= 0.5
            c, s = np.ones_like(half), half.copy()
            moving = np.flatnonzero(half.any(axis=1))
            if moving.size:
                c[moving] = np.cos(half[moving])
                s[moving] = np.sin(half[moving])
            cos_sin.append((c, s))
        idx = np.asarray(joints)
        for comp, values in enumerate(_compose_axes(order, cos_sin)):
            quat[comp, idx] = values
    trans = np.empty((3, j_count, f_count))
    trans[:] = np.asarray(offsets, dtype=float).T[:, :, None]
    has = layout.pos_cols >= 0
    if has.any():
        jj, aa = np.nonzero(has)
        trans[aa, jj] = rows[layout.pos_cols[jj, aa]]
    return quat, trans


def forward_kinematics(parents, quat_local, trans_local):
    """World positions and rotations from local transforms.

    Parameters
    ----------
    parents : ndarray of int, shape (J,)
        Parent index per joint, ``-1`` for roots; parents precede their children.
    quat_local : ndarray of shape (F, J, 4)
        Local rotations as unit quaternions (w, x, y, z).
    trans_local : ndarray of shape (F, J, 3)

    Returns
    -------
    positions : ndarray of shape (F, J, 3)
    quat_world : ndarray of shape (F, J, 4)
        World rotation of each joint's frame (see :func:`quat_to_matrix`).

    Notes
    -----
    Quaternion products are elementwise arithmetic, several times faster in NumPy than
    stacked 3x3 matrix products; joints are batched by tree depth so the Python loop
    runs about ten times, not once per joint or frame.

    The work runs on component-major copies (:func:`forward_kinematics_rows`).
    """
    parents = np.asarray(parents, dtype=int)
    ql = np.ascontiguousarray(np.asarray(quat_local, dtype=float).transpose(2, 1, 0))
    tl = np.ascontiguousarray(np.asarray(trans_local, dtype=float).transpose(2, 1, 0))
    p, q = forward_kinematics_rows(parents, ql, tl)
    return (
        np.ascontiguousarray(p.transpose(2, 1, 0)),
        np.ascontiguousarray(q.transpose(2, 1, 0)),
    )


def forward_kinematics_rows(parents, quat_local, trans_local):
    """:func:`forward_kinematics` on component-major arrays.

    Parameters
    ----------
    parents : ndarray of int, shape (J,)
    quat_local : ndarray of shape (4, J, F)
    trans_local : ndarray of shape (3, J, F)

    Returns
    -------
    positions : ndarray of shape (3, J, F)
    quat_world : ndarray of shape (4, J, F)

    Notes
    -----
    Every joint's component is a contiguous row of frames, so a level's parents are
    gathered as whole rows and every product runs on contiguous rows. Gathering and
    scattering (F, J, 4) across its middle axis, ``np.cross`` and ``np.stack`` took
    about 60 % of the time of the first version. The arithmetic is :func:`quat_mul`'s
    and :func:`quat_rotate`'s, term by term in the same order: the results are
    identical to the bit.
    """
    j_count, f_count = trans_local.shape[1:]
    parents = np.asarray(parents, dtype=int)
    ql, tl = quat_local, trans_local
    q = np.empty((4, j_count, f_count))
    p = np.empty((3, j_count, f_count))
    depth = joint_depths(parents)
    for d in range(int(depth.max()) + 1):
        idx = np.flatnonzero(depth == d)
        if d == 0:
            q[:, idx] = ql[:, idx]
            p[:, idx] = tl[:, idx]
            continue
        par = parents[idx]
        aw, ax, ay, az = np.take(q, par, axis=1)  # the parents' world rotations (n, F)
        bw, bx, by, bz = np.take(ql, idx, axis=1)
        # quat_mul(parent, local)
        q[0, idx] = aw * bw - ax * bx - ay * by - az * bz
        q[1, idx] = aw * bx + ax * bw + ay * bz - az * by
        q[2, idx] = aw * by - ax * bz + ay * bw + az * bx
        q[3, idx] = aw * bz + ax * by - ay * bx + az * bw
        # quat_rotate(parent, offset): t = 2 u x v, then v + w t + u x t (np.cross's terms)
        vx, vy, vz = np.take(tl, idx, axis=1)
        t0 = 2.0 * (ay * vz - az * vy)
        t1 = 2.0 * (az * vx - ax * vz)
        t2 = 2.0 * (ax * vy - ay * vx)
        px, py, pz = np.take(p, par, axis=1)
        p[0, idx] = px + (vx + aw * t0 + (ay * t2 - az * t1))
        p[1, idx] = py + (vy + aw * t1 + (az * t0 - ax * t2))
        p[2, idx] = pz + (vz + aw * t2 + (ax * t1 - ay * t0))
    return p, q


def rows_to_matrix(q: np.ndarray) -> np.ndarray:
    """Component-major unit quaternions (4, J, F) to rotation matrices (F, J, 3, 3).

    :func:`quat_to_matrix`'s arithmetic on contiguous rows, written straight into the
    frame-major result (no transposed copy of the quaternions): identical to the bit.
    """
    w, x, y, z = q
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz, wx, wy, wz = x * y, x * z, y * z, w * x, w * y, w * z
    m = np.empty((w.shape[1], w.shape[0], 3, 3))
    mt = m.transpose(2, 3, 1, 0)  # (3, 3, J, F) view of the result
    mt[0, 0] = 1 - 2 * (yy + zz)
    mt[0, 1] = 2 * (xy - wz)
    mt[0, 2] = 2 * (xz + wy)
    mt[1, 0] = 2 * (xy + wz)
    mt[1, 1] = 1 - 2 * (xx + zz)
    mt[1, 2] = 2 * (yz - wx)
    mt[2, 0] = 2 * (xz - wy)
    mt[2, 1] = 2 * (yz + wx)
    mt[2, 2] = 1 - 2 * (xx + yy)
    return m


def rest_positions(parents, offsets) -> np.ndarray:
    """Joint positions of a skeleton in its rest pose (identity rotations), (J, 3)."""
    parents = np.asarray(parents)
    out = np.zeros((len(parents), 3))
    for j, p in enumerate(parents):
        out[j] = offsets[j] + (out[p] if p >= 0 else 0.0)
    return out


def joint_depths(parents) -> np.ndarray:
    """Depth of each joint in its tree (roots are 0), shape (J,)."""
    parents = np.asarray(parents, dtype=int)
    depth = np.zeros(parents.size, dtype=int)
    for j, p in enumerate(parents):
        if p >= j:
            raise SceneError(f"parents: joint {j} has parent {p}; parents must precede children")
        depth[j] = 0 if p < 0 else depth[p] + 1
    return depth


def joints_from_world(world: np.ndarray, parents) -> dict:
    """Joint frames of a skeleton from its joints' world matrices (glTF, FBX).

    Scene-graph formats give each joint a full 4 × 4 world matrix that may scale (glTF
    node scale, an FBX armature scaled by 100); the suite's characters keep pure
    rotations and one uniform scale per joint apart, the scale constant over time.

    Parameters
    ----------
    world : ndarray of shape (F, J, 4, 4)
        World matrices of every joint at every frame.
    parents : ndarray of int, shape (J,)
        Parent joint of each joint (``-1`` for a root); parents precede children.

    Returns
    -------
    dict
        ``positions`` (F, J, 3); ``rotations`` (F, J, 3, 3), pure rotations by polar
        decomposition; ``local_rotations`` (F, J, 3, 3), relative to the parent's;
        ``offsets`` (J, 3), each joint's median position in its parent's frame;
        ``joint_scale`` (J,), the median isotropic world scale; ``uniform`` (bool),
        False when a joint scales non-uniformly or over time (by more than 0.1 %).
    """
    parents = np.asarray(parents, dtype=int)
    lin = world[..., :3, :3]
    u, sv, vt = np.linalg.svd(lin)
    rot = u @ vt
    flip = np.linalg.det(rot) < 0
    if np.any(flip):
        u[flip, :, -1] *= -1
        rot = u @ vt
    scale_fj = np.cbrt(np.abs(np.linalg.det(lin)))  # (F, J) isotropic world scale
    joint_scale = np.median(scale_fj, axis=0)
    uniform = not (
        np.any(np.abs(scale_fj / np.where(joint_scale > 0, joint_scale, 1) - 1) > 1e-3)
        or np.any(sv.max(-1) > sv.min(-1) * (1 + 1e-3))
    )
    pos = world[..., :3, 3]
    has_parent = parents >= 0
    par = np.maximum(parents, 0)
    par_rot = np.where(has_parent[None, :, None, None], rot[:, par], np.eye(3))
    local_rot = np.swapaxes(par_rot, -1, -2) @ rot
    rel = pos - np.where(has_parent[None, :, None], pos[:, par], 0.0)
    offsets = np.median(np.einsum("fjki,fjk->fji", par_rot, rel), axis=0)
    return {
        "positions": pos,
        "rotations": rot,
        "local_rotations": local_rot,
        "offsets": offsets,
        "joint_scale": joint_scale,
        "uniform": uniform,
    }


def trs_matrix(t: np.ndarray, q: np.ndarray, s: np.ndarray) -> np.ndarray:
    """4 x 4 matrices ``T · R · S`` from translations (..., 3), unit quaternions (..., 4)
    in (x, y, z, w) order (glTF, FBX via ufbx) and scales (..., 3)."""
    x, y, z, w = np.moveaxis(q, -1, 0)
    r = np.empty(q.shape[:-1] + (3, 3))
    r[..., 0, 0] = 1 - 2 * (y * y + z * z)
    r[..., 0, 1] = 2 * (x * y - w * z)
    r[..., 0, 2] = 2 * (x * z + w * y)
    r[..., 1, 0] = 2 * (x * y + w * z)
    r[..., 1, 1] = 1 - 2 * (x * x + z * z)
    r[..., 1, 2] = 2 * (y * z - w * x)
    r[..., 2, 0] = 2 * (x * z - w * y)
    r[..., 2, 1] = 2 * (y * z + w * x)
    r[..., 2, 2] = 1 - 2 * (x * x + y * y)
    m = np.zeros(q.shape[:-1] + (4, 4))
    m[..., :3, :3] = r * s[..., None, :]
    m[..., :3, 3] = t
    m[..., 3, 3] = 1.0
    return m
