"""Linear blend skinning and vertex normals, vectorised over frames.

The kernel both skinned bodies use: a glTF character's own mesh (its skins' joints and
inverse bind matrices) and the human body retargeted onto a BVH skeleton
(:mod:`snapcore.render.human`). It lives in the motion layer because it is kinematics —
pure arrays, no rendering — and the glTF loader needs it to find where a character's
feet meet the floor.

Linear blend skinning (Magnenat-Thalmann et al. 1988; glTF 2.0 §3.7.3): vertex ``v``
with weights ``w_vk`` over bones ``k`` moves to ``x_v = Σ_k w_vk M_k [r_v; 1]``, where
``M_k`` (3 × 4) is bone ``k``'s current world transform times its inverse bind matrix.
Written as blended matrices, ``B_v = Σ_k w_vk M_k`` is one sparse product ``W M`` with
``W`` the (V, K) weight matrix, for a chunk of frames at a time (no Python loop over
frames; chunks only bound the memory of the (V, F, 12) intermediate).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from snapcore.errors import SceneError

if TYPE_CHECKING:  # scipy.sparse is imported where skinning runs
    from scipy import sparse

    from snapcore.motion.dq_kernel import DQPlan

__all__ = [
    "SkinnedMesh",
    "weight_matrix",
    "blend_skin",
    "dq_skin",
    "vertex_normals",
    "face_incidence",
    "CHUNK_BYTES",
]

#: Memory budget (bytes) for one chunk of blended matrices (V × frames × 12 float64).
CHUNK_BYTES = 48 * 2**20


def weight_matrix(
    bones: np.ndarray, weights: np.ndarray, n_bones: int, *, normalize: bool = True
) -> sparse.csr_matrix:
    """Sparse (V, K) skin weights from per-vertex bone indices and weights.

    Parameters
    ----------
    bones : ndarray of int, shape (V, n)
        Bone index of each of a vertex's ``n`` influences.
    weights : ndarray of float, shape (V, n)
        Their weights; zero weights are dropped (their index is then irrelevant).
    n_bones : int
        K, the number of bones.
    normalize : bool
        Rescale each vertex's weights to sum to 1 (exporters round them); a vertex
        with no weight at all keeps none and stays at the origin of the skinning.

    Returns
    -------
    scipy.sparse.csr_matrix of shape (V, K)
    """
    import scipy.sparse as sparse  # only when skinning: a light `import snapcore.motion`

    bones = np.asarray(bones, dtype=np.int64)
    w = np.asarray(weights, dtype=np.float64)
    if bones.shape != w.shape or bones.ndim != 2:
        raise SceneError(f"bones {bones.shape} and weights {w.shape} must both be (V, n)")
    keep = w != 0
    if np.any(bones[keep] < 0) or np.any(bones[keep] >= n_bones):
        raise SceneError(f"bone indices must lie in 0..{n_bones - 1}")
    rows = np.broadcast_to(np.arange(bones.shape[0])[:, None], bones.shape)[keep]
    m = sparse.csr_matrix((w[keep], (rows, bones[keep])), shape=(bones.shape[0], n_bones))
    m.sum_duplicates()
    if normalize:
        total = np.asarray(m.sum(axis=1)).ravel()
        scale = np.divide(1.0, total, out=np.zeros_like(total), where=total > 0)
        m = sparse.diags(scale) @ m
    return m.tocsr()


def blend_skin(
    rest: np.ndarray, weights: sparse.csr_matrix, matrices: np.ndarray, *, dtype=np.float64
) -> np.ndarray:
    """Linear blend skinning of ``rest`` vertices by bone ``matrices``.

    Parameters
    ----------
    rest : ndarray of shape (V, 3)
        Vertices in the bind pose (the space the inverse bind matrices map from).
    weights : sparse matrix of shape (V, K)
        :func:`weight_matrix`.
    matrices : ndarray of shape (K, 3, 4) or (F, K, 3, 4)
        Each bone's skinning transform (world transform × inverse bind matrix), as the
        top three rows of the 4 × 4 matrix.
    dtype : numpy dtype
        Arithmetic precision: float64 (default), or float32 for drawing (half the
        memory traffic; ~1e-7 relative error, far below a pixel).

    Returns
    -------
    ndarray of shape (V, 3) or (F, V, 3)
        Skinned vertices, in the units and frame of the matrices' output.
    """
    import scipy.sparse as sparse  # only when skinning: a light `import snapcore.motion`

    m = np.asarray(matrices, dtype=dtype)
    single = m.ndim == 3
    if single:
        m = m[None]
    f, k = m.shape[:2]
    if m.shape[2:] != (3, 4) or weights.shape[1] != k:
        raise SceneError(f"matrices {m.shape} do not fit weights {weights.shape}")
    v = weights.shape[0]
    rest = np.asarray(rest, dtype=dtype)
    # The sparse product: SciPy's CSR times a dense block beat the dense (V, K) BLAS
    # product at every size measured (1-60 frames, 18-60 bones, 1-4 bones a vertex:
    # 1.1-9x; BrainStem's 60 sampled frames 49 -> 23 ms, its whole load 0.70 -> 0.62 CPU-s).
    w = weights.astype(dtype) if sparse.issparse(weights) else np.asarray(weights, dtype)
    out = np.empty((f, v, 3), dtype=dtype)
    step = max(1, int(CHUNK_BYTES // max(1, v * 12 * np.dtype(dtype).itemsize)))
    x, y, z = (rest[:, i, None, None] for i in range(3))
    for a in range(0, f, step):  # chunks bound memory; each is one matrix product
        b = min(f, a + step)
        # columns ordered (matrix column j, frame, row i): each column j of the blended
        # matrices is then one contiguous (V, chunk, 3) block for the multiply-adds
        flat = m[a:b].transpose(1, 3, 0, 2).reshape(k, -1)  # (K, 4 * chunk * 3)
        bl = np.asarray(w @ flat).reshape(v, 4, b - a, 3)
        acc = bl[:, 0] * x
        acc += bl[:, 1] * y
        acc += bl[:, 2] * z
        acc += bl[:, 3]
        out[a:b] = acc.transpose(1, 0, 2)
    return out[0] if single else out


def dq_skin(
    rest: np.ndarray,
    weights: sparse.csr_matrix,
    matrices: np.ndarray,
    centres: np.ndarray,
    *,
    linear: np.ndarray | None = None,
    dtype=np.float64,
    plan: DQPlan | None = None,
) -> np.ndarray:
    """Dual-quaternion skinning of ``rest`` vertices by bone ``matrices`` that may scale.

    Linear blending averages the bones' transforms: where two bones meet at a deep
    bend (an elbow folded to 20°) or turn far apart, the skin between takes the chord
    of the arc and collapses or comes to a corner. Blending the bones' rigid motions as
    unit dual quaternions (Kavan et al. 2008) keeps it on the arc. A bone's matrix
    ``M x = A x + t`` may also scale (a bone stretched to the skeleton's length, a body
    broadened): its rigid part is ``T x = R (x - c) + M c``, with ``R`` the rotation of
    the polar decomposition ``A = R S`` and ``c`` the bone's centre (where ``T`` and
    ``M`` agree), and the rest, ``(M - T) x``, is blended linearly:
    ``x' = DQB(T)(x) + Σ w (M - T) x``. That is ``M x`` for a vertex on one bone, and
    linear blend skinning where the bones' rotations agree. Each vertex's quaternions
    are put in the hemisphere of its heaviest bone's before blending.

    Parameters
    ----------
    rest : ndarray of shape (V, 3)
    weights : sparse matrix of shape (V, K)
        :func:`weight_matrix`.
    matrices : ndarray of shape (F, K, 3, 4)
        Each bone's skinning transform, as for :func:`blend_skin`.
    centres : ndarray of shape (K, 3)
        Each bone's centre in the rest pose (its head: where it meets its parent).
    linear : ndarray of shape (V,), optional
        Per vertex, the share (0-1) of linear blend skinning mixed in.
    dtype : numpy dtype
        Precision of the per-vertex arithmetic and the result: float32 for drawing
        (errors ~1e-6 m on a body), float64 (default) elsewhere.
    plan : DQPlan, optional
        :func:`snapcore.motion.dq_kernel.dq_plan` of ``rest``, ``weights`` and
        ``linear`` (pass it when skinning the same mesh often: ``rest``, ``linear`` and
        ``dtype`` are then the plan's).

    Returns
    -------
    ndarray of shape (F, V, 3)

    Notes
    -----
    Computed as sparse products over pairs of bones (exact algebra, see
    :mod:`snapcore.motion.dq_kernel`): no per-vertex dual quaternion is formed.
    """
    from snapcore.motion.dq_kernel import dq_plan, dq_skin_planned

    m = np.asarray(matrices, dtype=np.float64)
    k = m.shape[1] if m.ndim == 4 else -1
    if m.ndim != 4 or m.shape[2:] != (3, 4) or weights.shape[1] != k:
        raise SceneError(f"matrices {m.shape} do not fit weights {weights.shape}")
    if plan is None:
        plan = dq_plan(rest, weights, linear, dtype=dtype)
    elif (plan.n_vertices, plan.n_bones) != weights.shape:
        raise SceneError(
            f"a plan for {plan.n_vertices} x {plan.n_bones} weights, not {weights.shape}"
        )
    return dq_skin_planned(plan, m, centres).astype(dtype, copy=False)


def face_incidence(faces: np.ndarray, n_vertices: int) -> sparse.csr_matrix:
    """Sparse (V, M) matrix with a 1 where vertex ``v`` is a corner of face ``m``."""
    import scipy.sparse as sparse  # only when skinning: a light `import snapcore.motion`

    faces = np.asarray(faces, dtype=np.int64)
    m = faces.shape[0]
    return sparse.csr_matrix(
        (np.ones(faces.size), (faces.ravel(), np.repeat(np.arange(m), 3))), shape=(n_vertices, m)
    )


def vertex_normals(
    vertices: np.ndarray, faces: np.ndarray, incidence: sparse.csr_matrix | None = None
) -> np.ndarray:
    """Area-weighted unit vertex normals of a posed mesh, for one or many frames.

    Parameters
    ----------
    vertices : ndarray of shape (V, 3) or (F, V, 3)
    faces : ndarray of int, shape (M, 3)
        Counter-clockwise seen from outside.
    incidence : sparse matrix of shape (V, M), optional
        :func:`face_incidence` of ``faces`` (pass it when posing often).

    Returns
    -------
    ndarray, the shape and float type of ``vertices``
        Unit normals; a vertex on no face (or only degenerate ones) gets ``(0, 1, 0)``.
    """
    x = np.asarray(vertices)
    if x.dtype not in (np.float32, np.float64):
        x = x.astype(np.float64)
    single = x.ndim == 2
    if single:
        x = x[None]
    f, v = x.shape[:2]
    if incidence is None:
        incidence = face_incidence(faces, v)
    # Faces' area-weighted normals in a (M, 3, F) layout: corners gathered as rows of a
    # (V, 3, F) copy, the cross product over contiguous (M, F) planes, and the layout
    # the incidence product takes without a transpose (2.6x faster than gathering
    # (F, M, 3, 3) and np.cross; the same operations in the same order, so the same bits)
    xt = np.ascontiguousarray(x.transpose(1, 2, 0))
    p0, p1, p2 = (xt[faces[:, k]] for k in range(3))
    a, b = p1 - p0, p2 - p0
    fn = np.empty_like(a)
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        fn[:, i] = a[:, j] * b[:, k] - a[:, k] * b[:, j]
    n = (incidence @ fn.reshape(fn.shape[0], -1)).reshape(v, 3, f)
    n = np.ascontiguousarray(n.transpose(2, 0, 1))
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    up = np.broadcast_to(np.array([0.0, 1.0, 0.0], dtype=n.dtype), n.shape)
    n = np.where(norm > 1e-20, n / np.where(norm > 1e-20, norm, 1.0), up)
    return n[0] if single else n


@dataclass(frozen=True, eq=False)
class SkinnedMesh:
    """A character's own skinned mesh, posed by its joints (``Character.mesh``).

    What :func:`snapcore.motion.gltf.read_gltf` builds from a glTF file's skins; the
    renderer draws it as the character's body. Posing is :func:`blend_skin` with
    ``M_k = G_joint(k) · IBM_k``, ``G`` the joint's world transform rebuilt from the
    character's ``positions``/``rotations``/``scale``, so the mesh follows a character
    moved, turned, rescaled or cut to a frame range. Frozen: characters cut from one
    another share it.

    Attributes
    ----------
    rest : ndarray of shape (V, 3)
        Bind-pose vertices (file units, the space inverse bind matrices map from).
    faces : ndarray of int, shape (M, 3)
    weights : scipy.sparse.csr_matrix of shape (V, K)
        Skin weights over K slots, rows summing to 1.
    slot_joint : ndarray of int, shape (K,)
        Character joint index of each slot.
    inverse_bind : ndarray of shape (K, 4, 4)
        Inverse bind matrix of each slot.
    joint_scale : ndarray of shape (J,)
        Each joint's world scale in the file (the rotations are pure; glTF nodes may
        scale), a constant per joint.
    face_rgb : ndarray of shape (M, 3), optional
        Each face's own colour from its material (sRGB 0-1; NaN where the material
        gives none), None when no material has a colour.
    """

    rest: np.ndarray
    faces: np.ndarray
    weights: sparse.csr_matrix
    slot_joint: np.ndarray
    inverse_bind: np.ndarray
    joint_scale: np.ndarray
    face_rgb: np.ndarray | None = None

    @property
    def n_vertices(self) -> int:
        return int(self.rest.shape[0])

    def matrices(self, character, frames) -> np.ndarray:
        """Skinning matrices of every slot at ``frames``: (F, K, 3, 4) (or (K, 3, 4))."""
        rot = character.rotations[frames][..., self.slot_joint, :, :]
        pos = character.positions[frames][..., self.slot_joint, :]
        s = (character.scale * self.joint_scale[self.slot_joint])[:, None, None]
        g = np.concatenate([rot * s, pos[..., None]], axis=-1)  # (..., K, 3, 4)
        return g[..., :3] @ self.inverse_bind[:, :3, :] + np.concatenate(
            [np.zeros(g.shape[:-1] + (3,)), g[..., 3:]], axis=-1
        )

    def vertices(self, character, frames) -> np.ndarray:
        """World vertices (metres) at ``frames``: (V, 3) for one frame, (F, V, 3) for many."""
        return blend_skin(self.rest, self.weights, self.matrices(character, frames))
