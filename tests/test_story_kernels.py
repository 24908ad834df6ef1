"""The story's array kernels against plain reference implementations (issue 41's third
pass rewrote them for speed): the debouncing (hysteresis, minimum durations), the joint
tracks' rows and speeds, and the neutral stance's percentile and medians."""

from __future__ import annotations

import numpy as np
import pytest

from snapcore.motion import synth
from snapcore.select.novelty import tail_surprisal
from snapcore.select.signals import (
    enforce_min_durations,
    hysteresis,
    hysteresis_rows,
    nonzero_rows,
)
from snapcore.select.stance import (
    _percentile,
    _row_medians,
    descriptor_of,
    joint_trajectories,
    stance_departure,
    stance_departure_rows,
)
from snapcore.select.tracks import JointTracks


def _hysteresis_loop(x: np.ndarray, on: float, off: float) -> np.ndarray:
    """The two-threshold switch frame by frame (1-D)."""
    out = np.zeros(x.size, dtype=bool)
    state = False
    for i, v in enumerate(x):
        if v <= on:
            state = True
        elif v > off:
            state = False
        out[i] = state
    return out


def _runs(b: np.ndarray) -> list[list[int]]:
    runs, start = [], None
    for i, v in enumerate(list(b) + [False]):
        if v and start is None:
            start = i
        elif not v and start is not None:
            runs.append([start, i])
            start = None
    return runs


def _min_durations_loop(b: np.ndarray, min_on: int, min_off: int) -> np.ndarray:
    """Close gaps shorter than ``min_off`` between two contacts, then drop contacts
    shorter than ``min_on`` (one row, as the docstring states it)."""
    runs = _runs(b)
    merged: list[list[int]] = []
    for s, e in runs:
        if merged and s - merged[-1][1] < min_off:
            merged[-1][1] = e
        else:
            merged.append([s, e])
    out = np.zeros(b.size, dtype=bool)
    for s, e in merged:
        if e - s >= min_on:
            out[s:e] = True
    return out


def test_hysteresis_matches_the_frame_by_frame_switch():
    """Random scores (with NaN, which is neither on nor off): every column, either
    axis layout, equals the switch run frame by frame."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        x = rng.uniform(0, 3, size=(int(rng.integers(1, 60)), 4))
        x[rng.random(x.shape) < 0.05] = np.nan
        want = np.stack([_hysteresis_loop(x[:, j], 1.0, 1.5) for j in range(4)], axis=1)
        np.testing.assert_array_equal(hysteresis(x, 1.0, 1.5), want)
        np.testing.assert_array_equal(hysteresis_rows(np.ascontiguousarray(x.T), 1.0, 1.5), want.T)
    assert hysteresis_rows(np.zeros((3, 0)), 1.0, 1.5).shape == (3, 0)
    np.testing.assert_array_equal(hysteresis_rows(np.array([[1.2], [0.5]]), 1.0, 1.5), [[0], [1]])


def test_tail_surprisal_counts_the_frames_at_least_as_far_out():
    """Random curves with ties (and a signed zero): each frame's -log2 of the share of
    frames whose value is at least its own, counted frame by frame; NaN ties with NaN
    (sorted last, as NumPy sorts it)."""
    rng = np.random.default_rng(5)
    for _ in range(300):
        n = int(rng.integers(2, 50))
        v = rng.uniform(0, 10, n)
        if rng.random() < 0.5:
            v = np.round(v)  # ties
        v[rng.integers(n)] = -0.0
        at_least = np.array([np.count_nonzero(v >= x) for x in v])
        np.testing.assert_array_equal(tail_surprisal(v), -np.log2(at_least / n))
    v = np.array([1.0, np.nan, 3.0, np.nan])
    np.testing.assert_array_equal(tail_surprisal(v), -np.log2(np.array([4, 2, 3, 2]) / 4))


def test_nonzero_rows_is_numpys_nonzero():
    """Rows and columns of the True entries of random 2-D masks, zero-sized included,
    in NumPy's (row-major) order and integer type."""
    rng = np.random.default_rng(6)
    for _ in range(300):
        m = rng.random((int(rng.integers(0, 6)), int(rng.integers(0, 30)))) < rng.random()
        for got, want in zip(nonzero_rows(m), np.nonzero(m)):
            np.testing.assert_array_equal(got, want)
            assert got.dtype == want.dtype


def test_min_durations_match_the_run_by_run_rule():
    """Random (L, F) contact states: each row equals closing its short interior gaps and
    then dropping its short contacts, run by run."""
    rng = np.random.default_rng(4)
    for _ in range(500):
        st = rng.random((int(rng.integers(1, 5)), int(rng.integers(1, 40)))) < rng.uniform(0.1, 0.9)
        m_on, m_off = int(rng.integers(1, 6)), int(rng.integers(1, 6))
        want = np.stack([_min_durations_loop(r, m_on, m_off) for r in st])
        np.testing.assert_array_equal(enforce_min_durations(st, m_on, m_off), want)


@pytest.mark.parametrize("fps", [60, 24])
def test_joint_tracks_are_the_trajectories_and_their_gradient(fps):
    """The tracks' rows are joint_trajectories transposed (60 fps: the gather straight
    from the positions; 24 fps: a real Savitzky-Golay window), and their speeds the
    norm of np.gradient along the frames (the same doubles)."""
    scene = synth.synth_scene("kick", fps=fps)
    c = scene.characters[0]
    joints = np.array([c.n_joints - 1, 0, 3, 7])
    tr = JointTracks.of(c, joints, fps=float(fps), smooth_s=0.05)
    np.testing.assert_array_equal(tr.joints, np.sort(joints))
    x = joint_trajectories(c, np.sort(joints), fps=float(fps), smooth_s=0.05)  # (F, A, 3)
    np.testing.assert_array_equal(tr.rows, x.transpose(2, 1, 0))
    g = np.gradient(x, axis=0)
    speed = np.sqrt((g[..., 0] ** 2 + g[..., 1] ** 2) + g[..., 2] ** 2)
    np.testing.assert_array_equal(tr.speed, speed.T)
    np.testing.assert_array_equal(tr.height[tr.columns([3])[0]], x[:, 1, 1])  # joint 3: 2nd


def test_stance_percentile_and_medians_are_numpys():
    """The neutral stance's written-out percentile and row medians give NumPy's doubles
    (odd and even counts, ties, NaN)."""
    rng = np.random.default_rng(5)
    for i in range(400):
        v = rng.normal(size=(int(rng.integers(1, 600)), 2))
        if i % 5 == 0:
            v = np.round(v, 1)
        assert _percentile(v, 5) == float(np.percentile(v, 5))
        r = rng.normal(size=(4, int(rng.integers(1, 300))))
        assert _row_medians(r) == np.median(r, axis=1).tolist()
    v[0, 0] = np.nan
    assert np.isnan(_percentile(v, 5))
    r[1, 0] = np.nan
    assert np.isnan(_row_medians(r)[1])


def test_stance_departure_rows_is_the_frame_major_departure():
    """Feature-major rows give the same bits as stance_departure on (F, D), up to the
    order of the additions; a frame at the neutral stance has 0 bits."""
    rng = np.random.default_rng(6)
    feats = rng.normal(size=(500, 36))
    neutral = rng.normal(size=36)
    feats[7] = neutral
    rows = stance_departure_rows(np.ascontiguousarray(feats.T), neutral, spread=0.15)
    np.testing.assert_allclose(rows, stance_departure(feats, neutral, spread=0.15), rtol=1e-13)
    assert rows[7] == 0.0


@pytest.mark.parametrize("horizontal", [True, False])
def test_descriptor_is_heights_and_pairwise_distances(horizontal):
    """descriptor_of: the heights above the ground, then the 3-D and (optionally) the
    horizontal distances of the pairs in np.triu_indices order, over the stature."""
    rng = np.random.default_rng(7)
    x = rng.normal(size=(50, 5, 3))
    got = descriptor_of(x, ground=0.2, stature=1.6, horizontal=horizontal)
    a, b = np.triu_indices(5, 1)
    d = x[:, a] - x[:, b]
    parts = [x[..., 1] - 0.2, np.linalg.norm(d, axis=2)]
    if horizontal:
        parts.append(np.linalg.norm(d[..., ::2], axis=2))
    np.testing.assert_allclose(got, np.concatenate(parts, axis=1) / 1.6, rtol=1e-14)
