"""A character's joint tracks: some joints' smoothed trajectories, heights and speeds,
gathered once, component-major.

The story selector (:mod:`snapcore.select.story`) reads the same joints for several
terms -- the key joints for the pose descriptor, the trunk and the strikes, the limbs'
joints for the contacts -- and each gathering its own read the (F, J, 3) positions
again. :class:`JointTracks` is that one gathering, laid out as one contiguous row of
frames per component and joint, (3, A, F), the layout every later step works on: a
joint's height, speed or coordinate over the clip is a row, a set of joints a gather of
whole rows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from snapcore.select.signals import SAVGOL_POLYORDER, window_frames
from snapcore.select.stance import joint_trajectories

__all__ = ["JointTracks", "row_speeds"]


@dataclass(frozen=True)
class JointTracks:
    """Smoothed trajectories of some joints of one character, with their speeds.

    Attributes
    ----------
    joints : ndarray of int, shape (A,)
        The joints, sorted increasing; row ``a`` of the arrays below is joint
        ``joints[a]``.
    rows : ndarray of shape (3, A, F)
        Savitzky-Golay smoothed positions (m) component-major, each (component, joint)
        a contiguous row of frames: ``rows[1]`` is the heights. The values of
        :func:`snapcore.select.stance.joint_trajectories`, transposed.
    speed : ndarray of shape (A, F)
        Speeds in metres per frame (:func:`row_speeds`).
    """

    joints: np.ndarray
    rows: np.ndarray
    speed: np.ndarray

    @classmethod
    def of(cls, character, joints, *, fps: float, smooth_s: float) -> JointTracks:
        """The tracks of ``joints`` (any order; at least two frames).

        Parameters
        ----------
        character : Character
        joints : array_like of int, shape (A,)
        fps : float
        smooth_s : float
            Savitzky-Golay window (s), as for
            :func:`snapcore.select.stance.joint_trajectories`.

        Notes
        -----
        Where the smoothing is the identity (a window of at most ``polyorder + 1``
        frames: the default 0.05 s at 60 or 30 fps) the rows are gathered straight
        from the positions seen as (3 J, F) rows: one copy, no (F, A, 3) intermediate
        and no transpose of it (0.17 against 0.25 ms for 16 of 57 joints over 2,000
        frames, two characters); the same values.
        """
        j = np.unique(np.asarray(joints, dtype=np.int64))
        pos = character.positions
        n_f, n_j = pos.shape[:2]
        w = window_frames(smooth_s, fps, n_f, SAVGOL_POLYORDER) if smooth_s > 0 else 0
        if w <= SAVGOL_POLYORDER + 1:
            # row 3 j + c of the (3 J, F) view is component c of joint j: component-major
            pick = (3 * j + np.arange(3)[:, None]).ravel()
            rows = pos.reshape(n_f, 3 * n_j).T[pick].reshape(3, j.size, n_f)
        else:
            x = joint_trajectories(character, j, fps=fps, smooth_s=smooth_s)  # (F, A, 3)
            rows = np.ascontiguousarray(x.transpose(2, 1, 0))
        return cls(j, rows, row_speeds(rows))

    @property
    def height(self) -> np.ndarray:
        """World heights (m), shape (A, F): a view of ``rows[1]``."""
        return self.rows[1]

    def columns(self, joints) -> np.ndarray:
        """The rows of ``joints`` (each one of :attr:`joints`), shape (len(joints),)."""
        return np.searchsorted(self.joints, joints)


def row_speeds(rows: np.ndarray) -> np.ndarray:
    """Speeds of trajectories given as component rows, in units per frame.

    Parameters
    ----------
    rows : ndarray of shape (3, ..., F)
        At least two frames.

    Returns
    -------
    ndarray of shape (..., F)
        ``np.gradient``'s central differences and one-sided ends along the frames, and
        the norm over the components as two additions: the arithmetic of
        :func:`snapcore.select.strikes.rows_and_speeds`, element by element.
    """
    x = np.ascontiguousarray(rows)
    g = np.empty_like(x)
    # central differences over the rows laid end to end, one flat pass (on the (3, A,
    # F - 2) slices, 3.5 times as long): each row's first and last frame get values
    # across a row boundary, overwritten below by the one-sided ends
    flat, gf = x.reshape(-1), g.reshape(-1)
    np.subtract(flat[2:], flat[:-2], out=gf[1:-1])
    np.subtract(x[..., 1], x[..., 0], out=g[..., 0])
    np.subtract(x[..., -1], x[..., -2], out=g[..., -1])
    # twice the gradient everywhere (the ends doubled): the halving moves to the speed,
    # a third as many values; scaling by a power of two is exact through the squares,
    # the sum and the root (sqrt(s / 4) = sqrt(s) / 2), so the doubles are the same
    g[..., 0] *= 2.0
    g[..., -1] *= 2.0
    g *= g
    v = g[0] + g[1]
    v += g[2]
    np.sqrt(v, out=v)
    v *= 0.5
    return v
