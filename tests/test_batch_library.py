"""`snapshot batch` at library scale: memory, dead workers, sub-folder runs, stray JSON,
signals to the main process, Dask set-up, the Parquet index and the thumbnail choice.

The run-time at scale (2,500 clips, scenes per minute, RSS per worker) is a bench case
(`snapshot bench batch_library`), not a test.
"""

from __future__ import annotations

import gc
import weakref

from snapcore.motion import synth
from snapcore.motion.bvh import write_bvh


def test_a_processed_scene_is_freed_with_its_bodies(tmp_path):
    """A scene that was selected, rendered and dropped leaves nothing behind: the body
    cache once kept every scene alive (its values, the bodies, hold the scene), 10-18
    MB a scene in a batch worker."""
    from snapcore.motion.load import load_scene
    from snapcore.pipeline import take_snapshot
    from snapcore.render.renderer import render_still

    path = tmp_path / "walk.bvh"
    write_bvh(synth.humanoid_document("walk", seconds=1.0), path)
    scene = load_scene([str(path)])
    snap = take_snapshot(scene, view=True, baselines=False)
    render_still(scene, snap.index, snap.view, size=(80, 90))
    alive = weakref.ref(scene)
    del scene, snap
    gc.collect()
    assert alive() is None
