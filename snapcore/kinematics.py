"""Forward kinematics of BVH skeletons, vectorised over all frames at once.

Pure functions over arrays: channel values in, world positions and rotations out. The
only Python loop runs over joints (tens), never over frames (thousands); Euler angles of
every joint that shares a rotation order are converted in one SciPy call.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "ChannelLayout",
    "channel_layout",
    "local_transforms",
    "forward_kinematics",
    "joint_depths",
    "euler_to_matrix",
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


def _axis_matrices(axis: str, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices about one coordinate axis, shape ``angle.shape + (3, 3)``."""
    c, s = np.cos(angle), np.sin(angle)
    m = np.zeros(angle.shape + (3, 3))
    i = _AXIS[axis]
    j, k = (i + 1) % 3, (i + 2) % 3
    m[..., i, i] = 1.0
    m[..., j, j] = c
    m[..., k, k] = c
    m[..., j, k] = -s
    m[..., k, j] = s
    return m


def euler_to_matrix(order: str, angles: np.ndarray) -> np.ndarray:
    """Intrinsic Euler angles to rotation matrices.

    Parameters
    ----------
    order : str
        Three axis letters, e.g. ``"ZXY"``: ``R = R_Z(a0) @ R_X(a1) @ R_Y(a2)``, which is
        what BVH channel order means (SciPy's ``Rotation.from_euler("ZXY", ...)`` with
        upper-case, intrinsic axes gives the same; this is ~10x faster for our sizes).
    angles : ndarray of shape (..., 3)
        Radians, in ``order`` order.

    Returns
    -------
    ndarray of shape (..., 3, 3)
    """
    angles = np.asarray(angles, dtype=float)
    r = _axis_matrices(order[0], angles[..., 0])
    r = r @ _axis_matrices(order[1], angles[..., 1])
    return r @ _axis_matrices(order[2], angles[..., 2])


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
    rot : ndarray of shape (F, J, 3, 3)
        Local rotation of each joint relative to its parent.
    trans : ndarray of shape (F, J, 3)
        Local translation: the offset, with position channels replacing components
        (BVH semantics for the root and for 6-channel joints).
    """
    motion = np.asarray(motion, dtype=float)
    f_count, j_count = motion.shape[0], len(layout.rot_order)
    rot = np.broadcast_to(np.eye(3), (f_count, j_count, 3, 3)).copy()
    by_order: dict[str, list[int]] = {}
    for j, order in enumerate(layout.rot_order):
        if order:
            by_order.setdefault(order, []).append(j)
    for order, joints in by_order.items():
        cols = layout.rot_cols[joints]  # (Jg, 3), -1 for padded axes
        angles = np.where(cols >= 0, motion[:, np.maximum(cols, 0)], 0.0)  # (F, Jg, 3)
        rot[:, joints] = euler_to_matrix(order, np.deg2rad(angles))
    trans = np.broadcast_to(np.asarray(offsets, dtype=float), (f_count, j_count, 3)).copy()
    has = layout.pos_cols >= 0
    if has.any():
        jj, aa = np.nonzero(has)
        trans[:, jj, aa] = motion[:, layout.pos_cols[jj, aa]]
    return rot, trans


def forward_kinematics(parents, rot_local, trans_local):
    """World rotations and positions from local transforms.

    Parameters
    ----------
    parents : ndarray of int, shape (J,)
        Parent index per joint, ``-1`` for roots; parents precede their children.
    rot_local : ndarray of shape (F, J, 3, 3)
    trans_local : ndarray of shape (F, J, 3)

    Returns
    -------
    positions : ndarray of shape (F, J, 3)
    rotations : ndarray of shape (F, J, 3, 3)
        World rotation of each joint's frame.
    """
    f_count, j_count = trans_local.shape[:2]
    parents = np.asarray(parents, dtype=int)
    pos = np.empty((f_count, j_count, 3))
    rot = np.empty((f_count, j_count, 3, 3))
    # Batch by tree depth: one product per level (about ten) instead of one per joint.
    depth = joint_depths(parents)
    for d in range(int(depth.max()) + 1):
        idx = np.flatnonzero(depth == d)
        if d == 0:
            rot[:, idx] = rot_local[:, idx]
            pos[:, idx] = trans_local[:, idx]
            continue
        rp = rot[:, parents[idx]]
        rot[:, idx] = rp @ rot_local[:, idx]
        pos[:, idx] = pos[:, parents[idx]] + (rp @ trans_local[:, idx, :, None])[..., 0]
    return pos, rot


def joint_depths(parents) -> np.ndarray:
    """Depth of each joint in its tree (roots are 0), shape (J,)."""
    parents = np.asarray(parents, dtype=int)
    depth = np.zeros(parents.size, dtype=int)
    for j, p in enumerate(parents):
        if p >= j:
            raise ValueError(f"parents: joint {j} has parent {p}; parents must precede children")
        depth[j] = 0 if p < 0 else depth[p] + 1
    return depth
