"""Which way characters face, and which of two opposite views sees their front.

Projected areas cannot tell a view ``v`` from ``-v`` (METHOD.md §2), so the view
selector asks this module. A character's facing at a frame is the horizontal normal of
its left-right axes: ``(left - right) × up`` for the hip joints and for the upper-arm
(shoulder) joints, each normalised, summed, normalised. Which joints those are comes
from the anatomy table (:func:`snapcore.motion.anatomy.left_right_pairs`).

The front/back rule (:func:`choose_side`): a camera above the floor for views more than
10° off the horizon, else the side the characters face, else (profile views) the side
that shows their right so they face screen-right. It is deterministic and invariant
under rotating the scene about the vertical axis; see its docstring for the details.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from snapcore.motion.anatomy import left_right_pairs

__all__ = [
    "FACING_TIE",
    "ABOVE_DEG",
    "MIN_AXIS_M",
    "character_facing",
    "scene_facing",
    "choose_side",
    "SIDE_RULES",
]

#: Dot products below this (in absolute value) are ties: a view within ~6° of
#: perpendicular to a consistent facing, or characters without a consistent facing
#: (``|F| < 0.1``: turning on the spot, two people facing each other).
FACING_TIE = 0.1
#: Most frames :func:`scene_facing` averages over (evenly spaced).
MAX_FACING_FRAMES = 256
#: Views steeper than this many degrees from the horizon always put the camera above
#: the floor (before the facing is asked).
ABOVE_DEG = 10.0
#: Left-right joint pairs closer than this horizontally (m) give no facing at a frame
#: (the character lies or bends so the axis is near vertical).
MIN_AXIS_M = 0.02
#: The rules :func:`choose_side` applies, in order.
SIDE_RULES = ("above", "front", "right side", "fallback")


def character_facing(positions, names, parents) -> np.ndarray:
    """Horizontal facing of one character at every frame.

    Parameters
    ----------
    positions : ndarray of shape (F, J, 3)
        World joint positions, metres, Y up.
    names : sequence of str, length J
    parents : array of int, shape (J,)

    Returns
    -------
    ndarray of shape (F, 3)
        Unit horizontal vectors (``y = 0``); zero rows where no facing is defined (no
        named hips or shoulders (:func:`~snapcore.motion.anatomy.left_right_pairs`), or their axes shorter than :data:`MIN_AXIS_M`).

    Notes
    -----
    For a left-right axis ``h = x_left - x_right`` the forward direction is
    ``h × ŷ = (-h_z, 0, h_x)``: a character standing upright facing +Z has its left
    hip at +X, giving +Z.
    """
    x = np.asarray(positions, dtype=float)
    total = np.zeros((x.shape[0], 3))
    for pair in _left_right(tuple(names), tuple(np.asarray(parents).tolist())):
        if pair is None:
            continue
        left, right = pair
        h = x[:, left] - x[:, right]
        fwd = np.stack([-h[:, 2], np.zeros(len(h)), h[:, 0]], axis=1)
        n = np.linalg.norm(fwd, axis=1, keepdims=True)
        ok = n[:, 0] >= MIN_AXIS_M
        total[ok] += fwd[ok] / n[ok]
    n = np.linalg.norm(total, axis=1, keepdims=True)
    ok = n[:, 0] > 1e-12
    total[ok] /= n[ok]
    total[~ok] = 0.0
    return total


@lru_cache(maxsize=64)
def _left_right(names: tuple, parents: tuple) -> tuple:
    """The values of :func:`left_right_pairs`, once per skeleton: it reads every joint
    name with regular expressions (about 1 ms for the salsa pair's 2 x 57 joints, at
    every call of :func:`scene_facing`)."""
    return tuple(left_right_pairs(names, np.asarray(parents, dtype=int)).values())


def scene_facing(scene, *, frames=None) -> np.ndarray:
    """Mean facing of all characters over a range of frames.

    Parameters
    ----------
    scene : Scene
    frames : tuple of int, optional
        ``(start, stop)`` internal frames; default all.

    Returns
    -------
    ndarray of shape (3,)
        Horizontal; its length in [0, 1] says how consistent the facing is (1: every
        character faces the same way in every frame; ~0: turning, or facing each other).
        Frames without a defined facing count as zero. Long ranges are sampled at
        :data:`MAX_FACING_FRAMES` evenly spaced frames (a mean needs no more).
    """
    start, stop = (0, scene.n_frames) if frames is None else frames
    step = max(1, -(-(stop - start) // MAX_FACING_FRAMES))  # ceil: evenly spaced frames
    acc = np.zeros(3)
    for c in scene.characters:
        acc += character_facing(c.positions[start:stop:step], c.joint_names, c.parents).mean(axis=0)
    return acc / len(scene.characters)


def choose_side(
    view, facing, *, tie: float = FACING_TIE, above_deg: float = ABOVE_DEG
) -> tuple[np.ndarray, str]:
    """Pick ``view`` or ``-view`` (equal projected areas) by the floor and the facing.

    Parameters
    ----------
    view : array_like of shape (3,)
        Unit view (scene centre → camera).
    facing : array_like of shape (3,)
        Mean horizontal facing (:func:`scene_facing`), length in [0, 1].
    tie : float
        Tolerance of the facing ties (:data:`FACING_TIE`).
    above_deg : float
        Views steeper than this (degrees from the horizon) put the camera above the
        floor whatever the facing (:data:`ABOVE_DEG`).

    Returns
    -------
    view : ndarray of shape (3,)
    rule : str
        Which rule decided, one of :data:`SIDE_RULES`.

    Notes
    -----
    The first rule that applies decides:

    1. ``above``: when ``|v_y| ≥ sin(above_deg)`` the camera is above the horizon
       (``v_y > 0``): a camera under the floor sees the floor's underside, whatever it
       would see of the characters.
    2. ``front``: the camera on the side the characters face, ``v·F > 0``, when
       ``|v·F| ≥ tie``.
    3. ``right side`` (profile views, ``v ⟂ F``): when ``|F| ≥ tie`` and
       ``|v·R| ≥ tie`` for the characters' right ``R = F̂ × ŷ``, the camera sees their
       right side, so they face screen-right (the reading direction, as in most
       profile illustrations of walks and runs).
    4. ``fallback``: the first non-zero of ``(v_y, v·F, v·R, v_z, v_x)`` positive
       (deterministic; only the last two, reached by measure-zero inputs, depend on
       the world axes).

    Rules 1-3 depend only on dot products with the facing and the vertical, so rotating
    the scene about +Y rotates the chosen view with it.
    """
    v = np.asarray(view, dtype=float)
    f = np.asarray(facing, dtype=float)
    if abs(v[1]) >= np.sin(np.radians(above_deg)):
        return (v if v[1] > 0 else -v), "above"
    d_front = float(v @ f)
    if abs(d_front) >= tie:
        return (v if d_front > 0 else -v), "front"
    nf = float(np.linalg.norm(f))
    right = np.cross(f / nf, [0.0, 1.0, 0.0]) if nf > 0 else np.zeros(3)
    d_right = float(v @ right)
    if nf >= tie and abs(d_right) >= tie:
        return (v if d_right > 0 else -v), "right side"
    for c in (v[1], d_front, d_right, v[2], v[0]):
        if c != 0.0:
            return (v if c > 0 else -v), "fallback"
    return v, "fallback"
