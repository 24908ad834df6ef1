"""The view search's compiled kernel against its NumPy reference (issue 41).

``snapcore.select._pma_kernel`` repeats the NumPy passes' operations in the same order
(built with ``-ffp-contract=off``), so every output must be the same double, bit for bit:
the swept triangles' vectors, norms and quad areas, the bin index and per-bin sums
(summed per chunk in ``np.bincount``'s order), and the bins' members near a view. With
the extension hidden, ``kernels.compiled()`` is False, the NumPy passes run, and the
chosen view, its score, the certificate and every sample's score are the same.
"""

from __future__ import annotations

import json
import shutil
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from snapcore.motion.synth import synth_scene
from snapcore.select import kernels, sphere, view
from snapcore.select.sphere import BIN_RESOLUTION, CHUNK, _bin_generators
from snapcore.select.view import motion_triangles, select_view

HERE = Path(__file__).resolve().parent


@pytest.fixture
def numpy_only(monkeypatch):
    """The extension hidden (an import of it fails), as on a machine without a compiler."""
    monkeypatch.setitem(sys.modules, "snapcore.select._pma_kernel", None)
    kernels._module.cache_clear()
    yield
    kernels._module.cache_clear()


def _both(monkeypatch, fn):
    """``fn()`` with the compiled kernel, then with the extension hidden."""
    if not kernels.compiled():  # test_the_kernel_is_built_where_there_is_a_compiler fails
        pytest.skip("the compiled kernel is not built: the NumPy path alone runs")
    with_kernel = fn()
    with monkeypatch.context() as m:
        m.setitem(sys.modules, "snapcore.select._pma_kernel", None)
        kernels._module.cache_clear()
        assert not kernels.compiled()
        without = fn()
    kernels._module.cache_clear()
    return with_kernel, without


def _same_bits(a, b) -> bool:
    """Equal shapes, dtypes and bytes (so -0.0 against 0.0, or one NaN, is a difference)."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def test_the_kernel_is_built_where_there_is_a_compiler():
    """``make install`` builds it wherever gcc is (the Makefile installs gcc when absent):
    a silently skipped build would leave the view search 1.5x slower."""
    if shutil.which("gcc") is None:
        pytest.skip("no C compiler: the NumPy path is the one in use")
    assert kernels.compiled()


def _random_motion(rng, frames, joints, links):
    """A random walk of joint positions (m) with still and zero-length links."""
    x = np.cumsum(rng.normal(scale=0.01, size=(frames, joints, 3)), axis=0)
    x[:, 3] = x[:, 2]  # joint 3 sits on joint 2: the link (2, 3) sweeps nothing
    x[:, 5] = x[0, 5]  # joint 5 never moves
    return x, links


def _sources(rng):
    j = 24
    chain = np.stack([np.arange(j - 1), np.arange(1, j)], axis=1)  # children in a run
    shuffled = rng.permutation(np.stack([rng.integers(0, j, 30), rng.integers(0, j, 30)], 1))
    return [
        _random_motion(rng, 700, j, chain),  # 2·699·23 = 32k triangles: past one CHUNK
        _random_motion(rng, 700, j, shuffled),  # offset not a multiple of CHUNK
    ]


@pytest.mark.parametrize("frames", [None, (17, 530)])
def test_swept_triangles_equal_numpy_to_the_bit(monkeypatch, frames):
    rng = np.random.default_rng(3)
    src = _sources(rng)

    def run():
        t = motion_triangles(src, frames=frames, floor=1e-5)
        return t.pma_vectors, t.pma_norms, t.quads

    (b1, n1, q1), (b0, n0, q0) = _both(monkeypatch, run)
    assert b1.shape[1] > CHUNK
    assert 0 < np.count_nonzero(q0 < 1e-5) < q0.size  # some quads skipped, most vote
    assert _same_bits(b1, b0) and _same_bits(n1, n0) and _same_bits(q1, q0)


def test_swept_triangles_of_a_scene_equal_numpy_to_the_bit(monkeypatch):
    scene = synth_scene("walk")
    (t1, t0) = _both(monkeypatch, lambda: motion_triangles(scene, floor=0.0))
    for name in ("pma_vectors", "pma_norms", "quads"):
        assert _same_bits(getattr(t1, name), getattr(t0, name)), name


def test_links_the_kernel_declines_go_to_numpy(monkeypatch):
    """A negative joint index counts from the end in NumPy (the kernel hands such links
    over); one past the last joint is refused either way."""
    rng = np.random.default_rng(4)
    x, _ = _random_motion(rng, 40, 8, None)
    neg = np.array([[0, 1], [1, -1]])
    t1, t0 = _both(monkeypatch, lambda: motion_triangles(x, neg))
    assert _same_bits(t1.pma_vectors, t0.pma_vectors)
    assert _same_bits(t1.pma_vectors, motion_triangles(x, np.array([[0, 1], [1, 7]])).pma_vectors)
    for hidden in (False, True):
        with monkeypatch.context() as m:
            if hidden:
                m.setitem(sys.modules, "snapcore.select._pma_kernel", None)
            kernels._module.cache_clear()
            with pytest.raises((IndexError, ValueError)):  # NumPy's gather or its slice
                motion_triangles(x, np.array([[0, 8]]))
    kernels._module.cache_clear()


def _random_vectors(rng, k):
    b = rng.normal(size=(3, k)) * rng.lognormal(sigma=2.0, size=k)
    b[:, :40] = 0.0  # skipped quads
    b[1, 40:80] = 0.0  # on the fold's plane, both signs of zero
    b[1, 60:80] = -0.0
    b[0, 80:90] = b[2, 80:90] = 0.0  # straight up or down
    return b


@pytest.mark.parametrize("k", [1, 1000, 3 * CHUNK + 123])
def test_bins_equal_numpy_to_the_bit(monkeypatch, k):
    b = _random_vectors(np.random.default_rng(k), max(k, 100))[:, :k]

    def run():
        index = np.full(b.shape[1], -1, dtype=np.int32)
        gen, weight = _bin_generators(b, BIN_RESOLUTION, index)
        return gen, weight, index

    (g1, w1, i1), (g0, w0, i0) = _both(monkeypatch, run)
    assert _same_bits(g1, g0) and _same_bits(w1, w0) and _same_bits(i1, i0)
    assert i0.min() >= 0 and i0.max() < BIN_RESOLUTION**2


def test_bins_refuse_a_non_finite_vector(monkeypatch):
    """NumPy's bincount refuses the index of a NaN; the kernel refuses it too."""
    b = _random_vectors(np.random.default_rng(5), 500)
    b[2, 300] = np.nan

    def run():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # NumPy's NaN-to-int cast
            with pytest.raises(ValueError):
                _bin_generators(b, BIN_RESOLUTION)

    _both(monkeypatch, run)


def test_near_columns_are_the_numpy_selection():
    if not kernels.compiled():
        pytest.skip("the compiled kernel is not built")
    rng = np.random.default_rng(6)
    index = rng.integers(0, 2304, 50_000).astype(np.int32)
    b = _random_vectors(rng, 50_000)
    bn = np.linalg.norm(b, axis=0)
    near = rng.random(2304) < 0.1
    bc, bcn = kernels.near_columns(index, near, b, bn)
    sel = np.flatnonzero(np.take(near, index))
    assert _same_bits(bc, np.take(b, sel, axis=1)) and _same_bits(bcn, np.take(bn, sel))
    bc, bcn = kernels.near_columns(index, np.zeros(2304, bool), b, bn)
    assert bc.shape == (3, 0) and bcn.shape == (0,)


def _selection(sel):
    return (sel.view, sel.view_grid, sel.score, sel.score_grid, sel.scores, sel.iterations)


@pytest.mark.parametrize(
    "kwargs",
    [{}, {"method": "motion_area"}, {"refine": False}, {"index": 60, "window_s": 0.5}],
)
def test_selection_is_the_same_without_the_extension(monkeypatch, kwargs):
    scene = synth_scene("walk")
    s1, s0 = _both(monkeypatch, lambda: select_view(scene, **kwargs))
    assert s1.certified == s0.certified
    assert all(_same_bits(a, b) for a, b in zip(_selection(s1), _selection(s0)))


def test_the_fallback_runs_numpy_when_the_extension_is_hidden(monkeypatch, numpy_only):
    """With the extension hidden the NumPy passes are the ones called (and give the
    answer); with it, they are not."""
    calls = []
    for mod, name in ((view, "_swept_block"), (sphere, "_bin_sums")):
        fn = getattr(mod, name)
        monkeypatch.setattr(mod, name, lambda *a, _fn=fn, _n=name: (calls.append(_n), _fn(*a))[1])
    scene = synth_scene("walk")
    sel = select_view(scene)
    assert not kernels.compiled()
    assert calls.count("_bin_sums") == 1 and calls.count("_swept_block") >= 1
    assert sel.certified and sel.score > 0
    calls.clear()
    monkeypatch.delitem(sys.modules, "snapcore.select._pma_kernel")
    kernels._module.cache_clear()
    if shutil.which("gcc") is not None:  # built there: the kernel is back, NumPy not called
        assert kernels.compiled()
        select_view(scene)
        assert calls == []


def _shared_cases():
    ref = json.loads((HERE / "regression" / "speed41_outputs.json").read_text())
    return ref["cases"]


@pytest.mark.slow
@pytest.mark.parametrize("name", list(_shared_cases()))
def test_shared_clips_select_the_same_view_without_the_extension(monkeypatch, motions_dir, name):
    """Every shared clip (the issue-41 regression set): view, score, certificate, steps
    and every sample's score bit for bit with and without the kernel."""
    from snapcore.motion.load import load_scene

    case = _shared_cases()[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene([str(motions_dir / p) for p in case["paths"]], **case["kwargs"])
    s1, s0 = _both(monkeypatch, lambda: select_view(scene))
    assert s1.certified == s0.certified
    assert all(_same_bits(a, b) for a, b in zip(_selection(s1), _selection(s0)))
