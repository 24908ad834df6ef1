"""Baseline pose selectors: stretch, fastest, middle, random, salient.

Each is a pure function of a scene returning a per-frame score ``(F,)`` (higher is
better) or the frames themselves; :mod:`snapcore.select.pose_methods` turns them into the
same :class:`~snapcore.select.pose_selection.PoseSelection` as the paper's pose entropy and the story
selector, so they can be compared on annotated key moments (``snapshot keymoments``).

- ``stretch``: the most stretched pose, the mean distance of the joints from their
  centroid (over the stature), summed over characters.
- ``fastest``: the mean joint speed (statures per second, smoothed trajectories).
- ``middle``: the middle frame (then the frames at 1/4 and 3/4 of the clip).
- ``random``: uniformly random frames from a seeded generator.
- ``salient``: error-driven keyframes in the manner of *Salient Poses* (Roberts et al.
  2019) and the key-frame extraction the paper argues against (§2.1): the k interior
  frames which, with the first and last frame, reconstruct the motion best by linear
  interpolation (least squares over all joints), found exactly by dynamic programming.
"""

from __future__ import annotations

import numpy as np

from snapcore.motion.anatomy import stature_of
from snapcore.select.signals import smooth_positions

__all__ = [
    "stretch_score",
    "speed_score",
    "middle_frames",
    "random_frames",
    "interpolation_error_table",
    "salient_frames",
    "SALIENT_MAX_CANDIDATES",
]

#: Candidate key frames of :func:`salient_frames` at most (evenly spaced): the exact
#: dynamic programme is O(k C^2); 400 candidates keep a 3,000-frame clip under a second.
SALIENT_MAX_CANDIDATES = 400


def _visible(character) -> np.ndarray:
    """Joints that belong to the body (not hidden helper joints such as a floor root)."""
    roles = character.skeleton.roles
    keep = np.array([r != "hidden" for r in roles])
    return np.flatnonzero(keep) if keep.any() else np.arange(character.n_joints)


def stretch_score(scene) -> np.ndarray:
    """Mean joint distance from the joints' centroid over the stature, shape (F,).

    Summed over characters; dimensionless, so invariant to unit, yaw and translation.
    """
    out = np.zeros(scene.n_frames)
    for c in scene.characters:
        x = c.positions[:, _visible(c)]
        d = np.sqrt(np.square(x - x.mean(axis=1, keepdims=True)).sum(-1))
        out += d.mean(axis=1) / stature_of(c)
    return out


def speed_score(scene, *, smooth_s: float = 0.1) -> np.ndarray:
    """Mean joint speed in statures per second (smoothed trajectories), shape (F,)."""
    out = np.zeros(scene.n_frames)
    if scene.n_frames < 2:
        return out
    for c in scene.characters:
        x = smooth_positions(c.positions[:, _visible(c)], fps=scene.fps, smooth_s=smooth_s)
        v = np.sqrt(np.square(np.gradient(x, axis=0)).sum(-1)) * scene.fps
        out += v.mean(axis=1) / stature_of(c)
    return out


def middle_frames(n_frames: int, k: int) -> list[int]:
    """The middle frame, then the frames at 1/4 and 3/4, then 1/8, 3/8... (k of them)."""
    out: list[int] = []
    denom = 2
    while len(out) < min(k, n_frames):
        for num in range(1, denom, 2):
            f = int((n_frames - 1) * num // denom)
            if f not in out:
                out.append(f)
            if len(out) == k:
                break
        denom *= 2
        if denom > 4 * n_frames:
            break
    return out


def random_frames(n_frames: int, k: int, *, seed: int = 0, min_separation: int = 1) -> list[int]:
    """``k`` distinct frames drawn uniformly (seeded), each ``min_separation`` apart.

    The order of a random permutation, keeping a frame when it is far enough from
    those kept: the first pick is uniform over the clip.
    """
    rng = np.random.default_rng(seed)
    out: list[int] = []
    sep = max(int(min_separation), 1)
    for f in rng.permutation(n_frames).tolist():
        if all(abs(f - g) >= sep for g in out):
            out.append(f)
            if len(out) == k:
                break
    return out


def _trajectories(scene) -> np.ndarray:
    """All characters' visible joints, flattened per frame, over the stature: (F, D)."""
    parts = [
        c.positions[:, _visible(c)].reshape(scene.n_frames, -1) / stature_of(c)
        for c in scene.characters
    ]
    return np.concatenate(parts, axis=1)


def interpolation_error_table(x: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """Squared error of linear interpolation between every pair of candidate keys.

    Parameters
    ----------
    x : ndarray of shape (F, D)
        The motion, one row per frame.
    keys : ndarray of int, shape (C,)
        Increasing candidate key frames.

    Returns
    -------
    ndarray of shape (C, C)
        ``E[a, b] = sum_{i=keys[a]}^{keys[b]} |x_i - lerp(x_keys[a], x_keys[b])(i)|^2``
        for ``a < b`` (inf elsewhere).

    Notes
    -----
    With ``t = (i - s) / (e - s)`` the error expands into sums of ``|x_i|^2``,
    ``x_i`` and ``i x_i`` over the segment (prefix sums) and closed forms of
    ``sum (1-t)^2``, ``sum t (1-t)``, ``sum t^2``: each entry costs O(D), no loop over
    frames.
    """
    x = np.asarray(x, dtype=float)
    keys = np.asarray(keys, dtype=np.int64)
    i = np.arange(x.shape[0], dtype=float)
    zero = np.zeros((1, x.shape[1]))
    c0 = np.r_[0.0, np.cumsum(np.square(x).sum(1))]  # prefix sums of |x_i|^2
    c1 = np.vstack([zero, np.cumsum(x, axis=0)])  # of x_i
    c2 = np.vstack([zero, np.cumsum(x * i[:, None], axis=0)])  # of i x_i
    xk = x[keys]
    s = keys[:, None].astype(float)  # segment start (row a)
    e = keys[None, :].astype(float)  # segment end (column b)
    L = np.maximum(e - s, 1.0)
    n = e - s + 1.0
    sq = c0[keys + 1][None, :] - c0[keys][:, None]
    # sums over the segment of x_i . x_s and x_i . x_e (x_s = xk[a], x_e = xk[b])
    a1 = (c1[keys + 1] @ xk.T).T - np.einsum("ad,ad->a", c1[keys], xk)[:, None]
    a2 = np.einsum("bd,bd->b", c1[keys + 1], xk)[None, :] - c1[keys] @ xk.T
    # the same with i x_i
    b1 = (c2[keys + 1] @ xk.T).T - np.einsum("ad,ad->a", c2[keys], xk)[:, None]
    b2 = np.einsum("bd,bd->b", c2[keys + 1], xk)[None, :] - c2[keys] @ xk.T
    # t_i = (i - s) / L: sum t x_i = (sum i x_i - s sum x_i) / L
    tx_s = (b1 - s * a1) / L
    tx_e = (b2 - s * a2) / L
    cross = (a1 - tx_s) + tx_e  # sum x_i . ((1 - t) x_s + t x_e)
    su = L * (L + 1) / 2  # sum of u = i - s over 0..L
    suu = L * (L + 1) * (2 * L + 1) / 6
    st, stt = su / L, suu / L**2  # sum t, sum t^2
    ns = np.square(xk).sum(1)
    quad = (
        (n - 2 * st + stt) * ns[:, None] + 2 * (st - stt) * (xk @ xk.T) + stt * ns[None, :]
    )  # sum |(1 - t) x_s + t x_e|^2
    err = np.maximum(sq - 2 * cross + quad, 0.0)
    err[~(e > s)] = np.inf
    return err


def salient_frames(scene, k: int) -> list[int]:
    """Interior key frames that, with the end frames, best reconstruct the motion.

    Parameters
    ----------
    scene : Scene
    k : int

    Returns
    -------
    list of int
        The first is the best single key frame (k = 1 optimum); the others complete
        the k-key optimum, ordered by how much error each saves (removing it costs
        most first). Candidates are every frame up to :data:`SALIENT_MAX_CANDIDATES`,
        else evenly spaced ones.

    Notes
    -----
    Dynamic programme over candidates ``c_0 = 0 < ... < c_{C-1} = F-1``:
    ``D[m, b] = min_a D[m-1, a] + E[a, b]`` with ``E`` from
    :func:`interpolation_error_table`; the optimum for m interior keys is
    ``D[m+1, C-1]`` traced back.
    """
    n_f = scene.n_frames
    if n_f < 3:
        return [0][:k]
    cand = np.unique(
        np.linspace(0, n_f - 1, min(n_f, SALIENT_MAX_CANDIDATES)).round().astype(np.int64)
    )
    err = interpolation_error_table(_trajectories(scene), cand)
    n_c = cand.size

    def optimum(m: int) -> list[int]:
        cost = np.full(n_c, np.inf)
        cost[0] = 0.0
        back = []
        for _ in range(m + 1):
            tot = cost[:, None] + err  # (a, b)
            arg = np.argmin(tot, axis=0)
            cost = tot[arg, np.arange(n_c)]
            back.append(arg)
        path, b = [], n_c - 1
        for arg in reversed(back):
            b = int(arg[b])
            path.append(b)
        inner = sorted(p for p in path if 0 < p < n_c - 1)
        return inner

    m = min(k, n_c - 2)
    if m < 1:
        return [int(n_f // 2)][:k]
    best1 = optimum(1)
    keys = optimum(m)

    def total(ks) -> float:
        ks = [0, *ks, n_c - 1]
        return float(sum(err[a, b] for a, b in zip(ks[:-1], ks[1:])))

    saved = [total([q for q in keys if q != p]) for p in keys]
    ranked = [keys[i] for i in np.argsort(saved)[::-1]]
    order = best1 + [p for p in ranked if p not in best1]
    return [int(cand[p]) for p in order[:k]]
