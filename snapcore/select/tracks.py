"""A character's joint tracks: some joints' smoothed trajectories, heights and speeds,
gathered once.

The story selector (:mod:`snapcore.select.story`) reads the same joints for several
terms -- the key joints for the pose descriptor and the strikes, the limbs' joints for
the contacts -- and each gathering its own read the (F, J, 3) positions again.
:class:`JointTracks` is that one gathering: built once per character, then read by the
pose term, :func:`snapcore.select.limb_contacts.contacts_from_tracks` and the strikes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from snapcore.select.stance import joint_trajectories
from snapcore.select.strikes import rows_and_speeds

__all__ = ["JointTracks"]


@dataclass(frozen=True)
class JointTracks:
    """Smoothed trajectories of some joints of one character, with heights and speeds.

    Attributes
    ----------
    joints : ndarray of int, shape (A,)
        The joints, sorted increasing (gathering unsorted joints took 2.5 times as
        long); a column of the arrays below per joint.
    positions : ndarray of shape (F, A, 3)
        Savitzky-Golay smoothed positions (m), as
        :func:`snapcore.select.stance.joint_trajectories` returns them.
    rows : ndarray of shape (3, F, A)
        The same positions component-major (contiguous): ``rows[1]`` is the heights.
    speed : ndarray of shape (F, A)
        Speeds in metres per frame (:func:`snapcore.select.strikes.rows_and_speeds`).
    """

    joints: np.ndarray
    positions: np.ndarray
    rows: np.ndarray
    speed: np.ndarray

    @classmethod
    def of(cls, character, joints, *, fps: float, smooth_s: float) -> JointTracks:
        """The tracks of ``joints`` (any order, unique; at least two frames).

        Parameters
        ----------
        character : Character
        joints : array_like of int, shape (A,)
        fps : float
        smooth_s : float
            Savitzky-Golay window (s).
        """
        j = np.unique(np.asarray(joints, dtype=np.int64))
        x = joint_trajectories(character, j, fps=fps, smooth_s=smooth_s)  # (F, A, 3)
        rows, speed = rows_and_speeds(x)
        return cls(j, x, rows, speed)

    @property
    def height(self) -> np.ndarray:
        """World heights (m), shape (F, A): a view of ``rows[1]``."""
        return self.rows[1]

    def columns(self, joints) -> np.ndarray:
        """The columns of ``joints`` (each one of :attr:`joints`), shape (len(joints),)."""
        return np.searchsorted(self.joints, joints)
