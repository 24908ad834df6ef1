"""Stimuli folders: manifest, sha256 verification, and the builder on real scenes."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from app_helpers import fixture_study_doc, write_fixture_stimuli

from snapcore.schema import validate
from study_app.stimuli import StimuliError, load_stimuli, sha256_file, verify_stimuli

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
    on_disk = {p.relative_to(folder).as_posix() for p in folder.rglob("*")
               if p.is_file() and p.name != "manifest.json"}
    assert on_disk == set(m["files"])
    s = load_stimuli(folder)
    assert s.sha256 == hashlib.sha256((folder / "manifest.json").read_bytes()).hexdigest()
    assert s.scene_ids == ["walk", "jump", "kick"]
    sc = s.scenes["walk"]
    assert sc.n_video_frames == len(sc.frames) == 24 and sc.video.is_file()
    assert set(sc.views) == {"ours", "viewpoint_entropy", "motion_area"}
    assert sc.algorithm_video_frame == 10  # motion frame 20 is shown at video frame 10


@pytest.mark.parametrize("change, message", [
    (lambda d: (d / "walk" / "video.mp4").unlink(), "walk/video.mp4 is missing"),
    (lambda d: (d / "kick" / "frames" / "00007.jpg").write_bytes(b"x"),
     "kick/frames/00007.jpg has been altered"),
    (lambda d: (d / "jump" / "view_ours.png").rename(d / "jump" / "view_x.png"),
     "jump/view_ours.png is missing"),
    (lambda d: (d / "manifest.json").unlink(), "no manifest.json"),
    (lambda d: (d / "manifest.json").write_text("{"), "cannot read the manifest"),
])
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
    r = subprocess.run([SNAPSHOT, "stimuli", "verify", str(folder)], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0 and "ok" in r.stdout
    (copy / "walk" / "view_motion_area.png").write_bytes(b"")
    r = subprocess.run([SNAPSHOT, "stimuli", "verify", str(copy)], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2
    assert r.stderr.strip().startswith("error:") and "view_motion_area.png has been altered" in r.stderr


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
