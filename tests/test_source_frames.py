"""One frame numbering in the public API: a Snapshot's frame, passed to every public
drawing function, draws the selected pose.

CMU soccer 10_01 loses its first 4 frames (an added T-pose), so its source frame 568 is
the index 564 into the scene's arrays: a function that took the index where the user
passes the frame would draw the pose 4 frames (1/30 s) later. The reference is an
independent one: the same arrays with ``frame_offset = 0`` (a *twin* scene, where a
source frame and an index are one number), drawn at the snapshot's index.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

VIEW = np.array([0.8, 0.25, 0.55])
SIZE = (96, 128)


@pytest.fixture(scope="module")
def soccer(motions_dir):
    from snapcore import load_scene, take_snapshot

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene([motions_dir / "soccer/10_01.bvh"])
        snap = take_snapshot(scene, view=None)
    assert scene.frame_offset == 4  # the clip the test is about: frames differ from indices
    assert snap.source_frame == snap.index + 4
    twin = dataclasses.replace(scene, frame_offset=0)
    assert int(twin.source_frame(snap.index)) == snap.index
    return scene, twin, snap


def _still(scene, frame):
    from snapcore import render_still

    return render_still(
        scene, frame, VIEW, size=SIZE, ground=False, shadows=False, body="mannequin"
    )


def _sheet(scene, frame):
    from snapcore import contact_sheet

    return contact_sheet(
        scene, [frame], view=VIEW, size=SIZE, labels=False, ground=False, body="mannequin"
    )


def _compare(scene, frame):
    from snapcore import compare_views

    views = {"side": VIEW, "front": [0.0, 0.2, 1.0]}
    return compare_views(
        scene, frame, views, size=SIZE, labels=False, ground=False, body="mannequin"
    )


def _video(scene, frame, tmp_path):
    import imageio.v3 as iio

    from snapcore import render_video

    path = tmp_path / f"v{scene.frame_offset}.mp4"
    shown = render_video(
        scene,
        path,
        fps=scene.fps,
        size=SIZE,
        view=VIEW,
        progress=False,
        frame_range=(frame, frame + 1),
        ground=False,
        shadows=False,
        body="mannequin",
    )
    # the map names the frame in the scene's own numbering: the one passed
    assert shown.tolist() == [frame]
    return np.asarray(next(iter(iio.imiter(path))))[..., :3]


def _relief(scene, frame):
    from snapcore import ReliefParams, relief_from_scene

    rel = relief_from_scene(scene, frame, VIEW, params=ReliefParams(resolution=64))
    assert rel.meta["frame"] == frame  # the relief says which frame it carved
    return rel.height_mm


def _height_field(scene, frame):
    from snapcore import ReliefParams
    from snapcore.relief.scene import height_field_from_scene

    return height_field_from_scene(scene, frame, VIEW, params=ReliefParams(resolution=64)).depth


def _relief_body(scene, frame):
    from snapcore.relief.scene import relief_body

    return relief_body(scene, frame, body="mannequin").vertices


def _relief_figure(scene, frame):
    from snapcore import ReliefParams
    from snapcore.relief.scene import relief_comparison_figure

    fig = relief_comparison_figure(scene, frame, {"side": VIEW}, params=ReliefParams(resolution=48))
    return fig.reliefs["side"].height_mm


def _view_maps(scene, frame):
    """The scores plot-views draws, over ±0.05 s around the frame (pose-specific)."""
    from snapcore.render.view_plot import view_maps

    maps = view_maps(scene, frame=frame, window_s=0.05, n_views=162, entropy=False)
    return np.concatenate([maps[m]["scores"] for m in ("pma", "motion_area")])


DRAWERS = {
    "render_still": _still,
    "contact_sheet": _sheet,
    "compare_views": _compare,
    "render_video": _video,
    "relief_from_scene": _relief,
    "height_field_from_scene": _height_field,
    "relief_body": _relief_body,
    "relief_comparison_figure": _relief_figure,
    "view_maps": _view_maps,
}


#: The drawers that return pictures (uint8: one level of rasterisation or codec
#: rounding allowed); the others return geometry in metres or millimetres (exact).
PICTURES = {"render_still", "contact_sheet", "compare_views", "render_video"}


def _same(a, b, name) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    atol = 1.0 if name in PICTURES else 1e-9
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=0, atol=atol, equal_nan=True))


@pytest.mark.parametrize("name", list(DRAWERS))
def test_snapshot_frame_draws_the_selected_pose(soccer, name, tmp_path):
    """``f(scene, snap.source_frame)`` draws what the twin scene draws at the index, and
    not the pose 4 frames later (what the index-taking API drew)."""
    scene, twin, snap = soccer
    draw = DRAWERS[name]
    args = (tmp_path,) if name == "render_video" else ()
    drawn = draw(scene, snap.source_frame, *args)
    assert _same(drawn, draw(twin, snap.index, *args), name)
    # the test can tell: the pose at the index read as a source frame is another one
    assert not _same(drawn, draw(twin, snap.source_frame, *args), name)


def test_a_frame_the_scene_does_not_keep_is_refused(soccer):
    """Source frames 0..3 were cut: asking for one names the frames the scene keeps."""
    from snapcore.errors import RenderError

    scene, _, _ = soccer
    with pytest.raises(RenderError, match=r"keeps source frames 4\.\.801"):
        _still(scene, 0)
