"""The bins standing in for a full pass of the exact refinement (issue 41).

``LocalScores`` built from the octahedral bins must give the exact scores of every view
inside its window (the far bins' signed sums replace a pass over all vectors), and track
at least every vector near the plane perpendicular to its centre.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from snapcore.motion.synth import synth_scene
from snapcore.select.sphere import (
    BIN_RESOLUTION,
    OUTER_WINDOW,
    Bins,
    LocalScores,
    _bin_generators,
    _bin_geometry,
    abs_dot_sums,
)
from snapcore.select.view import motion_triangles


def _vectors(kind: str, rng) -> np.ndarray:
    if kind == "walk":
        return np.array(motion_triangles(synth_scene("walk")).pma_vectors)
    b = rng.normal(size=(3, 20000)) * rng.uniform(0.1, 2.0, 20000)
    b[:, :50] = 0.0  # skipped quads are zero vectors
    b[1, 50:100] = 0.0  # on the fold's plane
    return b


def _bins(b):
    index = np.empty(b.shape[1], dtype=np.int32)
    gen, _ = _bin_generators(b, BIN_RESOLUTION, index)
    return Bins(gen, index, *_bin_geometry(BIN_RESOLUTION))


@pytest.mark.parametrize("kind", ["random", "walk"])
def test_every_vector_lies_within_its_bins_radius(kind):
    b = _vectors(kind, np.random.default_rng(1))
    bins = _bins(b)
    n = np.linalg.norm(b, axis=0)
    ok = n > 0
    f = b[:, ok] / n[ok] * np.where(b[1, ok] < 0, -1.0, 1.0)  # folded to y >= 0
    cos = np.einsum("ki,ik->k", bins.centres[bins.index[ok]], f)
    assert np.all(np.arccos(np.clip(cos, -1, 1)) <= bins.radius[bins.index[ok]])
    # the generators are the members' folded sums
    want = np.zeros_like(bins.gen)
    np.add.at(want, bins.index[ok], f.T * n[ok, None])
    np.testing.assert_allclose(bins.gen, want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("kind", ["random", "walk"])
def test_window_from_bins_gives_exact_scores(kind):
    rng = np.random.default_rng(2)
    b = _vectors(kind, rng)
    bn = np.linalg.norm(b, axis=0)
    bins = _bins(b)
    for _ in range(5):
        v0 = rng.normal(size=3)
        v0 /= np.linalg.norm(v0)
        loc = LocalScores(v0, b, bn, OUTER_WINDOW, bins=bins)
        scale = float(bn.sum())
        assert loc.score0 == pytest.approx(
            abs_dot_sums(v0[None], b)[0], rel=1e-12, abs=1e-12 * scale
        )
        # views inside the window, up to its edge
        u = v0 + rng.normal(size=(40, 3)) * 0.06
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        u = u[loc.covers(u)]
        assert u.shape[0] > 10
        np.testing.assert_allclose(
            loc.scores(u), abs_dot_sums(u, b), rtol=1e-12, atol=1e-12 * scale
        )
        # every vector near the plane is tracked (a superset of the full pass's set)
        near = np.abs(v0 @ b) < math.sin(math.asin(OUTER_WINDOW)) * bn
        tracked = {tuple(c) for c in loc.bc.T}  # by value: equal vectors share a bin
        assert all(tuple(c) in tracked for c in b[:, near].T)


def test_triangles_do_not_depend_on_the_links_order():
    """BVH links (children 1..L in a run) take a slice, other orders a gather: the same
    quads either way, bit for bit."""
    scene = synth_scene("walk")
    c = scene.characters[0]
    links = np.asarray(c.skeleton.links)
    assert np.array_equal(links[:, 1], np.arange(1, links.shape[0] + 1))  # the slice path
    perm = np.random.default_rng(3).permutation(links.shape[0])
    a = motion_triangles([(c.positions, links)])
    b = motion_triangles([(c.positions, links[perm])])
    steps = c.positions.shape[0] - 1
    va = a.pma_vectors.reshape(3, 2, steps, -1)[..., perm]
    assert np.array_equal(va, b.pma_vectors.reshape(3, 2, steps, -1))
    assert np.array_equal(a.quads.reshape(steps, -1)[:, perm], b.quads.reshape(steps, -1))


def test_gap_bound_is_the_per_row_sum_of_the_straddle_factors():
    from snapcore.select.sphere import _gap_bound, _straddle_factors

    n = 642
    weight = np.random.default_rng(4).uniform(0, 3, BIN_RESOLUTION**2)
    rows, cols, vals = _straddle_factors(n, BIN_RESOLUTION)
    want = np.zeros(n // 2)
    for r, c, v in zip(rows, cols, vals):  # the definition, one term at a time
        want[r] += v * weight[c]
    np.testing.assert_allclose(_gap_bound(n, BIN_RESOLUTION, weight), want, rtol=1e-12)
