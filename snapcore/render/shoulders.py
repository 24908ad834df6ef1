"""Shoulders that round over when the arms hang: the MakeHuman rig's skin weights and a
pose-driven drop of the top of the shoulder.

The rig is in an A-pose, its upper arms 48° below the horizontal (42° out from the
trunk's pelvis → neck line). Two things made the shoulder of a hanging arm a box with
a corner on top (issue 40: CMU 01_01 frame 197 and every other family, in a front
view):

- **Weights.** The top of the shoulder, up to 7 cm above the shoulder joint and 8 cm
  in towards the neck, is skinned 30-80% to the upper arm. When the arm turns down
  about its joint, a point above the joint turns with it by that share, so it moves
  *out*, not down: the top of the shoulder was carried out over the arm and stood
  level with (or above) the neck's side, ending in a corner where the arm's own side
  went down. :func:`shoulder_weights` splits the clavicle's and the upper arm's share
  of each vertex on the upper side of the joint by where the vertex lies along the
  arm's axis (a plane through the joint, square to the arm, blended over 7 cm): the
  skin above and inside the joint stays with the clavicle, the deltoid's outer side
  goes with the arm, and the turn between them is spread over the band.
- **Posture.** The A-pose's raised arm bunches the deltoid and trapezius up: the skin
  over the joint is 7 cm above it, where on a person whose arm hangs it is 4-5 cm.
  With a hanging arm the rig's top of the shoulder therefore stood 2-3 cm high, a
  shrug. :func:`shoulder_drops` moves the top of the shoulder down the trunk by up
  to :data:`DROP_M` (x the body's size) as the arm comes down from the rig's
  elevation to hanging (a corrective shape driven by the arm's elevation, as game
  rigs have), weighted by :func:`shoulder_masks`; at the rig's elevation and above
  it nothing moves.

Both act on the body's mesh and weights only; the skinning itself
(:func:`snapcore.motion.skinning.dq_skin`) is unchanged.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

__all__ = [
    "shoulder_weights",
    "shoulder_masks",
    "shoulder_drops",
    "rig_elevation",
    "DROP_M",
]

#: The split plane along the arm's axis, metres from the shoulder joint: the clavicle
#: takes all of a vertex's (clavicle + arm) weight before ``SPLIT_M[0]``, the arm all
#: of it after ``SPLIT_M[1]`` (a vertex above the joint is at about -0.04).
SPLIT_M = (-0.02, 0.05)
#: Within ``REACH_M[0]`` of the joint the split replaces the rig's weights; it fades
#: back to the rig's by ``REACH_M[1]`` (the chest, the back and the arm below keep
#: theirs).
REACH_M = (0.10, 0.16)
#: Above the arm's axis (towards the neck) by at least this, metres, a vertex is on the
#: shoulder's upper side; the armpit below keeps the rig's weights.
UPPER_FADE_M = 0.02
#: The top of the shoulder's drop with a hanging arm, metres on the rig (x the body's
#: girth scale on a skeleton): the rig's 7 cm of skin over the joint to a person's 4-5.
DROP_M = 0.025
#: The dropped region: within this of the rig's top of the shoulder (the point 7 cm
#: over the joint), metres, fading to nothing.
DROP_RADIUS_M = 0.08
#: Height of the top of the shoulder over the joint on the rig, metres.
TOP_M = 0.07
SIDES = ("Left", "Right")


def _smooth(x: np.ndarray) -> np.ndarray:
    """Smoothstep on [0, 1] (0 below, 1 above)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _arm(asset, side: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rig's shoulder joint (3,), the upper arm's unit axis (3,) and the unit normal
    to it in the frontal plane that points up (3,), rest pose."""
    b = asset.bone(f"{side}Arm")
    j = np.asarray(asset.heads[b], float)
    ax = np.asarray(asset.tails[b], float) - j
    ax /= np.linalg.norm(ax)
    n = np.cross([0.0, 0.0, 1.0], ax)
    n /= np.linalg.norm(n)
    return j, ax, n if n[1] > 0 else -n


def shoulder_weights(asset) -> sparse.csr_matrix:
    """The rig's skin weights (V, B) with each shoulder's clavicle/arm split redone.

    For a vertex on the upper side of the shoulder joint (above the arm's axis), its
    clavicle + upper-arm weight ``w`` is shared as ``w (1 - f)`` and ``w f``, with
    ``f`` a smoothstep of the vertex's position along the arm's axis from the joint
    over :data:`SPLIT_M`; blended with the rig's split by a smoothstep of the distance
    to the joint over :data:`REACH_M`. Other bones' weights and every row's sum are
    unchanged.

    Parameters
    ----------
    asset : HumanAsset
        The rig in its rest pose (metres).

    Returns
    -------
    scipy.sparse.csr_matrix of shape (V, B)
    """
    w = sparse.csr_matrix(asset.weights, copy=True)
    v = np.asarray(asset.vertices, float)
    for side in SIDES:
        sh, arm = asset.bone(f"{side}Shoulder"), asset.bone(f"{side}Arm")
        j, ax, n = _arm(asset, side)
        d = v - j
        col_s = np.asarray(w[:, sh].todense()).ravel()
        col_a = np.asarray(w[:, arm].todense()).ravel()
        total = col_s + col_a
        f = _smooth((d @ ax - SPLIT_M[0]) / (SPLIT_M[1] - SPLIT_M[0]))
        m = 1.0 - _smooth((np.linalg.norm(d, axis=1) - REACH_M[0]) / (REACH_M[1] - REACH_M[0]))
        m *= _smooth((d @ n) / UPPER_FADE_M + 0.5)
        m[total <= 1e-9] = 0.0
        rows = np.flatnonzero(m > 0)
        change = m[rows] * (total[rows] * f[rows] - col_a[rows])  # to the arm
        w = w + sparse.csr_matrix(
            (
                np.concatenate([change, -change]),
                (np.tile(rows, 2), np.repeat([arm, sh], rows.size)),
            ),
            shape=w.shape,
        )
    out = sparse.csr_matrix(w)
    out.eliminate_zeros()
    return out


def shoulder_masks(asset, points: np.ndarray, weights) -> np.ndarray:
    """How much of each side's shoulder drop each point takes: (P, 2), 0-1.

    A smoothstep bump of radius :data:`DROP_RADIUS_M` about the rig's top of the
    shoulder (:data:`TOP_M` over the joint), on the upper side of the arm's axis, times
    the point's clavicle + upper-arm weight (so the neck and the chest, which are
    skinned to the spine, stay).

    Parameters
    ----------
    asset : HumanAsset
    points : array of shape (P, 3)
        Rest-pose positions, metres.
    weights : sparse matrix of shape (P, B)
        The points' skin weights.
    """
    p = np.asarray(points, float)
    w = sparse.csr_matrix(weights)
    out = np.zeros((len(p), 2))
    for i, side in enumerate(SIDES):
        j, _, n = _arm(asset, side)
        top = j + np.array([0.0, TOP_M, 0.0])
        bump = 1.0 - _smooth(np.linalg.norm(p - top, axis=1) / DROP_RADIUS_M)
        upper = _smooth(((p - j) @ n) / (1.5 * UPPER_FADE_M) + 0.3)
        share = np.asarray(
            w[:, [asset.bone(f"{side}Shoulder"), asset.bone(f"{side}Arm")]].sum(axis=1)
        ).ravel()
        out[:, i] = bump * upper * np.clip(share, 0.0, 1.0)
    return out


def rig_elevation(asset) -> float:
    """The rig's upper arms' angle from the trunk's down direction (pelvis → neck
    reversed), degrees, both sides' mean (42° for the MakeHuman A-pose)."""
    down = asset.heads[asset.bone("Hips")] - asset.heads[asset.bone("Neck")]
    down = down / np.linalg.norm(down)
    return float(
        np.mean([np.degrees(np.arccos(np.clip(_arm(asset, s)[1] @ down, -1, 1))) for s in SIDES])
    )


def shoulder_drops(
    shoulders: np.ndarray, elbows: np.ndarray, up: np.ndarray, rig_deg: float, scale: float
) -> np.ndarray:
    """Each side's drop of the top of the shoulder, per frame: (F, 2, 3), metres.

    ``DROP_M x scale`` down the trunk, times how far the upper arm has come down from
    the rig's elevation towards hanging: ``clip((rig - e) / rig, 0, 1)`` for the arm's
    angle ``e`` from the trunk's down direction.

    Parameters
    ----------
    shoulders, elbows : arrays of shape (F, 2, 3)
        The skeleton's shoulder and elbow joints, left then right, metres.
    up : array of shape (F, 3)
        The trunk's up direction (pelvis → neck base).
    rig_deg : float
        :func:`rig_elevation`.
    scale : float
        The body's girth scale over the rig's.
    """
    up = up / np.maximum(np.linalg.norm(up, axis=-1, keepdims=True), 1e-12)
    arm = elbows - shoulders
    arm = arm / np.maximum(np.linalg.norm(arm, axis=-1, keepdims=True), 1e-12)
    e = np.degrees(np.arccos(np.clip(-np.einsum("fsi,fi->fs", arm, up), -1.0, 1.0)))
    drive = np.clip((rig_deg - e) / rig_deg, 0.0, 1.0)  # (F, 2)
    return -(DROP_M * scale) * drive[..., None] * up[:, None, :]
