"""The sparse dual-quaternion skinning kernel (issue 41) against a straightforward float64
reference (tests/skin_reference.py: every vertex's dual quaternion formed, blended and
normalised as Kavan et al. 2008 describe).

Tolerances: the kernel's algebra is exact (pairs of bones' bilinear forms instead of
per-vertex dual quaternions), so in float64 it agrees to rounding (1e-9 m here, 1e-15
measured). In float32, what drawing uses, a coordinate of a metre-sized body carries
~6e-8 m of rounding per operation; 1e-5 m bounds what a few dozen operations do, a
hundredth of the 1e-3 m a pixel of a 1280×720 picture of two dancers covers.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import sparse
from scipy.spatial.transform import Rotation
from skin_reference import dq_reference

from snapcore.motion.dq_kernel import dq_plan, dq_skin_planned, polar_rotation
from snapcore.motion.skinning import dq_skin
from snapcore.render.shoulders import shoulder_masks

#: float64 agreement with the reference (metres).
TOL64 = 1e-9
#: float32 agreement with the reference (metres): see the module's docstring.
TOL32 = 1e-5


def _random_rig(rng, v=400, k=9, f=6, spread=np.pi):
    """Random weights (1-5 influences; some vertices on one bone with weight 1, one
    vertex with none), linear shares, bone matrices that rotate up to ``spread``,
    stretch anisotropically (0.6-1.6) and translate."""
    rest = rng.normal(size=(v, 3))
    w = np.zeros((v, k))
    for i in range(v):
        n = rng.integers(1, min(6, k + 1))
        w[i, rng.choice(k, n, replace=False)] = rng.random(n) + 0.05
    w[: v // 3] = 0.0
    w[np.arange(v // 3), rng.integers(0, k, v // 3)] = 1.0  # one bone, weight 1
    w[v // 3] = 0.0  # no weight at all
    w /= np.maximum(w.sum(axis=1, keepdims=True), 1e-300)
    rot = Rotation.random(f * k, random_state=rng).as_matrix().reshape(f, k, 3, 3)
    small = Rotation.from_rotvec(rng.normal(size=(f * k, 3)) * spread / 3).as_matrix()
    rot = np.where(rng.random((f, k, 1, 1)) < 0.5, rot, small.reshape(f, k, 3, 3))
    scale = rng.uniform(0.6, 1.6, size=(f, k, 3))
    axes = Rotation.random(k, random_state=rng).as_matrix()
    a = rot @ (axes * scale[..., None, :]) @ np.swapaxes(axes, -1, -2)  # R · (A S Aᵀ)
    m = np.concatenate([a, rng.normal(size=(f, k, 3, 1))], axis=-1)
    linear = np.where(rng.random(v) < 0.2, rng.random(v), 0.0)
    centres = rng.normal(size=(k, 3))
    return rest, sparse.csr_matrix(w), m, centres, linear


@pytest.mark.parametrize("seed", range(6))
def test_kernel_equals_the_reference_on_random_rigs(seed):
    """Random rigs with large relative rotations (quaternions in opposite hemispheres,
    so the signs matter), anisotropic stretch, linear shares, one-bone and weightless
    vertices: float64 to rounding, float32 within TOL32."""
    rng = np.random.default_rng(seed)
    rest, w, m, centres, linear = _random_rig(rng)
    want = dq_reference(rest, w, m, centres, linear=linear)
    got = dq_skin(rest, w, m, centres, linear=linear)
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, want, rtol=0, atol=TOL64)
    got32 = dq_skin(rest, w, m, centres, linear=linear, dtype=np.float32)
    assert got32.dtype == np.float32
    assert np.abs(got32 - want).max() < TOL32 * np.abs(want).max()


def test_a_plan_adds_its_shifts_and_writes_into_out():
    """``shift_weights @ shifts`` is added per frame; ``out`` receives the result."""
    rng = np.random.default_rng(7)
    rest, w, m, centres, linear = _random_rig(rng, v=50, k=4, f=3)
    sw = sparse.random(50, 4, density=0.3, random_state=1, format="csr")
    shifts = rng.normal(size=(3, 4, 3))
    plan = dq_plan(rest, w, linear, shift_weights=sw)
    out = np.full((3, 50, 3), np.nan)
    back = dq_skin_planned(plan, m, centres, shifts, out=out)
    assert back is out
    want = dq_reference(rest, w, m, centres, linear=linear) + np.einsum(
        "vs,fsi->fvi", sw.toarray(), shifts
    )
    np.testing.assert_allclose(out, want, rtol=0, atol=TOL64)
    # frames need not be adjacent (every other frame of a larger array) ...
    big = np.full((6, 50, 3), np.nan)
    dq_skin_planned(plan, m, centres, shifts, out=big[::2])
    np.testing.assert_array_equal(big[::2], out)
    # ... but each frame's vertices must be (the kernel writes them as one row)
    with pytest.raises(ValueError, match="contiguous"):
        dq_skin_planned(plan, m, centres, shifts, out=np.zeros((3, 3, 50)).transpose(0, 2, 1))


def test_blocks_of_frames_and_vertices_give_the_same_skin(monkeypatch):
    """Frames in chunks and vertices in blocks (the kernel's cache sizes made small:
    chunks of 4 frames, blocks of 256 vertices, the first block all on one bone, so
    with no blended part) skin as the reference does."""
    import snapcore.motion.dq_kernel as kernel

    rng = np.random.default_rng(11)
    rest, w, m, centres, linear = _random_rig(rng, v=900, k=7, f=10)
    w = w.tolil()
    w[:300] = 0.0
    w[np.arange(300), rng.integers(0, 7, 300)] = 1.0  # vertices 0-299: one bone each
    w = w.tocsr()
    linear[300] = 0.0  # the weightless vertex: stays put (a linear share would scale it)
    want = dq_reference(rest, w, m, centres, linear=linear)
    monkeypatch.setattr(kernel, "KERNEL_FRAMES", 4)
    monkeypatch.setattr(kernel, "KERNEL_CHUNK_BYTES", 1)  # the minimum block, 256 rows
    plan = dq_plan(rest, w, linear)
    assert [b[3] is None for b in plan.row_blocks(256)] == [True, False, False, False]
    got = dq_skin_planned(plan, m, centres)
    np.testing.assert_allclose(got, want, rtol=0, atol=TOL64)


def test_a_plan_leaves_the_callers_weights_as_they_were():
    """The plan prunes stored zeros from its own copy: a shared weight matrix (the human
    asset's, used by every body) with a stored zero keeps it."""
    w = sparse.csr_matrix(np.array([[0.5, 0.5, 0.0], [0.0, 1.0, 0.0]]))
    w.data[0] = 0.0  # a stored zero: what eliminate_zeros would prune
    w.data[1] = 1.0
    before = (w.data.copy(), w.indices.copy(), w.indptr.copy())
    dq_plan(np.zeros((2, 3)), w, np.array([0.0, 0.5]))
    for now, then in zip((w.data, w.indices, w.indptr), before):
        np.testing.assert_array_equal(now, then)


def test_plans_are_shared_by_inputs_of_equal_value():
    """A library's scenes share rigs: a plan asked again with inputs of the same values
    (new arrays, as each scene's body makes them) is the one made before, and skins as
    a plan made afresh does; a change to any value (a shift weight, the dtype) makes
    another plan."""
    import snapcore.motion.dq_kernel as kernel

    rng = np.random.default_rng(5)
    rest, w, m, centres, linear = _random_rig(rng, v=60, k=5, f=4)
    sw = sparse.random(60, 5, density=0.3, random_state=2, format="csr")
    shifts = rng.normal(size=(4, 5, 3))
    first = dq_plan(rest, w, linear, shift_weights=sw)
    again = dq_plan(rest.copy(), w.copy(), linear.copy(), shift_weights=sw.copy())
    assert again is first
    kernel._PLANS.clear()
    fresh = dq_plan(rest, w, linear, shift_weights=sw)
    assert fresh is not first
    np.testing.assert_array_equal(
        dq_skin_planned(first, m, centres, shifts), dq_skin_planned(fresh, m, centres, shifts)
    )
    moved = sw.copy()
    moved.data[0] += 0.25
    assert dq_plan(rest, w, linear, shift_weights=moved) is not fresh
    assert dq_plan(rest, w, linear, shift_weights=sw, dtype=np.float32) is not fresh
    assert dq_plan(rest, w, linear, shift_weights=sw) is fresh
    # bounded: the oldest plans go
    for i in range(kernel.PLAN_CACHE_SIZE + 1):
        dq_plan(rest + i, w, linear)
    assert len(kernel._PLANS) == kernel.PLAN_CACHE_SIZE
    assert dq_plan(rest, w, linear, shift_weights=sw) is not fresh


def test_polar_rotation_is_the_svd_nearest_rotation():
    """Newton's iteration gives the SVD's polar factor; a mirror (det < 0) gets the
    nearest proper rotation as before."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(500, 3, 3))
    u, _, vt = np.linalg.svd(a)
    flip = np.linalg.det(u @ vt) < 0
    u[flip, :, -1] *= -1
    np.testing.assert_allclose(polar_rotation(a), u @ vt, atol=1e-10)
    assert flip.any() and (np.linalg.det(a) > 0).any()  # both branches were taken


def test_quaternions_of_matrices_in_every_branch():
    """The kernel's matrix → quaternion conversion gives back the matrix (so q or -q of
    SciPy's) for rotations near 0° and near 180° about each axis, where each of its
    four readings is the one taken, and for random ones."""
    from snapcore.motion.dq_kernel import _quaternions
    from snapcore.motion.kinematics import quat_to_matrix

    vecs = [np.zeros(3), *(np.pi * (np.eye(3)[i] * 0.999 + 0.01) for i in range(3))]
    r = np.concatenate(
        [
            Rotation.from_rotvec(vecs).as_matrix(),
            Rotation.random(200, random_state=4).as_matrix(),
        ]
    )
    q = _quaternions(r)  # (4, N)
    np.testing.assert_allclose(quat_to_matrix(q.T), r, atol=1e-14)
    want = Rotation.from_matrix(r).as_quat()[:, [3, 0, 1, 2]]
    np.testing.assert_allclose(np.abs(np.einsum("in,ni->n", q, want)), 1.0, atol=1e-14)


def test_known_rotations_skin_as_the_polar_ones():
    """A caller's rotations (the polar factors it built its matrices from) give what the
    polar iteration gives; other rotations would not (so they are used)."""
    rng = np.random.default_rng(7)
    rest, w, m, centres, linear = _random_rig(rng, spread=1.0)
    plan = dq_plan(rest, w, linear)
    r = polar_rotation(m[..., :3])
    got = dq_skin_planned(plan, m, centres, rotations=r)
    np.testing.assert_allclose(got, dq_skin_planned(plan, m, centres), atol=TOL64)
    other = dq_skin_planned(plan, m, centres, rotations=np.broadcast_to(np.eye(3), r.shape))
    assert np.abs(other - got).max() > 1e-3


def _salsa_body(motions_dir):
    from snapcore.motion.load import load_scene
    from snapcore.render.human import HumanBody

    a, b = motions_dir / "two_person/60_01_scaled.bvh", motions_dir / "two_person/61_01_scaled.bvh"
    if not (a.exists() and b.exists()):
        pytest.skip("salsa pair not in the shared data")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the salsa unit is fitted, which warns
        scene = load_scene([a, b], fps=60)
    return HumanBody(scene.characters[1])


def test_the_human_body_equals_the_reference_on_a_real_clip(motions_dir):
    """The salsa follower's body (13,380 vertices, stretch and linear hip shares) over
    100 frames of turns and dips (every third of 600-900): the drawn (float32) skin within TOL32 of the float64
    reference plus the stretch term, and the float64 skin to rounding."""
    body = _salsa_body(motions_dir)
    c, r, a = body.character, body.retarget, body.asset
    frames = np.arange(600, 900, 3)
    m, st = r.group_matrices(c.positions[frames], c.rotations[frames], stretch=True)
    linear = np.asarray(a.weights @ r._linear_bones).ravel()
    want = dq_reference(a.vertices, a.weights, m[:, r.bone_group], a.heads, linear=linear)
    want += np.einsum("vb,fbi->fvi", body._stretch.toarray(), st[:, r.bone_group])
    # the shoulders' drop as the arms hang (snapcore.render.shoulders), added after the
    # blend: the reference adds it densely, over every vertex
    drop_w = shoulder_masks(a, a.vertices, a.weights)
    want += np.einsum("vs,fsi->fvi", drop_w, r._shoulder_drops(c.positions[frames]))
    got32 = body.skin(c.positions[frames], c.rotations[frames], dtype=np.float32)
    assert got32.dtype == np.float32 and got32.shape == want.shape
    assert np.abs(got32 - want).max() < TOL32
    got64 = body.skin(c.positions[frames], c.rotations[frames])
    np.testing.assert_allclose(got64, want, rtol=0, atol=TOL64)
