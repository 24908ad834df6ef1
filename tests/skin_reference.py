"""Straightforward float64 skinning, the reference the fast kernels are tested against.

Written for clarity, not speed: every vertex's dual quaternion is formed, blended and
normalised as Kavan et al. (2008) describe, and linear blend skinning is a dense
weighted sum of matrices. (This is the suite's dual-quaternion skinning as it was
before the sparse kernel of issue 41.)
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def lbs_reference(rest, weights, matrices):
    """Linear blend skinning: (V, 3), (V, K), (F, K, 3, 4) -> (F, V, 3)."""
    w = np.asarray(weights.toarray() if hasattr(weights, "toarray") else weights, float)
    m = np.asarray(matrices, float)
    blended = np.einsum("vk,fkij->fvij", w, m)
    return np.einsum("fvij,vj->fvi", blended[..., :3], rest) + blended[..., 3]


def dq_reference(rest, weights, matrices, centres, linear=None):
    """Dual-quaternion skinning with scaling bones, as documented for
    :func:`snapcore.motion.skinning.dq_skin`: (F, V, 3), float64."""
    m = np.asarray(matrices, dtype=np.float64)
    f, k = m.shape[:2]
    c = np.asarray(centres, dtype=np.float64)
    rest64 = np.asarray(rest, dtype=np.float64)
    u, _, vt = np.linalg.svd(m[..., :3])
    flip = np.linalg.det(u @ vt) < 0
    u[flip, :, -1] *= -1
    r = u @ vt  # (F, K, 3, 3)
    t = np.einsum("fkij,kj->fki", m[..., :3] - r, c) + m[..., 3]
    lin = m - np.concatenate([r, t[..., None]], axis=-1)
    out = lbs_reference(rest64, weights, lin)
    q = Rotation.from_matrix(r.reshape(-1, 3, 3)).as_quat()
    qr = q[:, [3, 0, 1, 2]].reshape(f, k, 4)
    w, v = qr[..., :1], qr[..., 1:]
    qd = 0.5 * np.concatenate(
        [-np.sum(t * v, axis=-1, keepdims=True), w * t + np.cross(t, v)], axis=-1
    )
    dq = np.concatenate([qr, qd], axis=-1)  # (F, K, 8)
    wd = weights.toarray() if hasattr(weights, "toarray") else np.asarray(weights)
    pivot = np.argmax(wd, axis=1)
    blend = np.zeros((f, wd.shape[0], 8))
    for p in np.unique(pivot):
        rows = np.flatnonzero(pivot == p)
        sign = np.where(np.sum(qr * qr[:, p, None], axis=-1) < 0, -1.0, 1.0)
        blend[:, rows] = np.einsum("vk,fkd->fvd", wd[rows], dq * sign[..., None])
    n = np.linalg.norm(blend[..., :4], axis=-1, keepdims=True)
    blend /= np.where(n > 1e-12, n, 1.0)
    w, v = blend[..., :1], blend[..., 1:4]
    wd_, vd = blend[..., 4:5], blend[..., 5:]
    x = np.broadcast_to(rest64, out.shape)
    out += x + 2.0 * np.cross(v, np.cross(v, x) + w * x)
    out += 2.0 * (w * vd - wd_ * v + np.cross(v, vd))
    if linear is not None and np.any(linear > 0):
        mix = np.asarray(linear, dtype=np.float64)[:, None]
        out += mix * (lbs_reference(rest64, weights, m) - out)
    return out
