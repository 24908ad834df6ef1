"""Test helpers for the study app: a tiny stimuli folder without rendering.

``write_fixture_stimuli`` writes, per scene, a short H.264 video whose frames show their
own number (large digits, so a screenshot or a decoded frame can be checked by eye),
the matching frame images, three candidate-view images and a real manifest (via
``study_app.design.build.write_manifest``), so the app, the session logic and the browser
test run on the same kind of folder ``snapshot stimuli build`` produces.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from snapcore.select.view_methods import VIEW_METHODS
from study_app.design.build import write_manifest
from study_app.design.protocol import study_from_dict

#: Motion frames per fixture scene and the motion/video rates: 48 motion frames at
#: 48 fps are 1 s, i.e. 24 video frames at 24 fps; video frame i shows motion frame 2i.
FIXTURE_MOTION_FPS = 48.0
FIXTURE_MOTION_FRAMES = 48
FIXTURE_VIDEO_FPS = 24.0
FIXTURE_SIZE = (160, 128)
#: The fixture's "algorithm" picks motion frame 20 (video frame 10) in every scene.
FIXTURE_ALGORITHM_FRAME = 20

COLOURS = {"ours": (200, 60, 60), "viewpoint_entropy": (60, 160, 60), "motion_area": (60, 60, 200)}


def fixture_study_doc(scene_ids=("walk", "jump"), **study_fields) -> dict:
    """A study config document with the given scenes (as demo scenes)."""
    study = {
        "id": "fixture",
        "title": "Fixture study",
        "video_fps": FIXTURE_VIDEO_FPS,
        "size": list(FIXTURE_SIZE),
        **study_fields,
    }
    return {"study": study, "scenes": [{"id": s, "demo": s} for s in scene_ids]}


def _digits_image(text: str, size, colour=(30, 30, 30)) -> np.ndarray:
    from PIL import Image, ImageDraw, ImageFont

    img = Image.new("RGB", size, (235, 235, 225))
    d = ImageDraw.Draw(img)
    try:
        font = ImageFont.load_default(size=size[1] // 2)
    except TypeError:  # Pillow < 10.1
        font = ImageFont.load_default()
    d.text((size[0] // 2, size[1] // 2), text, fill=colour, font=font, anchor="mm")
    return np.asarray(img)


def write_fixture_stimuli(folder, doc: dict | None = None, *, shown: dict | None = None) -> Path:
    """Write a complete, valid stimuli folder for ``doc`` (default: two scenes);
    ``shown``: per scene, the manifest's merged pictures (each the methods it stands for)."""
    import imageio.v3 as iio
    from PIL import Image

    doc = doc or fixture_study_doc()
    study = study_from_dict(doc)
    root = Path(folder)
    root.mkdir(parents=True, exist_ok=True)
    n_video = int(FIXTURE_MOTION_FRAMES * FIXTURE_VIDEO_FPS / FIXTURE_MOTION_FPS)
    entries = []
    for sc in study.scenes:
        d = root / sc["id"]
        (d / "frames").mkdir(parents=True, exist_ok=True)
        frames = np.stack([_digits_image(str(i), study.size) for i in range(n_video)])
        video = d / "video.mp4"
        iio.imwrite(
            video,
            frames,
            plugin="FFMPEG",
            fps=study.video_fps,
            codec="libx264",
            macro_block_size=8,
            output_params=["-movflags", "+faststart", "-g", "6"],
        )
        paths = []
        for i, f in enumerate(frames):
            p = d / "frames" / f"{i:05d}.jpg"
            Image.fromarray(f).save(p, quality=90)
            paths.append(p)
        views = {}
        for k, m in enumerate(VIEW_METHODS):
            p = d / f"view_{m}.png"
            Image.fromarray(_digits_image("ABC"[k], study.size, COLOURS[m])).save(p)
            views[m] = {"file": p, "direction": [0.0, 0.0, 1.0]}
        entries.append(
            {
                "id": sc["id"],
                "title": sc["id"],
                "fps": FIXTURE_MOTION_FPS,
                "n_frames": FIXTURE_MOTION_FRAMES,
                "frame_offset": 0,
                "video": video,
                "video_fps": study.video_fps,
                "size": list(study.size),
                "video_to_motion": [2 * i for i in range(n_video)],
                "frames": paths,
                "picks": {
                    "frame": FIXTURE_ALGORITHM_FRAME,
                    "frames": [FIXTURE_ALGORITHM_FRAME],
                    "view": [0.0, 0.0, 1.0],
                    "viewpoint_entropy": [1.0, 0.0, 0.0],
                    "motion_area": [0.0, 1.0, 0.0],
                },
                "views": views,
                **({"shown": shown[sc["id"]]} if shown and sc["id"] in shown else {}),
            }
        )
    return write_manifest(root, study, entries)


# ----------------------------------------------------------------------------- real stimuli

#: A tiny real study on two synthetic scenes (one and two characters): small images at
#: 12 fps, so the build takes seconds. Built once per test session (tiny_demo_stimuli).
TINY_STUDY = """\
[study]
id = "tiny"
title = "Tiny demo"
video_fps = 12
size = [160, 120]
# Three pictures in every view task (the browser tests of the chooser need them): alike
# ones replaced, not merged (merged pictures: tests/test_e2e_candidates.py).
near_duplicate = "replace"

[[scenes]]
id = "jump"
demo = "jump"

[[scenes]]
id = "push"
demo = "push"
frames = [10, 70]
"""


def tiny_demo_stimuli(tmp_path_factory):
    """Build the tiny study with `snapshot stimuli build` once per test run.

    Returns
    -------
    (Path, subprocess.CompletedProcess or None)
        The stimuli folder, and the build's process result (None when it was already
        built earlier in the session). Runs in a subprocess so the tests' own process
        never holds an EGL context, with relative paths as a person would type them.
    """
    import fcntl
    import os
    import subprocess
    import sys

    base = tmp_path_factory.getbasetemp()
    # every xdist worker of this run shares the build: their temp folders sit side by
    # side under the run's own (one build instead of one per worker)
    root = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "tiny-demo"
    out = root / "stimuli"
    root.mkdir(parents=True, exist_ok=True)
    with open(root / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # a worker that finds it building waits
        if (out / "manifest.json").exists():
            return out, None
        (root / "tiny.toml").write_text(TINY_STUDY)
        snapshot = str(Path(sys.executable).with_name("snapshot"))
        r = subprocess.run(
            [snapshot, "stimuli", "build", "tiny.toml", "-o", "stimuli", "-q"],
            capture_output=True,
            text=True,
            timeout=600,
            cwd=root,
        )
    return out, r
