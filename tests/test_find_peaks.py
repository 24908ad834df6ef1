"""The NumPy peak finder of the strikes (issue 41: importing scipy.signal cost 1-3 s of
every `snapshot select`) gives scipy.signal.find_peaks's peaks, index for index."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import find_peaks as scipy_find_peaks

from snapcore.select.signals import find_peaks


def _arrays(rng, n_arrays):
    """Random signals of every kind that matters: few levels (plateaus and ties
    everywhere), smooth speeds with noise, NaN sprinkled, constant, short."""
    for i in range(n_arrays):
        n = int(rng.integers(0, 80))
        kind = i % 5
        if kind == 0:
            x = rng.integers(0, 4, n).astype(float)  # plateaus, equal peaks
        elif kind == 1:
            t = np.linspace(0, rng.uniform(1, 20), n)
            x = np.abs(np.sin(t)) * rng.uniform(0.5, 5) + rng.normal(0, 0.2, n)
        elif kind == 2:
            x = rng.normal(size=n)
            x[rng.random(n) < 0.1] = np.nan
        elif kind == 3:
            x = np.repeat(rng.integers(0, 5, max(1, n // 4)).astype(float), 4)
            x[rng.random(len(x)) < 0.05] = np.nan
        else:
            x = np.full(n, float(rng.integers(0, 3)))
        yield x


@pytest.mark.parametrize("seed", range(4))
def test_the_same_peaks_as_scipy(seed):
    rng = np.random.default_rng(seed)
    checked = found = 0
    for x in _arrays(rng, 2500):
        height = float(rng.choice([0.0, 0.5, 1.0, 2.0, rng.uniform(-1, 3)]))
        prominence = float(rng.choice([0.0, 0.25, 0.5, 1.0, rng.uniform(0, 2)]))
        want = scipy_find_peaks(x, height=height, prominence=prominence)[0]
        got = find_peaks(x, height=height, prominence=prominence)
        np.testing.assert_array_equal(got, want, err_msg=f"{x!r} {height} {prominence}")
        checked += 1
        found += len(want)
    assert checked == 2500 and found > 1000  # the comparison saw many peaks


def test_real_strike_speeds(motions_dir):
    """On the strike speeds of a real clip, at the thresholds the selector uses."""
    import warnings

    from snapcore.motion.load import load_scene
    from snapcore.select.strikes import strike_speeds

    path = motions_dir / "boxing_jump" / "Boxing_Toes.bvh"
    if not path.exists():
        pytest.skip("Boxing_Toes.bvh not in the shared data")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene(path)
    c = scene.characters[0]
    speed = strike_speeds(c.positions, fps=scene.fps, stature=1.7)
    for threshold in (0.5, 1.0, 2.0, 4.0):
        for e in range(speed.shape[1]):
            want = scipy_find_peaks(speed[:, e], height=threshold, prominence=0.5 * threshold)[0]
            got = find_peaks(speed[:, e], height=threshold, prominence=0.5 * threshold)
            np.testing.assert_array_equal(got, want)
