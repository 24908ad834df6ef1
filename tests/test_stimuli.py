"""Stimuli folders: manifest, sha256 verification, and the builder on real scenes."""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from app_helpers import fixture_study_doc, tiny_demo_stimuli, write_fixture_stimuli
from conftest import need

from snapcore.schema import validate
from study_app.design.stimuli import StimuliError, load_stimuli, sha256_file, verify_stimuli

SNAPSHOT = str(Path(sys.executable).with_name("snapshot"))


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("stim") / "fixture"
    write_fixture_stimuli(d, fixture_study_doc(("walk", "jump", "kick")))
    return d


@pytest.fixture
def copy(folder, tmp_path):
    d = tmp_path / "copy"
    shutil.copytree(folder, d)
    return d


def test_manifest_lists_every_file_with_its_sha256(folder):
    """Each listed file's sha256 equals hashlib's over its bytes; every used file is listed."""
    m = json.loads((folder / "manifest.json").read_text())
    validate(m, "stimuli")
    for rel, digest in m["files"].items():
        assert hashlib.sha256((folder / rel).read_bytes()).hexdigest() == digest
    on_disk = {
        p.relative_to(folder).as_posix()
        for p in folder.rglob("*")
        if p.is_file() and p.name != "manifest.json"
    }
    assert on_disk == set(m["files"])
    s = load_stimuli(folder)
    assert s.file_sha256 == hashlib.sha256((folder / "manifest.json").read_bytes()).hexdigest()
    assert s.scene_ids == ["walk", "jump", "kick"]
    sc = s.scenes["walk"]
    assert sc.n_video_frames == len(sc.frames) == 24 and sc.video.is_file()
    assert set(sc.views) == {"ours", "viewpoint_entropy", "motion_area"}
    assert sc.algorithm_video_frame == 10  # motion frame 20 is shown at video frame 10


def test_set_identity_covers_content_not_build_record(folder, tmp_path):
    """Issue 29 item 4: a build run later (other time, app version, timings) shows the
    same set; a changed file or frame map is another set."""
    import shutil

    from study_app.design.stimuli import content_sha256

    base = load_stimuli(folder).sha256
    copy = tmp_path / "again"
    shutil.copytree(folder, copy)
    m = json.loads((copy / "manifest.json").read_text())
    m["created_at"], m["app_version"] = "2031-01-01T00:00:00+00:00", "9.9.9"
    m["scenes"][0]["timings_s"] = {"load": 123.0}
    (copy / "manifest.json").write_text(json.dumps(m, indent=3))
    again = load_stimuli(copy)
    assert again.sha256 == base and again.file_sha256 != load_stimuli(folder).file_sha256
    m2 = json.loads(json.dumps(m))
    first = sorted(m2["files"])[0]
    m2["files"][first] = "0" * 64
    assert content_sha256(m2) != base
    m3 = json.loads(json.dumps(m))
    m3["scenes"][0]["video_to_motion"][3] += 1
    assert content_sha256(m3) != base


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: (d / "walk" / "video.mp4").unlink(), "walk/video.mp4 is missing"),
        (
            lambda d: (d / "kick" / "frames" / "00007.jpg").write_bytes(b"x"),
            "kick/frames/00007.jpg has been altered",
        ),
        (
            lambda d: (d / "jump" / "view_ours.png").rename(d / "jump" / "view_x.png"),
            "jump/view_ours.png is missing",
        ),
        (lambda d: (d / "manifest.json").unlink(), "no manifest.json"),
        (lambda d: (d / "manifest.json").write_text("{"), "cannot read the manifest"),
    ],
)
def test_altered_or_missing_files_are_refused(copy, change, message):
    change(copy)
    with pytest.raises(StimuliError, match=message.replace(".", r"\.")):
        load_stimuli(copy)


def test_inconsistent_manifest_is_refused(copy):
    """A manifest whose scene uses an unlisted file, or whose frame map is short, is refused."""
    m = json.loads((copy / "manifest.json").read_text())
    m["scenes"][0]["frames"].append("walk/frames/extra.jpg")
    (copy / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(StimuliError, match="no sha256 in files"):
        verify_stimuli(copy)
    m["scenes"][0]["frames"].pop()
    m["scenes"][0]["video_to_motion"].pop()
    (copy / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(StimuliError, match="24 frame images but 23 video frames"):
        verify_stimuli(copy)
    m = json.loads((copy / "manifest.json").read_text())
    m["scenes"][0]["video_to_motion"] = [m["scenes"][0]["video_to_motion"][0]] * 23 + [500]
    (copy / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(StimuliError, match="outside the scene's range"):
        verify_stimuli(copy)


def test_verify_command(folder, copy):
    r = subprocess.run(
        [SNAPSHOT, "stimuli", "verify", str(folder)], capture_output=True, text=True, timeout=60
    )
    assert r.returncode == 0 and "ok" in r.stdout
    (copy / "walk" / "view_motion_area.png").write_bytes(b"")
    r = subprocess.run(
        [SNAPSHOT, "stimuli", "verify", str(copy)], capture_output=True, text=True, timeout=60
    )
    assert r.returncode == 2
    assert (
        r.stderr.strip().startswith("error:")
        and "view_motion_area.png has been altered" in r.stderr
    )


def test_fixture_video_decodes_to_its_frames(folder):
    """The H.264 video decodes to as many frames as the manifest maps, each like its JPEG."""
    import imageio.v3 as iio
    from PIL import Image

    sc = load_stimuli(folder).scenes["jump"]
    frames = list(iio.imiter(sc.video))
    assert len(frames) == sc.n_video_frames
    for i in (0, 11, 23):
        jpg = np.asarray(Image.open(sc.frames[i]), dtype=float)
        assert np.abs(jpg - frames[i][..., :3]).mean() < 4  # JPEG vs H.264 noise only
    assert sha256_file(sc.video) == load_stimuli(folder).manifest["files"]["jump/video.mp4"]


# ----------------------------------------------------------------------------- real build


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The tiny study, built once per session through the CLI (`snapshot stimuli build`)."""
    out, r = tiny_demo_stimuli(tmp_path_factory)
    if r is not None:
        need(
            "must run the view stage" not in r.stderr,
            "snapcore.pipeline.take_snapshot has no view stage yet",
        )
        assert r.returncode == 0, r.stderr
        assert "2 scenes" in r.stdout and "manifest sha256" in r.stdout
    return out


@pytest.fixture(scope="module")
def tiny_config(built):
    return built.parent / "tiny.toml"


@pytest.mark.slow
def test_build_writes_a_verified_folder(built, tiny_config):
    """Every scene: a decodable H.264 video, one image per video frame, three same-size views."""
    import imageio.v3 as iio
    from PIL import Image

    s = load_stimuli(built)
    assert s.study.id == "tiny" and s.scene_ids == ["jump", "push"]
    assert not (built.parent / "stimuli.partial").exists()
    for sc in s.scenes.values():
        frames = list(iio.imiter(sc.video))
        assert len(frames) == sc.n_video_frames == len(sc.frames)
        assert frames[0].shape[:2] == (120, 160)
        # Video frame k (time k / video_fps) shows the motion frame nearest that time:
        # within half a motion frame of offset + k * fps / video_fps (30 → 12 fps here).
        k = np.arange(sc.n_video_frames)
        exact = sc.frame_offset + k * sc.fps / sc.video_fps
        assert np.all(np.abs(np.asarray(sc.video_to_motion) - exact) <= 0.5)
        assert sc.video_to_motion[-1] >= sc.frame_offset + sc.n_frames - 1 - sc.fps / sc.video_fps
        assert sc.frame_offset <= sc.algorithm_frame < sc.frame_offset + sc.n_frames
        images = {m: np.asarray(Image.open(p)) for m, p in sc.views.items()}
        assert {im.shape for im in images.values()} == {(120, 160, 3)}
        dirs = {m: np.array(v["direction"]) for m, v in sc.entry["views"].items()}
        for d in dirs.values():
            assert abs(np.linalg.norm(d) - 1) < 1e-9
        for a, b in (("ours", "viewpoint_entropy"), ("ours", "motion_area")):
            if np.degrees(np.arccos(np.clip(dirs[a] @ dirs[b], -1, 1))) > 10:
                assert np.abs(images[a].astype(int) - images[b]).mean() > 1
    push = s.scenes["push"]
    assert (push.frame_offset, push.n_frames) == (10, 60)  # the config's window [10, 70)
    assert push.entry["source"]["demo"] == "push"


@pytest.mark.slow  # over 20 s: builds stimuli
def test_build_records_the_selection(built):
    """The manifest's picks and view directions are those take_snapshot gives for the scene."""
    from snapcore.motion.load import load_scene
    from snapcore.pipeline import take_snapshot

    s = load_stimuli(built)
    sc = s.scenes["push"]
    scene = load_scene(built / sc.entry["source"]["scene_file"])
    snap = take_snapshot(scene).to_dict()
    assert sc.algorithm_frame == snap["frame"]
    np.testing.assert_allclose(sc.entry["views"]["ours"]["direction"], snap["view"], atol=1e-9)


def test_selection_table_with_an_unknown_key_is_one_clear_error():
    """The config's ``selection`` table becomes the pipeline's parameter objects by field
    name; a key that is no field (an old spelling, a typo) is a StimuliError naming it,
    and a paper-only option with another method one naming that option."""
    from snapcore.motion.synth import synth_scene
    from study_app.design.candidates import select_scene

    scene = synth_scene("walk", fps=30)
    with pytest.raises(StimuliError, match=r"\[selection\]: unknown selection option\(s\) top_k"):
        select_scene(scene, {"pose_method": "story", "top_k": 3})
    with pytest.raises(StimuliError, match=r"\[selection\]: option\(s\) w_local apply to"):
        select_scene(scene, {"w_local": 0.5})


def test_build_refuses_to_overwrite(built, tiny_config):
    r = subprocess.run(
        [SNAPSHOT, "stimuli", "build", str(tiny_config), "-o", str(built), "-q"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2 and "already exists" in r.stderr


@pytest.mark.slow  # over 20 s: builds stimuli
def test_study_command_builds_missing_stimuli_then_serves(
    built, tiny_config, tmp_path, monkeypatch
):
    """`snapshot study --build` builds a missing folder, verifies it, then execs streamlit."""
    from click.testing import CliRunner

    from study_app.commands import study

    calls = []
    monkeypatch.setattr(study.os, "execve", lambda exe, argv, env: calls.append((argv, env)))
    out = tmp_path / "st"
    db = f"sqlite:///{tmp_path / 'db.sqlite'}"
    r = CliRunner().invoke(
        study.study,
        [
            "--config",
            str(tiny_config),
            "--stimuli",
            str(out),
            "--db",
            db,
            "--port",
            "8599",
            "--build",
            "-q",
        ],
    )
    assert r.exit_code == 0, r.output
    ((argv, env),) = calls
    assert argv[1:4] == ["-m", "study_app.web.server", "run"] and argv[4].endswith(
        "study_app/web/app.py"
    )
    assert argv[argv.index("--server.port") + 1] == "8599"
    assert argv[argv.index("--server.headless") + 1] == "true"
    assert env["SNAPSHOT_STIMULI"] == str(out.resolve()) and env["SNAPSHOT_DB"] == db
    assert load_stimuli(out).study.id == "tiny"
    # without --build, a study other than the demo is not built implicitly
    r = CliRunner().invoke(
        study.study, ["--config", str(tiny_config), "--stimuli", str(tmp_path / "none"), "--db", db]
    )
    assert r.exit_code != 0 and "snapshot stimuli build" in str(r.exception)


def _three_views(tmp_path, *, size):
    """The candidate stills of a synthetic walk from below the floor, level and from
    above (``write_views``), and the background colour in 0-255 levels."""
    from snapcore.motion import synth
    from snapcore.render.renderer import BACKGROUND
    from study_app.design.media import write_views

    scene = synth.synth_scene("walk", fps=30)
    dirs = [
        np.array(v, float) / np.linalg.norm(v)
        for v in ((1, -0.16, 0.2), (1, 0, 0.3), (0.6, 0.6, 0.5))
    ]
    picks = {
        "frame": scene.frame_offset + 20,
        "view": dirs[0],
        "viewpoint_entropy": dirs[1],
        "motion_area": dirs[2],
    }
    return write_views(scene, picks, tmp_path, size=size), np.round(np.asarray(BACKGROUND) * 255)


def test_view_stills_share_one_background(tmp_path):
    """The three candidate views of a view task are drawn on the same plain background,
    whatever their elevation (from below the floor, level, from above), so the floor
    cannot give a method away; each still shows the figure."""
    import imageio.v3 as iio

    from snapcore.select.view_methods import VIEW_METHODS

    views, bg = _three_views(tmp_path, size=(96, 128))
    for m in VIEW_METHODS:
        img = iio.imread(views[m]["file"])[..., :3].astype(float)
        border = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
        assert np.abs(border - bg).max() <= 2, m  # plain background all round
        assert (np.abs(img - bg).max(axis=-1) > 30).mean() > 0.05, m  # the figure is there


def test_view_stills_show_one_contact_shadow(tmp_path):
    """Each candidate view has a floor cue, the same in each (issue 40: nothing told a
    viewer the figure stands on the ground): a soft neutral shadow on the background
    under the figure, as wide in every candidate (within 4 px of 96) and lighter than the
    figure threshold of the alike-pictures check (so the silhouettes compared are the
    figure's alone), with the border plain."""
    import imageio.v3 as iio

    from snapcore.select.view_methods import VIEW_METHODS
    from study_app.design.similarity import silhouette

    views, bg = _three_views(tmp_path, size=(160, 200))
    widths = []
    for m in VIEW_METHODS:
        img = iio.imread(views[m]["file"])[..., :3].astype(float)
        dark = bg.mean() - img.mean(axis=-1)
        neutral = np.ptp(img, axis=-1) <= 2
        shadow = neutral & (dark >= 3) & (dark < 30)
        figure = np.abs(img - bg).max(axis=-1) > 30
        assert shadow.sum() > 50, m
        cols = np.flatnonzero(shadow.any(axis=0))
        widths.append(cols[-1] - cols[0])
        rows = np.flatnonzero(figure.any(axis=1))
        # under the figure's lower part (its feet), not across its middle
        assert np.median(np.flatnonzero(shadow.any(axis=1))) > rows[0] + 0.6 * np.ptp(rows), m
        border = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
        assert np.abs(border - bg).max() <= 2, m
        # the alike-pictures check sees the figure alone: the silhouette with the shadow
        # is the one of the figure's pixels
        assert silhouette(img.astype(np.uint8)).sum() > 0
    assert max(widths) - min(widths) <= 4, widths  # of ~96 px: the soft edge at sub-pixel centres


@pytest.mark.slow  # over 20 s: builds stimuli
def test_build_warnings_name_their_scene(tmp_path):
    """A warning raised while one scene is built says which scene it is about; the angle
    between every pair of candidates is reported; a scene without contacts (the demo
    punch) builds without the alarming "constant global pose entropy" warning."""
    (tmp_path / "one.toml").write_text(
        '[study]\nid = "one"\ntitle = "One"\nvideo_fps = 12\n'
        'size = [96, 72]\nnear_duplicate_deg = 90\nnear_duplicate = "warn"\n\n'
        '[[scenes]]\nid = "punch"\ndemo = "punch"\n'
    )
    snapshot = str(Path(sys.executable).with_name("snapshot"))
    r = subprocess.run(
        [snapshot, "stimuli", "build", "one.toml", "-o", "stim", "-q"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    # a 90° threshold makes every pair a near-duplicate ("warn": built anyway): the
    # warning names the scene
    assert "warning: scene punch: nearly the same picture from" in r.stderr
    assert "global pose entropy" not in r.stderr and "constant" not in r.stderr
    assert re.search(
        r"punch: ours/viewpoint_entropy \d+\.\d°, ours/motion_area \d+\.\d°, "
        r"viewpoint_entropy/motion_area \d+\.\d°  NEAR-DUPLICATE",
        r.stdout,
    ), r.stdout
    entry = json.loads((tmp_path / "stim" / "manifest.json").read_text())["scenes"][0]
    assert set(entry["view_angles"]) == {
        "ours|viewpoint_entropy",
        "ours|motion_area",
        "viewpoint_entropy|motion_area",
    }
    assert len(entry["near_duplicates"]) == 3
    # the WebM/VP9 copy is listed and hashed beside the MP4
    assert entry["video_webm"] == "punch/video.webm"
    assert (
        "punch/video.webm" in json.loads((tmp_path / "stim" / "manifest.json").read_text())["files"]
    )


@pytest.mark.slow  # over 20 s: builds stimuli
def test_near_duplicate_error_refuses_alike_pictures(tmp_path):
    """near_duplicate = "error": a scene whose candidates are too alike (the demo jump:
    motion area's view is 3.5° from ours; it was a mirror image 163.6° apart, caught by
    the silhouettes, under an earlier selection) is refused, in one line naming the
    scene and the measure."""
    (tmp_path / "jump.toml").write_text(
        '[study]\nid = "j"\ntitle = "J"\nvideo_fps = 12\nsize = [160, 120]\n'
        'near_duplicate = "error"\n\n[[scenes]]\nid = "jump"\ndemo = "jump"\n'
    )
    r = subprocess.run(
        [SNAPSHOT, "stimuli", "build", "jump.toml", "-o", "stim", "-q"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode != 0
    (line,) = [x for x in r.stderr.splitlines() if x.strip()]
    assert "Traceback" not in r.stderr
    assert re.search(
        r"scene jump: nearly the same picture from ours and motion_area "
        r"\((\d+\.\d° apart\) \(threshold 15°|silhouette IoU 0\.9\d, mirror images "
        r"included\) \(threshold IoU 0\.8)",
        line,
    ), line
    assert not (tmp_path / "stim").exists()


def _drawn(boxes, size=(160, 120)):
    """A candidate picture: dark boxes (x0, y0, x1, y1) on the plain background."""
    img = np.full((size[1], size[0], 3), 249, dtype=np.uint8)
    for x0, y0, x1, y1 in boxes:
        img[y0:y1, x0:x1] = (40, 60, 90)
    return img


def _unit(*v):
    a = np.asarray(v, float)
    return a / np.linalg.norm(a)


def test_replacement_walks_the_method_ranking_skipping_alike_views():
    """find_replacement keeps the baseline's best-ranked view whose picture is unlike the
    kept ones: views near a kept view, its mirror image or a rejected view are skipped
    without rendering; a rendered view that is alike is rejected; the bound refuses
    with the measure."""
    from study_app.design.replacement import NoReplacement, find_replacement

    ell = _drawn([(40, 10, 60, 110), (40, 90, 120, 110)])
    mirrored = ell[:, ::-1].copy()
    bar = _drawn([(20, 50, 140, 70)])
    ours = _unit(1, 0, 0)
    original = _unit(-1, 0.05, 0)  # nearly ours' opposite: the mirror image
    views = np.array(
        [
            original,  # rank 1: the method's own pick
            _unit(-1, 0.1, 0.1),  # near ours' mirror image: skipped unrendered
            _unit(0, 0, 1),  # rendered: the same L again, rejected
            _unit(0.1, 0, 1),  # 5.7° from the rejected one: skipped unrendered
            _unit(0, 1, 0.2),  # rendered: a bar, kept
            _unit(0, 1, -0.9),
        ]
    )
    scores = np.array([6.0, 5.9, 5.5, 5.4, 5.0, 4.0])
    pictures = {2: ell, 4: bar, 5: bar}
    rendered = []

    def render(v):
        i = int(np.argmin(np.linalg.norm(views - v, axis=1)))
        rendered.append(i)
        return pictures[i]

    kept = {"ours": (ours, ell)}
    ranking = (views, scores, 6.0, "m²")
    rep, pic = find_replacement(
        "motion_area", original, mirrored, kept, ranking, render, exclude_deg=15
    )
    assert rendered == [2, 4] and pic is bar
    assert rep.replacement == pytest.approx(views[4]) and (rep.rank, rep.renders) == (5, 2)
    assert rep.alike == ["ours"] and rep.iou_before["ours|motion_area"] == pytest.approx(1.0)
    assert rep.iou_after["ours|motion_area"] < 0.5
    assert (rep.score_original, rep.score_replacement) == (6.0, 5.0)
    # A picture unlike the kept ones is kept as it is, nothing rendered.
    rendered.clear()
    assert find_replacement(
        "motion_area", original, bar, kept, ranking, render, exclude_deg=15
    ) == (None, None)
    assert rendered == []
    # Out of renders: refused, with the measure.
    with pytest.raises(NoReplacement, match=r"silhouette IoU 1\.00 with ours \(threshold 0\.8"):
        find_replacement(
            "motion_area", original, mirrored, kept, ranking, render, exclude_deg=15, max_renders=1
        )


def test_near_duplicate_error_stops_the_build():
    """near_duplicate = "error": a pair under the threshold (or a mirror image) stops the
    build with the angles named; "warn" warns and records them."""
    import warnings

    from study_app.design.candidates import check_near_duplicates
    from study_app.design.protocol import study_from_dict
    from study_app.design.stimuli import StimuliError

    picks = {
        "view": [1.0, 0.0, 0.0],
        "viewpoint_entropy": [0.0, 0.0, 1.0],
        "motion_area": [-0.99, 0.0, 0.1411],
    }  # ~171.9° from ours: a mirror image
    doc = {
        "study": {"id": "s", "title": "S", "near_duplicate": "error"},
        "scenes": [{"id": "a", "demo": "walk"}],
    }
    with pytest.raises(StimuliError, match=r"ours and motion_area \(171\.9° apart\)"):
        check_near_duplicates(study_from_dict(doc), "a", picks)
    doc["study"]["near_duplicate"] = "warn"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        angles, dupes = check_near_duplicates(study_from_dict(doc), "a", picks)
    assert dupes == [["ours", "motion_area"]] and angles["ours|viewpoint_entropy"] == 90.0
    assert len(caught) == 1 and "votes may split" in str(caught[0].message)
