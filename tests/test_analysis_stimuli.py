"""The analysis side of the stimuli manifest: scene info, the motion for the motion-derived
baselines, and simulating participants for a manifest's scenes."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner
from conftest import lazy_module

from snapcore.cli.main import cli

# the modules under test, imported when a test first uses them (fast collection)
fr = lazy_module("analysis.frames")
sim = lazy_module("analysis.simulate")
st = lazy_module("analysis.stimuli")


def _manifest(scenes):
    """A schema-valid stimuli manifest around the given scene entries (files need not exist)."""
    out = []
    for e in scenes:
        sid = e["id"]
        out.append(
            {
                "video": f"{sid}/video.mp4",
                "video_fps": 24.0,
                "video_to_motion": [e["frame_offset"]],
                "frames": [f"{sid}/f0.png"],
                "views": {
                    m: {"file": f"{sid}/{m}.png"}
                    for m in ("ours", "viewpoint_entropy", "motion_area")
                },
                **e,
            }
        )
    return {
        "format": "action-snapshot-stimuli",
        "version": 1,
        "created_at": "2025-01-01T00:00:00+00:00",
        "app_version": "test",
        "study": {"study": {"id": "stim-test", "title": "t"}},
        "scenes": out,
        "files": {"a/video.mp4": "0" * 64},
    }


def _walk_entry(**kw):
    from snapcore.motion import synth

    sc = synth.synth_scene("walk")
    e = {
        "id": "walk",
        "title": "Synthetic walk",
        "source": {"demo": "walk"},
        "fps": sc.fps,
        "n_frames": sc.n_frames,
        "frame_offset": int(sc.frame_offset),
        "picks": {
            "frame": int(sc.frame_offset) + sc.n_frames // 3,
            "frames": [int(sc.frame_offset) + sc.n_frames // 3, int(sc.frame_offset) + 5],
        },
    }
    e.update(kw)
    return e, sc


def test_stimuli_scene_table():
    """Scene rows carry fps, length, offset, the picks and titles from the manifest."""
    e, sc = _walk_entry()
    t = st.stimuli_scenes(_manifest([e])).iloc[0]
    assert t["scene"] == "walk" and t["title"] == "Synthetic walk"
    assert t["n_frames"] == sc.n_frames and t["fps"] == sc.fps
    assert t["algorithm_frames"] == tuple(e["picks"]["frames"])


def test_baselines_are_the_manifest_selector_picks():
    """The fastest and stretch baselines are the top picks the manifest recorded for those
    selectors (picks.by_method), not recomputed from a reloaded motion: a source naming
    no loadable motion changes nothing."""
    e, _ = _walk_entry(source={"files": ["/nowhere/gone.bvh"]})
    e["picks"]["by_method"] = {"story": [30, 12], "fastest": [44, 3], "stretch": [9]}
    extra = fr.baselines_from_stimuli(_manifest([e]))["walk"]
    assert extra["baseline_frames"] == {"fastest": 44, "stretch": 9}
    assert extra["selector_frames"]["story"] == [30, 12]
    assert extra["algorithm_frames"] == tuple(e["picks"]["frames"])


def test_manifest_without_selector_picks_warns_and_leaves_them_out():
    """An older manifest without picks.by_method: a warning, no baseline frames, the
    algorithm's picks still read."""
    e, _ = _walk_entry()
    with pytest.warns(UserWarning, match="left out"):
        extra = fr.baselines_from_stimuli(_manifest([e]))["walk"]
    assert "baseline_frames" not in extra and extra["algorithm_frames"]


def test_analyze_with_stimuli_adds_motion_baselines(tmp_path):
    """analyze(..., stimuli=manifest): the fastest and stretch rows appear, titles used."""
    from analysis.report import analyze

    e, sc = _walk_entry()
    e["picks"]["by_method"] = {
        "fastest": [int(sc.frame_offset) + 20],
        "stretch": [int(sc.frame_offset) + 40],
    }
    doc = _manifest([e])
    design = sim.design_from_stimuli(doc)
    assert design[0].salient_frames == (e["picks"]["frames"][1],)
    rows = sim.simulated_rows(sim.simulate_participants(design, 25, seed=4))
    summary = analyze(rows, tmp_path, include_simulated=True, stimuli=doc, n_boot=20, figures=False)
    hits = __import__("pandas").read_csv(tmp_path / "tables" / "frame_hits.csv")
    assert {"fastest", "stretch"} <= set(hits["predictor"])
    assert summary["participants"] == 25
    assert "Synthetic walk" in (tmp_path / "report.html").read_text()


def test_simulate_cli_with_manifest(tmp_path):
    """`snapshot simulate --stimuli manifest.json`: the manifest's scenes, study id and hash."""
    import hashlib

    e, _ = _walk_entry()
    path = tmp_path / "manifest.json"
    path.write_text(json.dumps(_manifest([e])))
    url = f"sqlite:///{tmp_path / 's.db'}"
    res = CliRunner().invoke(
        cli,
        [
            "simulate",
            "--n",
            "6",
            "--db",
            url,
            "--stimuli",
            str(path),
            "--strengths",
            "ours=2,viewpoint_entropy=1,motion_area=1",
            "-q",
        ],
    )
    assert res.exit_code == 0, res.output
    from study_app.data.store import Store

    rows = Store(url).export_rows(include_simulated=True)
    assert {r["study_id"] for r in rows} == {"stim-test"}
    assert {r["manifest_sha256"] for r in rows} == {hashlib.sha256(path.read_bytes()).hexdigest()}
    pose = [r for r in rows if r["task"] == "pose"]
    assert len(pose) == 6 and {r["algorithm_frame"] for r in pose} == {e["picks"]["frame"]}
    res = CliRunner().invoke(
        cli, ["simulate", "--n", "2", "--db", url, "--strengths", "ours=1,best=2"]
    )
    assert res.exit_code == 2 and "unknown method 'best'" in res.output


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:stimuli scene")
def test_replaced_views_and_builder_pairs_reach_the_report(tmp_path):
    """A manifest whose builder replaced motion area's view in one scene (it was ours'
    mirror image) and left a near-duplicate pair in another: the pairs are the builder's
    (judged on the pictures shown, IoU included, not re-judged by angle); the replaced
    view is listed in the report and the summary (both schema-valid)."""
    from analysis.report import analyze
    from snapcore.schema import validate

    rows = sim.simulated_rows(sim.simulate_participants(sim.paper_design(), 20, seed=5))
    scenes = list(dict.fromkeys(rows["scene"]))
    entries = []
    for k, sid in enumerate(scenes):
        e = {"id": sid, "fps": 30.0, "n_frames": 300, "frame_offset": 0, "picks": {"frame": 10}}
        # 163.6° apart: not a near-duplicate by angle, yet the same picture mirrored
        e["view_angles"] = {
            "ours|viewpoint_entropy": 60.0,
            "ours|motion_area": 163.6 if k == 1 else 70.0,
            "viewpoint_entropy|motion_area": 50.0,
        }
        e["view_iou"] = {
            "ours|viewpoint_entropy": 0.4,
            "ours|motion_area": 0.93 if k == 1 else 0.6,
            "viewpoint_entropy|motion_area": 0.5,
        }
        e["near_duplicates"] = [["ours", "motion_area"]] if k == 1 else []
        e["replacements"] = []
        entries.append(e)
    entries[0]["replacements"] = [
        {
            "method": "motion_area",
            "original": [-0.99, 0.04, 0.11],
            "replacement": [-0.89, 0.07, 0.45],
            "alike": ["ours"],
            "iou_before": {"ours|motion_area": 0.954, "viewpoint_entropy|motion_area": 0.46},
            "iou_after": {"ours|motion_area": 0.6, "viewpoint_entropy|motion_area": 0.5},
            "score_original": 7.47,
            "score_replacement": 7.02,
            "score_unit": "m²",
            "rank": 113,
            "renders": 7,
            "reason": "silhouette IoU 0.95 with ours at or above 0.8 (mirror images included)",
        }
    ]
    doc = _manifest(entries)
    validate(doc, "stimuli", source="test manifest")
    d = st.near_duplicate_scenes(doc)
    assert list(d["scene"]) == [scenes[1]] and d["iou"].iloc[0] == pytest.approx(0.93)
    r = st.replaced_views(doc)
    assert list(r["scene"]) == [scenes[0]] and list(r["method"]) == ["motion_area"]
    assert (r["iou_before"].iloc[0], r["iou_after"].iloc[0]) == (0.954, 0.6)
    summary = analyze(rows, tmp_path, include_simulated=True, stimuli=doc, n_boot=20, figures=False)
    assert summary["near_duplicate_scenes"] == [scenes[1]]
    assert summary["replaced_views"] == [
        {"scene": scenes[0], "method": "motion_area", "iou_before": 0.954}
    ]
    assert "Replaced candidate views" in (tmp_path / "report.html").read_text()
    assert (tmp_path / "tables" / "replaced_views.csv").is_file()
    # the summary written to disk passed its schema (validated before writing)
    assert json.loads((tmp_path / "summary.json").read_text())["replaced_views"]
