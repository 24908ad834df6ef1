"""Paper figures from the motion data: files made and not blank, Table 1 beside the paper's,
and a clear skip reason when an ingredient is missing."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from conftest import lazy_module

from snapcore.select.view_methods import VIEW_METHODS, ViewMethod

# the modules under test, imported when a test first uses them (fast collection)
fg = lazy_module("analysis.figures")


def _png_std(path) -> float:
    from PIL import Image

    return float(np.asarray(Image.open(path).convert("L"), dtype=float).std())


def test_paper_tables_are_package_data():
    """Table 1 and the analogue list ship with the package, with their source."""
    t1 = fg.paper_table1().set_index("scene")
    # Paper Table 1: Dancing 1096 frames / 38 joints, pose 4.33 s, view 2.16 s.
    assert tuple(t1.loc["dancing", ["frames", "joints"]]) == (1096, 38)
    assert t1.loc["dancing", "pose_selection_s"] == 4.33
    assert t1.loc["two_person_arguing", "viewpoint_selection_s"] == 4.69
    assert t1["source"].str.contains("Table 1").all()
    an = fg.paper_analogues()
    assert set(an["scene"]) == {
        "dancing",
        "running",
        "soccer_kicking",
        "basketball_shooting",
        "two_person_arguing",
        "two_person_boxing",
    }
    assert an.set_index("scene").loc["two_person_arguing", "files"] == [
        "two_person/60_01_scaled.bvh",
        "two_person/61_01_scaled.bvh",
    ]


@pytest.mark.slow  # over 10 s on 2 cores
def test_missing_data_is_a_reason_not_a_crash(tmp_path):
    """No motion folder: the clip figures are skipped with a reason, Table 2 is still made."""
    res = fg.make_figures(
        tmp_path, names=["table2", "fig6"], progress=False, data_dir=tmp_path / "nowhere"
    )
    assert res["table2"][0] and not res["table2"][1]
    paths, reason = res["fig6"]
    assert paths == []
    # fig6 is the dance: the reason names the missing clip where it was looked for
    assert reason == f"motion file(s) missing: {tmp_path / 'nowhere' / 'dance' / '05_06.bvh'}"


def test_snapshot_views_reads_the_typed_views():
    """The three views come from Snapshot.views in the paper's order (whatever order the
    snapshot holds them in); a snapshot without the view stage or without a baseline is
    refused, naming what it lacks."""
    views = {
        ViewMethod.MOTION_AREA: np.array([0.0, 0, 1]),
        ViewMethod.OURS: np.array([1.0, 0, 0]),
        ViewMethod.VIEWPOINT_ENTROPY: np.array([0.0, 1, 0]),
    }
    v = fg.snapshot_views(SimpleNamespace(views=views))
    assert list(v) == list(VIEW_METHODS) == ["ours", "viewpoint_entropy", "motion_area"]
    np.testing.assert_array_equal(v[ViewMethod.VIEWPOINT_ENTROPY], [0, 1, 0])
    np.testing.assert_array_equal(v[ViewMethod.MOTION_AREA], [0, 0, 1])
    with pytest.raises(fg.FigureUnavailable, match="no ours, viewpoint_entropy, motion_area"):
        fg.snapshot_views(SimpleNamespace(views={}))
    del views[ViewMethod.MOTION_AREA]
    with pytest.raises(fg.FigureUnavailable, match="no motion_area view"):
        fg.snapshot_views(SimpleNamespace(views=views))


def test_view_panels_are_named_by_the_method_vocabulary():
    """Figure panels and legends use ViewMethod.panel: the label and the paper figure."""
    assert [m.panel for m in VIEW_METHODS] == [
        "ours: PMA (Fig. 8)",
        "viewpoint entropy (Fig. 9)",
        "motion area (Fig. 10)",
    ]


@pytest.mark.slow  # over 10 s on 2 cores
def test_fig6_and_table1_from_the_motion_data(tmp_path, motions_dir):
    """Fig. 6 of the dance is drawn (not blank); Table 1 times two clips beside the paper."""
    pytest.importorskip("snapcore.pipeline")
    pytest.importorskip("snapcore.render.entropy_plot")
    res = fg.make_figures(tmp_path, names=["fig6", "fig11"], progress=False, data_dir=motions_dir)
    paths, reason = res["fig6"]
    assert not reason, reason
    png = [p for p in paths if p.suffix == ".png"][0]
    assert _png_std(png) > 10
    # Fig. 11 (the view stage with both baselines, and OpenGL) is made, not skipped.
    paths, reason = res["fig11"]
    assert not reason, reason
    assert {p.suffix for p in paths} == {".png", ".pdf"}
    assert _png_std([p for p in paths if p.suffix == ".png"][0]) > 10
    t = fg.measure_table1(
        repeats=1, data_dir=motions_dir, scenes=["running", "basketball_shooting"]
    )
    assert list(t["scene"]) == ["running", "basketball_shooting"]
    assert (t["ours_pose_s"] > 0).all()
    assert list(t["paper_pose_s"]) == [0.31, 2.06]  # the paper's Table 1
    assert list(t["paper_frames"]) == [66, 540]
