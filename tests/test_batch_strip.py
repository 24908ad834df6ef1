"""The preview strip's level of detail (issue 41): panels at most
:data:`~snapcore.render.mannequin.COARSE_MAX_PX` tall draw the coarse mannequin.

Tolerance, against the same strip drawn with the full mannequin (the framing is the
full one's in both, so only the figures' facets differ): the mean absolute difference
at most 1.5 levels (of 255) per channel, and at most 2% of the pixels further than 16
levels from every pixel within one pixel of them in the other picture (the figures'
outlines move by under a pixel: see ``COARSE_MAX_PX``). Measured on the 300 strips of
the bench library (docs/speed.md): at most 1.30 levels and 1.36%; on the three scenes
here 0.50-0.75 levels and 0.27-0.44%.
"""

from __future__ import annotations

import numpy as np
import pytest

from snapcore.batch.task import _strip, preview_size
from snapcore.motion import synth
from snapcore.render.mannequin import TESSELLATION, TESSELLATION_COARSE, tessellation_for

pytestmark = pytest.mark.timeout(300)

#: See the module docstring.
MEAN_LEVELS = 1.5
NEAR_LEVELS = 16
NEAR_SHARE = 0.02


def _far_share(a: np.ndarray, b: np.ndarray) -> float:
    """Share of ``a``'s pixels with no pixel of ``b`` within one pixel (8-neighbourhood
    and itself) within NEAR_LEVELS in every channel."""
    a, b = a.astype(int), b.astype(int)
    h, w, _ = a.shape
    pad = np.pad(b, ((1, 1), (1, 1), (0, 0)), mode="edge")
    near = np.zeros((h, w), bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near |= np.abs(a - pad[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]).max(-1) <= NEAR_LEVELS
    return float((~near).mean())


def _strips(scene, monkeypatch, size):
    frames = np.unique(np.linspace(0, scene.n_frames - 1, 12).round().astype(int))
    view = np.array([0.5, 0.35, 0.8])
    view /= np.linalg.norm(view)
    small = _strip(scene, frames, view, size, "mannequin")
    import snapcore.render.mannequin as mannequin

    monkeypatch.setattr(mannequin, "tessellation_for", lambda height_px: TESSELLATION)
    full = _strip(scene, frames, view, size, "mannequin")
    monkeypatch.undo()
    return small, full


def test_small_panels_take_the_coarse_mannequin_and_large_ones_the_full():
    assert tessellation_for(preview_size((320, 360))[1]) is TESSELLATION_COARSE
    assert tessellation_for(135) is TESSELLATION_COARSE
    assert tessellation_for(480) is TESSELLATION


@pytest.mark.parametrize("motion, seed", [("walk", 0), ("jumping_jacks", 4), ("kick", 9)])
def test_the_coarse_strip_stays_within_the_tolerance_of_the_full_one(monkeypatch, motion, seed):
    scene = synth.synth_scene(motion, seed=seed)
    small, full = _strips(scene, monkeypatch, preview_size((320, 360)))
    assert small.shape == full.shape == (135, 12 * 120, 3)
    differ = np.abs(small.astype(int) - full).max(-1) > 0
    assert differ.any()  # the coarse body is drawn (else this test tests nothing)
    assert np.abs(small.astype(int) - full).mean() <= MEAN_LEVELS
    assert _far_share(small, full) <= NEAR_SHARE
    assert _far_share(full, small) <= NEAR_SHARE
    # the floor and the figures' places did not move: the rows and columns without a
    # figure in either picture are the same pixels
    rows = ~differ.any(axis=1)
    assert rows.sum() > 10 and np.array_equal(small[rows], full[rows])


def test_large_panels_draw_the_full_mannequin(monkeypatch):
    scene = synth.synth_scene("walk", seed=2)
    small, full = _strips(scene, monkeypatch, (240, 270))
    np.testing.assert_array_equal(small, full)
